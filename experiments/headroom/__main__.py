"""``python -m experiments.headroom [--env ID ...] [--tune-episodes 256] [--episodes 256] [--quick]``.

The headroom gate of issue #21: is there room for a learned knob on the v2 ids? For each id
(default: every registered ``-v2`` id), on the same held-out episodes (evaluation seeds of
:mod:`agents.seeds`):

* ``plain``: the plain filter (the task's neutral action every step);
* the best tuned **constant** knob (the ``constant`` baseline of the task's
  :func:`agents.baselines.registry.baseline_task` key, else a grid of constant actions here);
* every tuned classical **adaptive** baseline of that key in :mod:`agents.baselines`;
* the **clairvoyant** filter (env keyword ``clairvoyant=True``: the plain filter told the
  step's true Q, R and measurement bias; reads truth, an upper reference, never a baseline).

Every tuned policy is grid-searched on tuning seeds only (:func:`agents.tuning.tune`; the same
batching here for a constant-action grid), scored by
the mean episode RMSE (``--score return``: the mean return, as :mod:`agents.tuning`). The best
tuned baseline is the one with the best tuning score, evaluated on the held-out episodes;
``headroom = (RMSE_base - RMSE_clairvoyant) / RMSE_base`` (RMSE: the mean over episodes of each
episode's horizontal position RMSE), with a paired percentile-bootstrap CI over episodes. An id
passes when the headroom is at least 20 % and its CI excludes 0.

The pieces: :mod:`.candidates` (the tuned policies), :mod:`.clairvoyant` (the reference and the
paired episodes), :mod:`.gate` (the headroom statistic and the gate); this module runs the study
and writes its report.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

import navgym  # noqa: F401  (registers the ids)
from agents.baselines import ConstantAction
from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES, bootstrap_mean_ci, paired_difference
from agents.evaluation.runner import make_vector_env
from agents.reporting import git_commit, markdown_table, write_csv
from agents.seeds import check_seeds
from agents.seeds import seeds as seed_range
from experiments.headroom.candidates import ACTION_LEVELS, candidates
from experiments.headroom.clairvoyant import CLAIRVOYANT, clairvoyant_episodes, play_policies, v2_ids
from experiments.headroom.gate import GATE, headroom, passes
from experiments.outputs import write_manifest
from navgym.envs.base import navigation_env

__all__ = ["ERROR_METRICS", "GATED_TASKS", "QUICK", "main", "report", "study_env", "study_seeds"]

#: Tasks the gate of #21 applies to (other tasks are reported, not gated; Robust and Jumps: #26).
GATED_TASKS = ("Fading", "NoiseScale", "Mixture", "Robust", "Jumps")
#: The error a run is tuned and gated on (``--error``): the position error alone, or the error the
#: reward charges (position plus the platform's extra error: Jpa's weighted attitude error,
#: SignalTracking's weighted Doppler error; :func:`agents.evaluation.metrics.episode_metrics`).
ERROR_METRICS = {"position": "rmse_m", "scored": "scored_rmse_m"}
#: Offsets into the tuning and evaluation seed ranges (agents.tuning and navgym eval use 0 too).
TUNE_OFFSET = 0
EVAL_OFFSET = 0
#: The quick mode (the test): short episodes, few of them, tiny grids.
QUICK = {"tune_episodes": 8, "episodes": 8, "steps": 40, "n_boot": 200, "action_levels": 3}


# ------------------------------------------------------------------------------------- seeds
def study_seeds(
    n_tune: int, n_eval: int, tune_offset: int = TUNE_OFFSET, eval_offset: int = EVAL_OFFSET
) -> tuple[list[int], list[int]]:
    """Tuning and held-out seeds (:mod:`agents.seeds`), checked against their ranges and disjoint."""
    tune, held = seed_range("tune", n_tune, tune_offset), seed_range("eval", n_eval, eval_offset)
    check_seeds("tune", tune)
    check_seeds("eval", held)
    if set(tune) & set(held):  # the ranges are disjoint; this guards against changes to them
        raise ValueError("tuning and evaluation seeds overlap")
    return tune, held


# ------------------------------------------------------------------------------------ study
def study_env(
    env_id: str,
    *,
    tune_seeds: Sequence[int],
    eval_seeds: Sequence[int],
    tune_offset: int = TUNE_OFFSET,
    env_kwargs: Mapping[str, Any] | None = None,
    clairvoyant_kwargs: Mapping[str, Any] = CLAIRVOYANT,
    score: str = "rmse",
    quick: bool = False,
    action_levels: int = ACTION_LEVELS,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    max_batch: int | None = None,
    threshold: float = GATE,
    error: str = "position",
) -> dict[str, Any]:
    """Tune, evaluate and gate one id: ``{"rows", "gate", "notes", "tuned", "seconds"}``.

    ``error``: a key of :data:`ERROR_METRICS`, the error tuned, compared and gated on.
    """
    if error not in ERROR_METRICS:
        raise ValueError(f"error must be one of {sorted(ERROR_METRICS)}; got {error!r}")
    key = ERROR_METRICS[error]
    t0 = time.perf_counter()
    env_kwargs = dict(env_kwargs or {})
    cands, notes = candidates(
        env_id,
        tune_seeds=tune_seeds,
        tune_offset=tune_offset,
        env_kwargs=env_kwargs,
        score=score,
        quick=quick,
        action_levels=action_levels,
        max_batch=max_batch,
        error_key=key,
    )
    layout = make_vector_env(env_id, 1, env_kwargs)
    task = navigation_env(layout).task
    task_name = str(task.name)
    policies: dict[str, Any] = {"plain": ConstantAction(task.action_space, task.neutral_action(), "plain")}
    for c in cands:
        policies[c.name] = c.build(layout)
    layout.close()
    check_seeds("eval", eval_seeds)
    episodes = play_policies(env_id, policies, eval_seeds, env_kwargs)
    episodes["clairvoyant"], paired_ok = clairvoyant_episodes(
        env_id, env_kwargs, eval_seeds, clairvoyant_kwargs
    )
    if not paired_ok:
        notes.append("the clairvoyant env does not replay the same episodes: the comparison is not paired")
    rmse = {name: m[key] for name, m in episodes.items()}
    diverged = {name: m["diverged"] for name, m in episodes.items()}
    by_name = {c.name: c for c in cands}
    best = min(cands, key=lambda c: c.tune_rmse if score == "rmse" else -c.tune_return)
    rows = []
    for i, name in enumerate(rmse):
        c = by_name.get(name)
        mean, lo, hi, _ = bootstrap_mean_ci(rmse[name], n_boot, level, seed=100 * i)
        d = (
            paired_difference(rmse[name], rmse["plain"], n_boot, level, seed=100 * i + 1)
            if name != "plain"
            else None
        )
        role = "plain" if name == "plain" else "clairvoyant" if name == "clairvoyant" else c.role
        note = ""
        if c is not None and d is not None and d["mean_diff"] > 0:
            note = "worse than plain out of sample" + (" (CI excludes 0)" if d["significant"] else "")
        rows.append(
            {
                "env": env_id,
                "task": task_name,
                "policy": name,
                "role": role,
                "best_tuned": name == best.name,
                "params": json.dumps(c.params) if c is not None else "",
                "grid_points": c.grid_size if c is not None else 0,
                "tune_rmse_m": c.tune_rmse if c is not None else float("nan"),
                "rmse_m": mean,
                "rmse_lo": lo,
                "rmse_hi": hi,
                "d_rmse_vs_plain_m": d["mean_diff"] if d else 0.0,
                "d_rmse_vs_plain_lo": d["low"] if d else 0.0,
                "d_rmse_vs_plain_hi": d["high"] if d else 0.0,
                "d_rmse_vs_plain_significant": bool(d["significant"]) if d else False,
                "diverged_pct": 100.0 * float(np.mean(diverged[name])),
                "note": note,
            }
        )
    h = headroom(rmse[best.name], rmse["clairvoyant"], n_boot, level, seed=7)
    held_best = min(cands, key=lambda c: float(np.mean(rmse[c.name])))
    h_held = headroom(rmse[held_best.name], rmse["clairvoyant"], n_boot, level, seed=8)
    gated = task_name in GATED_TASKS
    ok = passes(h, threshold)
    if held_best.name != best.name:
        notes.append(
            f"the best on the tuning episodes (`{best.name}`) is not the best on the held-out ones "
            f"(`{held_best.name}`; headroom against it {100 * h_held['headroom']:.1f} %)"
        )
    gate = {
        "env": env_id,
        "task": task_name,
        "error": error,
        "best_tuned_baseline": best.name,
        "baseline_rmse_m": h["baseline_rmse"],
        "clairvoyant_rmse_m": h["clairvoyant_rmse"],
        "headroom_pct": 100.0 * h["headroom"],
        "headroom_lo_pct": 100.0 * h["low"],
        "headroom_hi_pct": 100.0 * h["high"],
        "headroom_vs_heldout_best_pct": 100.0 * h_held["headroom"],
        "adaptive_baselines": " ".join(c.name for c in cands if c.role == "adaptive") or "none",
        "paired": paired_ok,
        "episodes": h["n"],
        "verdict": ("PASS" if ok else "FAIL") if gated else "not gated",
    }
    tuned = {
        c.name: {
            "role": c.role,
            "source": c.source,
            "params": c.params,
            "grid_points": c.grid_size,
            "tune_rmse_m": c.tune_rmse,
            "tune_return": c.tune_return,
            "tune_diverged": c.tune_diverged,
            "seconds": c.seconds,
        }
        for c in cands
    }
    return {"rows": rows, "gate": gate, "notes": notes, "tuned": tuned, "seconds": time.perf_counter() - t0}


# ----------------------------------------------------------------------------------- report
def _ci(x: float, lo: float, hi: float, digits: int = 3) -> str:
    return f"{x:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def policy_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """Markdown table of one id's policies."""
    md = []
    for r in rows:
        d = (
            "-"
            if r["policy"] == "plain"
            else _ci(r["d_rmse_vs_plain_m"], r["d_rmse_vs_plain_lo"], r["d_rmse_vs_plain_hi"])
            + ("*" if r["d_rmse_vs_plain_significant"] else "")
        )
        md.append(
            {
                "policy": r["policy"] + (" (best tuned)" if r["best_tuned"] else ""),
                "role": r["role"],
                "tuned params": r["params"] or "-",
                "tuning RMSE m": "-" if not np.isfinite(r["tune_rmse_m"]) else f"{r['tune_rmse_m']:.3f}",
                "held-out RMSE m [95% CI]": _ci(r["rmse_m"], r["rmse_lo"], r["rmse_hi"]),
                "ΔRMSE vs plain m [95% CI]": d,
                "diverged %": f"{r['diverged_pct']:.1f}",
                "note": r["note"] or "",
            }
        )
    return markdown_table(md)


def gate_table(gates: Sequence[Mapping[str, Any]]) -> str:
    """Markdown table of the gate, one row per id."""
    return markdown_table(
        [
            {
                "env": g["env"],
                "task": g["task"],
                "best tuned baseline": g["best_tuned_baseline"],
                "baseline RMSE m": f"{g['baseline_rmse_m']:.3f}",
                "clairvoyant RMSE m": f"{g['clairvoyant_rmse_m']:.3f}",
                "headroom % [95% CI]": _ci(g["headroom_pct"], g["headroom_lo_pct"], g["headroom_hi_pct"], 1),
                "adaptive baselines": g["adaptive_baselines"],
                "verdict": g["verdict"],
            }
            for g in gates
        ]
    )


def report(results: Mapping[str, Mapping[str, Any]], config: Mapping[str, Any]) -> str:
    """The markdown report."""
    gates = [r["gate"] for r in results.values()]
    s = config["seeds"]
    text = [
        "# Headroom gate (issue #21): clairvoyant filter vs the best tuned baseline\n",
        f"{s['tune']['n']} tuning episodes (seeds {s['tune']['first']}..{s['tune']['last']}), "
        f"{s['eval']['n']} held-out episodes (seeds {s['eval']['first']}..{s['eval']['last']}); "
        f"tuning score: mean episode {config['score']}; RMSE: mean over episodes of the horizontal "
        + (
            "position RMSE"
            if config.get("error", "position") == "position"
            else "RMSE of the scored error (position plus the platform's extra error, as the reward charges)"
        )
        + f"; {int(100 * config['level'])} % percentile-bootstrap CIs over episodes "
        f"({config['n_boot']} resamples), "
        f"paired. Headroom = (best tuned baseline RMSE - clairvoyant RMSE) / best tuned baseline RMSE; "
        f"PASS: headroom >= {100 * config['gate']:.0f} % and its CI excludes 0."
        + (" **Quick mode** (short episodes, tiny grids): not a result." if config["quick"] else "")
        + "\n",
        "## Gate\n",
        gate_table(gates),
    ]
    for env_id, r in results.items():
        text.append(f"## `{env_id}` ({r['seconds']:.0f} s)\n")
        text.append(policy_table(r["rows"]))
        text.append("`*`: the paired CI of ΔRMSE excludes 0.\n")
        for n in r["notes"]:
            text.append(f"- {n}")
        text.append("")
    text.append(f"Wall time: {config['wall_s']:.0f} s.\n")
    return "\n".join(text)


# -------------------------------------------------------------------------------------- CLI
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.headroom", description=__doc__.splitlines()[0])
    p.add_argument("--env", nargs="+", default=None, help="env ids (default: every registered -v2 id)")
    p.add_argument("--tune-episodes", type=int, default=256, help="tuning episodes per grid point")
    p.add_argument("--episodes", type=int, default=256, help="held-out evaluation episodes")
    p.add_argument("--tune-offset", type=int, default=TUNE_OFFSET, help="offset into the tuning seed range")
    p.add_argument(
        "--eval-offset", type=int, default=EVAL_OFFSET, help="offset into the evaluation seed range"
    )
    p.add_argument("--score", choices=("rmse", "return"), default="rmse", help="tuning score")
    p.add_argument(
        "--error",
        choices=tuple(ERROR_METRICS),
        default="position",
        help="the error tuned and gated on: position alone, or scored (position plus the platform's "
        "extra error, as the reward charges it)",
    )
    p.add_argument("--env-kwargs", default="{}", help="env keyword arguments as JSON")
    p.add_argument("--n-boot", type=int, default=DEFAULT_RESAMPLES)
    p.add_argument("--max-batch", type=int, default=None, help="sub-envs per batched tuning rollout")
    p.add_argument("--quick", action="store_true", help="8 + 8 episodes of 40 steps, tiny grids (the test)")
    p.add_argument("--strict", action="store_true", help="exit 1 when a gated id fails")
    p.add_argument("--out", default="results/headroom")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    git_at_start = git_commit()  # the code that ran (the manifest's "git" is read when it is written)
    ids = args.env or v2_ids()
    if not ids:
        p.error("no -v2 id is registered; pass --env ID")
    env_kwargs = json.loads(args.env_kwargs)
    n_tune, n_eval, n_boot, levels = args.tune_episodes, args.episodes, args.n_boot, ACTION_LEVELS
    if args.quick:
        n_tune, n_eval, n_boot, levels = (
            QUICK["tune_episodes"],
            QUICK["episodes"],
            QUICK["n_boot"],
            QUICK["action_levels"],
        )
        env_kwargs = {"episode_steps": QUICK["steps"], "max_episode_steps": QUICK["steps"], **env_kwargs}
    tune_seeds, eval_seeds = study_seeds(n_tune, n_eval, args.tune_offset, args.eval_offset)
    results = {}
    for env_id in ids:
        r = study_env(
            env_id,
            tune_seeds=tune_seeds,
            eval_seeds=eval_seeds,
            tune_offset=args.tune_offset,
            env_kwargs=env_kwargs,
            score=args.score,
            quick=args.quick,
            action_levels=levels,
            n_boot=n_boot,
            max_batch=args.max_batch,
            error=args.error,
        )
        results[env_id] = r
        g = r["gate"]
        print(
            f"{env_id}: headroom {g['headroom_pct']:.1f} % "
            f"[{g['headroom_lo_pct']:.1f}, {g['headroom_hi_pct']:.1f}] "
            f"(best tuned baseline {g['best_tuned_baseline']} {g['baseline_rmse_m']:.3f} m, clairvoyant "
            f"{g['clairvoyant_rmse_m']:.3f} m) -> {g['verdict']}  ({r['seconds']:.0f} s)",
            flush=True,
        )
    wall = time.perf_counter() - t0

    def _seeds(kind: str, s: list[int], offset: int) -> dict[str, Any]:
        return {"kind": kind, "n": len(s), "offset": offset, "first": s[0], "last": s[-1]}

    config = {
        "ids": ids,
        "quick": args.quick,
        "score": args.score,
        "error": args.error,
        "gate": GATE,
        "level": DEFAULT_LEVEL,
        "n_boot": n_boot,
        "env_kwargs": env_kwargs,
        "clairvoyant_kwargs": CLAIRVOYANT,
        "action_levels": levels,
        "seeds": {
            "tune": _seeds("tune", tune_seeds, args.tune_offset),
            "eval": _seeds("eval", eval_seeds, args.eval_offset),
        },
        "wall_s": round(wall, 1),
    }
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table.csv", [row for r in results.values() for row in r["rows"]])
    write_csv(out / "gate.csv", [r["gate"] for r in results.values()])
    (out / "report.md").write_text(report(results, config))
    write_manifest(
        out,
        "experiments.headroom",
        argv,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        git_at_start=git_at_start,
        config=config,
        tuned={env_id: r["tuned"] for env_id, r in results.items()},
        gate=[r["gate"] for r in results.values()],
        notes={env_id: r["notes"] for env_id, r in results.items()},
    )
    print(gate_table([r["gate"] for r in results.values()]))
    print(f"wrote {out}/ (table.csv, gate.csv, report.md, manifest.json) in {wall:.0f} s")
    failed = [r["gate"]["env"] for r in results.values() if r["gate"]["verdict"] == "FAIL"]
    return 1 if args.strict and failed else 0


if __name__ == "__main__":
    sys.exit(main())
