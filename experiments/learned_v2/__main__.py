"""``python -m experiments.learned_v2 [--episodes 500] [--envs ID ...] [--quick] [--no-readme] [--out DIR]``.

The v2 zoo agents (``<agents-dir>/<EnvName-v2>/model.zip``, default ``agents/zoo``) against the
tuned classical baselines, with the clairvoyant filter as the upper reference. Per v2 id with an
agent, on held-out episodes (evaluation seeds of :mod:`agents.seeds`, offset 0):

* every tuned baseline of the id (the committed ``agents/baselines/tuned/<EnvName-v2>.json``) and
  the agent, paired on the same episodes (:func:`agents.evaluation.cli.run_eval`);
* the **reference**, fixed before any evaluation: the baseline with the highest tuning ``score``
  in the tuned file (ties: the first in the file);
* the **plain** filter: the tuned file's untuned baseline (``plain`` for Fading / NoiseScale,
  ``zero`` for Mixture); Resample has none, nor a clairvoyant (``n/a``);
* the **clairvoyant** filter: the same seeds with ``clairvoyant=True`` and the task's neutral
  action (:mod:`experiments.headroom`), checked to replay the same episodes.

Numbers (``RMSE``: the mean over episodes of each episode's horizontal position RMSE, ``r_e``):

* ``ΔRMSE % = 100 * mean_e(r_agent,e - r_ref,e) / mean_e(r_ref,e)``; its 95 % CI is the paired
  percentile-bootstrap CI of the mean difference (:func:`agents.evaluation.bootstrap.paired_difference`,
  episodes resampled) divided by the same fixed ``mean_e(r_ref,e)``;
* ``capture = (mean(r_plain) - mean(r_agent)) / (mean(r_plain) - mean(r_clairvoyant))``: the share
  of the plain filter's gap to the clairvoyant that the agent closes (1: all of it, 0: none,
  < 0: worse than plain); its 95 % CI resamples episodes jointly for the three policies;
* verdict: ``worse`` when the ΔRMSE CI lies above 0, ``ties`` when it contains 0, ``beats`` when it
  lies below 0, ``target met`` when it lies below 0 and ``ΔRMSE % <= -10``.

Then the same agent, untouched, the reference (same tuned parameters), the plain filter and the
clairvoyant on ``--shift-episodes`` episodes of each shift of :data:`~experiments.learned_v2.shifts.SHIFTS`
(event ranges beyond the training ones; env keyword arguments). A shift an id does not accept
(``UnknownKeywordError``) gives a row saying which keyword arguments are missing.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import traceback
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import asdict
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import navgym  # noqa: F401  (registers the ids)
from agents.baselines import load_tuned
from agents.baselines.registry import baseline_task, best_tuned
from agents.demo import ZOO
from agents.evaluation.bootstrap import (
    DEFAULT_LEVEL,
    DEFAULT_RESAMPLES,
)
from agents.evaluation.cli import parse_policies, run_eval
from agents.evaluation.comparison import NA, TARGET_PCT, capture_share, delta_rmse, verdict
from agents.reporting import environment_versions, git_commit, markdown_table, replace_marked_block
from agents.seeds import seeds as seed_range
from experiments.headroom.clairvoyant import CLAIRVOYANT, clairvoyant_episodes, v2_ids
from experiments.learned_v2.shifts import SHIFT_KWARGS, SHIFTS, platform_of
from navgym.envs.arguments import UnknownKeywordError

ROOT = Path(__file__).resolve().parents[2]
STUDY_README = Path(__file__).resolve().parent / "README.md"
BEGIN, END = "<!-- learned-v2:begin -->", "<!-- learned-v2:end -->"
#: The name of the held-out (unshifted) episode set.
HELD_OUT = "held-out"
#: The untuned baseline of each baselines key that is the plain filter (Resample: none).
PLAIN = {"Fading": "plain", "NoiseScale": "plain", "Mixture": "zero", "RowMixture": "zero"}
#: Defaults and the quick mode (``--quick``).
EPISODES, SHIFT_EPISODES = 500, 200
QUICK = {"episodes": 16, "shift_episodes": 8, "n_boot": 500}
#: run_eval's warning when tuned parameters meet env kwargs: expected here (the shifts).
TUNED_WARNING = "baseline parameters were tuned with the default env kwargs"


def policy_metrics(ep: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Summary of a policy's per-episode metrics (:mod:`agents.evaluation.metrics`).

    ``return``, ``rmse_m``, ``p95_err_m``, ``outage_end_err_m``: means over the episodes with a
    finite value (outage end: the episodes with an outage); ``nees_median``: median over episodes
    of the episode's mean NEES; ``diverged_pct``: 100 x the share of episodes that diverged.
    """

    def mean(x: np.ndarray) -> float:
        x = np.asarray(x, dtype=np.float64)
        x = x[np.isfinite(x)]
        return float(x.mean()) if x.size else float("nan")

    nees = np.asarray(ep["mean_nees"], dtype=np.float64)
    nees = nees[np.isfinite(nees)]
    return {
        "return": mean(ep["return"]),
        "rmse_m": mean(ep["rmse_m"]),
        "p95_err_m": mean(ep["p95_err_m"]),
        "outage_end_err_m": mean(ep["outage_end_err_m"]),
        "nees_median": float(np.median(nees)) if nees.size else float("nan"),
        "diverged_pct": 100.0 * mean(ep["diverged"]),
        "n": int(np.asarray(ep["rmse_m"]).size),
    }


# --------------------------------------------------------------------------- ids and policies
def agent_envs(agents_dir: str | Path = ZOO) -> list[str]:
    """Registered v2 ids with an agent ``<agents_dir>/<EnvName-v2>/model.zip`` (registry order)."""
    return [e for e in v2_ids() if (Path(agents_dir) / e.split("/")[-1] / "model.zip").is_file()]


def plain_baseline(env_id: str) -> str | None:
    """The tuned file's untuned baseline that is the plain filter (:data:`PLAIN`; None: Resample)."""
    return PLAIN.get(baseline_task(env_id))


def missing_kwargs(
    env_id: str, kwargs: Mapping[str, Any], base_kwargs: Mapping[str, Any] | None = None
) -> list[str]:
    """Keys of ``kwargs`` that ``gym.make(env_id)`` refuses as unknown (each key tried alone).

    Other errors (a value out of range) propagate.
    """
    missing = []
    for k, v in kwargs.items():
        try:
            gym.make(env_id, **{**dict(base_kwargs or {}), k: v}).close()
        except UnknownKeywordError:
            missing.append(k)
    return missing


def agent_label(agent: Any, zoo: bool) -> str:
    """``learned (zoo PPO)`` for a zoo agent, ``learned (PPO)`` for one from elsewhere."""
    algo = (agent.algo or "").upper() or "agent"
    return f"learned ({'zoo ' if zoo else ''}{algo})"


def agent_record(agent: Any, path: Path) -> dict[str, Any]:
    """What results.json says about the agent (path, algo, residual baseline, model SHA-256)."""
    res = getattr(agent, "residual", None)
    files = (getattr(agent, "manifest", None) or {}).get("files") or {}
    return {
        "path": str(path),
        "algo": agent.algo,
        "env_id": agent.env_id,
        "residual": None if res is None else {"baseline": res.spec.baseline, "scale": res.spec.scale},
        "files": files,
    }


# ------------------------------------------------------------------------------- one episode set
def run_set(
    env_id: str,
    set_name: str,
    *,
    agent: Any,
    label: str,
    tuned: Mapping[str, Mapping[str, Any]],
    reference: str,
    plain: str | None,
    clairvoyant: bool,
    env_kwargs: Mapping[str, Any],
    episodes: int,
    all_baselines: bool,
    n_boot: int,
    out: Path | None,
    plots: bool = False,
    progress: bool = False,
) -> dict[str, Any]:
    """One row: the agent, baselines and clairvoyant on one episode set of ``env_id``.

    ``all_baselines``: every baseline of the id (the held-out set), else the reference and the
    plain filter only (the shifts). Returns the row (module docstring for its numbers).
    """
    t0 = time.perf_counter()
    env_kwargs = dict(env_kwargs)
    specs = ["baselines"] if all_baselines else list(dict.fromkeys(x for x in (reference, plain) if x))
    policies = parse_policies(specs, env_id, env_kwargs, tuned)
    policies[label] = agent
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=TUNED_WARNING)
        res = run_eval(
            env_id,
            policies,
            episodes,
            out,
            env_kwargs=env_kwargs,
            tuned=tuned,
            reference=reference,
            n_boot=n_boot,
            plots=plots,
            progress=progress,
        )
    eps = {name: dict(m) for name, m in res.episodes.items()}
    notes: list[str] = []
    paired = None
    if clairvoyant:
        eps["clairvoyant"], paired = clairvoyant_episodes(env_id, env_kwargs, res.seeds)
        if not paired:
            notes.append("the clairvoyant env does not replay the same episodes: capture is not paired")
    rmse = {name: m["rmse_m"] for name, m in eps.items()}
    d = delta_rmse(rmse[label], rmse[reference], n_boot, seed=11)
    cap = (
        capture_share(rmse[plain], rmse[label], rmse["clairvoyant"], n_boot, seed=12)
        if clairvoyant and plain
        else None
    )
    return {
        "env": env_id,
        "set": set_name,
        "description": "held-out episodes" if set_name == HELD_OUT else SHIFTS[set_name].description,
        "env_kwargs": env_kwargs,
        "seeds": {
            "kind": "eval",
            "offset": 0,
            "n": len(res.seeds),
            "first": res.seeds[0],
            "last": res.seeds[-1],
        },
        "reference": reference,
        "plain": plain,
        "agent": label,
        "policies": {name: policy_metrics(m) for name, m in eps.items()},
        "rmse_per_episode": {name: np.asarray(x).tolist() for name, x in rmse.items()},
        "delta_rmse": d,
        "capture": cap,
        "verdict": verdict(d["delta_pct"], d["low_pct"], d["high_pct"]),
        "paired_clairvoyant": paired,
        "notes": notes,
        "error": None,
        "seconds": round(time.perf_counter() - t0, 1),
    }


def error_row(env_id: str, set_name: str, message: str, **fields: Any) -> dict[str, Any]:
    """A row that did not run, with the reason."""
    desc = "held-out episodes" if set_name == HELD_OUT else SHIFTS[set_name].description
    return {
        "env": env_id,
        "set": set_name,
        "description": desc,
        "error": message,
        "verdict": "not run",
        **fields,
    }


def study_env(
    env_id: str,
    agent_path: Path,
    *,
    zoo: bool,
    episodes: int,
    shift_episodes: int,
    shifts: Sequence[str],
    n_boot: int,
    env_kwargs: Mapping[str, Any],
    out: Path | None,
    plots: bool = False,
    progress: bool = False,
    pbar: Any = None,
) -> dict[str, Any]:
    """Every row of one id: the held-out set, then each shift of ``shifts``."""
    from agents.training.loading import load_agent

    sets = [HELD_OUT, *shifts]
    rec: dict[str, Any] = {"env": env_id, "rows": []}

    def tick() -> None:
        if pbar is not None:
            pbar.update(1)

    try:
        reference, score = best_tuned(env_id)
        tuned = load_tuned(env_id)
        agent = load_agent(agent_path, env=env_id)
        if agent.env_id not in (None, env_id):
            raise ValueError(f"{agent_path} holds an agent of {agent.env_id}, not of {env_id}")
    except Exception as e:
        rec["rows"] = [error_row(env_id, s, f"{type(e).__name__}: {e}") for s in sets]
        for _ in sets:
            tick()
        return rec
    plain = plain_baseline(env_id)
    clair = not missing_kwargs(env_id, CLAIRVOYANT, env_kwargs)
    label = agent_label(agent, zoo)
    rec.update(
        {
            "agent": {"label": label, **agent_record(agent, agent_path)},
            "reference": reference,
            "reference_tuning_score": score,
            "plain": plain,
            "clairvoyant": clair,
        }
    )
    name = env_id.split("/")[-1]
    common = {
        "agent": agent,
        "label": label,
        "tuned": tuned,
        "reference": reference,
        "plain": plain,
        "clairvoyant": clair,
        "n_boot": n_boot,
        "progress": progress,
    }
    for s in sets:
        kwargs = dict(env_kwargs)
        if s != HELD_OUT:
            shifted = SHIFT_KWARGS[platform_of(env_id)][s]
            missing = missing_kwargs(env_id, shifted, env_kwargs)
            if missing:
                rec["rows"].append(
                    error_row(
                        env_id,
                        s,
                        f"{env_id} does not accept the env keyword argument(s) {missing} "
                        f"(UnknownKeywordError): the '{s}' shift needs them",
                        reference=reference,
                        env_kwargs=shifted,
                    )
                )
                tick()
                continue
            kwargs.update(shifted)
        slug = s.replace(" ", "-")
        try:
            row = run_set(
                env_id,
                s,
                env_kwargs=kwargs,
                episodes=episodes if s == HELD_OUT else shift_episodes,
                all_baselines=s == HELD_OUT,
                out=None if out is None else out / name / slug,
                plots=plots and s == HELD_OUT,
                **common,
            )
        except Exception as e:
            traceback.print_exc()
            row = error_row(env_id, s, f"{type(e).__name__}: {e}", reference=reference, env_kwargs=kwargs)
        rec["rows"].append(row)
        tick()
    return rec


# ----------------------------------------------------------------------------------- tables
def _f(x: Any, digits: int = 2) -> str:
    return "-" if x is None or not math.isfinite(float(x)) else f"{float(x):.{digits}f}"


def _ci(x: float, lo: float, hi: float, digits: int = 1, sign: bool = True) -> str:
    if not math.isfinite(x):
        return NA
    s = f"{x:+.{digits}f}" if sign else f"{x:.{digits}f}"
    return f"{s} [{_f(lo, digits)}, {_f(hi, digits)}]"


def _capture(row: Mapping[str, Any]) -> str:
    c = row.get("capture")
    if c is None:
        return NA
    return _ci(100.0 * c["capture"], 100.0 * c["low"], 100.0 * c["high"], 1, sign=False)


def _pair(row: Mapping[str, Any], metric: str, names: Sequence[str | None], digits: int = 2) -> str:
    pol = row["policies"]
    return " / ".join(NA if n is None or n not in pol else _f(pol[n][metric], digits) for n in names)


#: The metric columns of :func:`full_table` (after id, episodes, n, reference; before verdict).
FULL_COLUMNS = (
    "RMSE m: agent / ref / plain / clairvoyant",
    "p95 m: agent / ref",
    "outage end m: agent / ref",
    "NEES median: agent / ref",
    "diverged %: agent / ref",
    "return: agent / ref",
    "ΔRMSE % [95% CI]",
    "capture % [95% CI]",
)


def full_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """The full table: one row per id and episode set (agent vs reference; plain, clairvoyant)."""
    md = []
    for r in rows:
        ref = r.get("reference") or "-"
        base = {"id": f"`{r['env']}`", "episodes": r["set"], "n": "-", "reference (best tuned)": f"`{ref}`"}
        if r.get("error"):
            cells = dict.fromkeys(FULL_COLUMNS, "-")
            md.append({**base, **cells, FULL_COLUMNS[0]: r["error"], "verdict": "not run"})
            continue
        a, p = r["agent"], r["plain"]
        clair = "clairvoyant" if "clairvoyant" in r["policies"] else None
        d = r["delta_rmse"]
        md.append(
            {
                **base,
                "n": str(r["seeds"]["n"]),
                "RMSE m: agent / ref / plain / clairvoyant": _pair(r, "rmse_m", [a, ref, p, clair]),
                "p95 m: agent / ref": _pair(r, "p95_err_m", [a, ref]),
                "outage end m: agent / ref": _pair(r, "outage_end_err_m", [a, ref]),
                "NEES median: agent / ref": _pair(r, "nees_median", [a, ref], 1),
                "diverged %: agent / ref": _pair(r, "diverged_pct", [a, ref], 1),
                "return: agent / ref": _pair(r, "return", [a, ref], 1),
                "ΔRMSE % [95% CI]": _ci(d["delta_pct"], d["low_pct"], d["high_pct"]),
                "capture % [95% CI]": _capture(r),
                "verdict": r["verdict"],
            }
        )
    return markdown_table(md) if md else "No v2 agent found.\n"


def summary_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """The top-level README's compact table: one row per id, its held-out figures and, in the last
    column, the agent's ΔRMSE % on each shift of :data:`SHIFTS` (``-`` where not run)."""
    shifted: dict[str, dict[str, str]] = {}
    for r in rows:
        if r["set"] != HELD_OUT:
            d = r.get("delta_rmse")
            shifted.setdefault(r["env"], {})[r["set"]] = (
                "-" if r.get("error") or not d else f"{d['delta_pct']:+.1f}"
            )
    md = []
    for r in rows:
        if r["set"] != HELD_OUT:
            continue
        ref = r.get("reference") or "-"
        if r.get("error"):
            md.append([f"`{r['env']}`", f"`{ref}`", r["error"], "-", "-", "not run", "-"])
            continue
        a, clair = r["agent"], "clairvoyant" if "clairvoyant" in r["policies"] else None
        d = r["delta_rmse"]
        md.append(
            [
                f"`{r['env']}`",
                f"`{ref}`",
                _pair(r, "rmse_m", [a, ref, clair]),
                _ci(d["delta_pct"], d["low_pct"], d["high_pct"]),
                _capture(r),
                r["verdict"],
                " / ".join(shifted.get(r["env"], {}).get(name, "-") for name in SHIFTS),
            ]
        )
    head = [
        "id",
        "best tuned baseline",
        "RMSE m: agent / baseline / clairvoyant",
        "ΔRMSE % [95% CI]",
        "capture % [95% CI]",
        "verdict",
        "ΔRMSE % on shifts: " + " / ".join(_shift_slug(name) for name in SHIFTS),
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(c) + " |" for c in md]
    return "\n".join(lines) + "\n" if md else "No v2 agent found.\n"


def policies_table(row: Mapping[str, Any]) -> str:
    """Every policy of one row with the metrics of :func:`policy_metrics`."""
    md = []
    for name, m in row["policies"].items():
        tags = [
            t for t, on in (("ref", name == row["reference"]), ("plain filter", name == row["plain"])) if on
        ]
        role = f" ({', '.join(tags)})" if tags else ""
        md.append(
            {
                "policy": f"{name}{role}",
                "return": _f(m["return"], 1),
                "RMSE m": _f(m["rmse_m"], 3),
                "p95 m": _f(m["p95_err_m"], 2),
                "outage end m": _f(m["outage_end_err_m"], 2),
                "NEES median": _f(m["nees_median"], 1),
                "diverged %": _f(m["diverged_pct"], 1),
            }
        )
    return markdown_table(md)


def footer(config: Mapping[str, Any]) -> str:
    """What the tables hold and how they were made."""
    return (
        f"Generated by `{config['command']}` at {config['git']['commit'] or 'unknown'}"
        f"{' (dirty)' if config['git'].get('dirty') else ''}: {config['episodes']} held-out episodes per id, "
        f"{config['shift_episodes']} per shift (evaluation seeds from offset 0); reference: the tuned "
        f"baseline with the best tuning score (fixed before evaluation); ΔRMSE % and capture with paired "
        f"{int(100 * config['level'])} % bootstrap CIs over episodes ({config['n_boot']} resamples); "
        f"verdict: target met (CI below 0 and ΔRMSE <= -{TARGET_PCT:g} %), beats (CI below 0), ties, worse."
    )


def short_footer(config: Mapping[str, Any]) -> str:
    """The top-level README's footer: the command and the sample sizes (the rest in the study's README)."""
    return (
        f"`{config['command']}`: {config['episodes']} held-out episodes per id, "
        f"{config['shift_episodes']} per shift; reference fixed by the tuning score; paired "
        f"{int(100 * config['level'])} % bootstrap CIs; "
        f"target met = CI below 0 and ΔRMSE <= -{TARGET_PCT:g} %."
    )


def report(envs: Mapping[str, Mapping[str, Any]], config: Mapping[str, Any]) -> str:
    """table.md: the full table, then every policy of every row."""
    rows = [r for e in envs.values() for r in e["rows"]]
    text = [
        "# Learned v2 agents vs the best tuned baseline and the clairvoyant\n",
        ("**Quick mode**: not a result.\n" if config["quick"] else ""),
        full_table(rows),
        footer(config) + "\n",
    ]
    for env_id, e in envs.items():
        agent = e.get("agent") or {}
        res = agent.get("residual")
        text.append(
            f"## `{env_id}`\n\nagent `{agent.get('path', '-')}` ({agent.get('algo', '-')}"
            f"{', residual over ' + res['baseline'] if res else ''}); reference `{e.get('reference', '-')}` "
            f"(tuning score {_f(e.get('reference_tuning_score'), 1)})\n"
        )
        for r in e["rows"]:
            text.append(f"### {r['set']} ({r['description']})\n")
            if r.get("error"):
                text.append(f"Not run: {r['error']}\n")
                continue
            if r["env_kwargs"]:
                text.append(f"env kwargs: `{json.dumps(r['env_kwargs'])}`\n")
            text.append(policies_table(r))
            for n in r["notes"]:
                text.append(f"- {n}")
            text.append("")
    return "\n".join(text)


def replace_block(path: Path, block: str) -> None:
    """Replace the text between :data:`BEGIN` and :data:`END` in ``path`` (both must be there)."""
    replace_marked_block(path, BEGIN, END, block)


def _json(x: Any) -> Any:
    """``x`` with NumPy scalars as Python numbers, tuples as lists, non-finite floats as null."""
    if isinstance(x, Mapping):
        return {str(k): _json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json(v) for v in x]
    if isinstance(x, np.ndarray):
        return _json(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer, int)):
        return int(x)
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(float(x)) else None
    return x


# -------------------------------------------------------------------------------------- CLI
def row_line(r: Mapping[str, Any]) -> str:
    """One line on a row that ran: ΔRMSE %, capture %, verdict."""
    d = r["delta_rmse"]
    return (
        f"ΔRMSE {_ci(d['delta_pct'], d['low_pct'], d['high_pct'])} % vs {r['reference']}, "
        f"capture {_capture(r)} % -> {r['verdict']}"
    )


def _shift_slug(name: str) -> str:
    return name.split()[0]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.learned_v2", description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=EPISODES, help="held-out episodes per id")
    p.add_argument("--shift-episodes", type=int, default=SHIFT_EPISODES, help="episodes per shift")
    p.add_argument("--envs", nargs="+", default=None, help="only these v2 ids (implies --no-readme)")
    p.add_argument(
        "--shifts",
        nargs="*",
        default=[_shift_slug(s) for s in SHIFTS],
        choices=[_shift_slug(s) for s in SHIFTS],
        help="shifts to run (default all; none: no shift rows)",
    )
    p.add_argument(
        "--agents-dir", default=str(ZOO), help="folder of <EnvName-v2>/model.zip (default the zoo)"
    )
    p.add_argument("--out", default="results/learned_v2")
    p.add_argument("--n-boot", type=int, default=DEFAULT_RESAMPLES, help="bootstrap resamples")
    p.add_argument("--steps", type=int, default=None, help="episode_steps (smoke tests only: not a result)")
    p.add_argument("--quick", action="store_true", help="16 episodes, 8 per shift, no README writing")
    p.add_argument("--no-readme", action="store_true", help="do not rewrite the README blocks")
    p.add_argument("--no-plots", action="store_true", help="no PNG plots of the held-out sets")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    git = git_commit()
    episodes, shift_episodes, n_boot = args.episodes, args.shift_episodes, args.n_boot
    if args.quick:
        episodes, shift_episodes = QUICK["episodes"], QUICK["shift_episodes"]
        n_boot = min(n_boot, QUICK["n_boot"])
    agents_dir = Path(args.agents_dir)
    zoo = agents_dir.resolve() == ZOO.resolve()
    envs = agent_envs(agents_dir)
    if args.envs:
        unknown = sorted(set(args.envs) - set(envs))
        if unknown:
            p.error(f"no v2 agent in {agents_dir} for {unknown}; v2 ids with an agent: {envs}")
        envs = [e for e in envs if e in args.envs]
    shifts = [s for s in SHIFTS if _shift_slug(s) in args.shifts]
    env_kwargs: dict[str, Any] = {}
    if args.steps is not None:
        env_kwargs = {"episode_steps": args.steps, "max_episode_steps": args.steps}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    command = " ".join(["python -m experiments.learned_v2", *(sys.argv[1:] if argv is None else argv)])
    pbar = None
    if not args.quiet and envs:
        from tqdm.auto import tqdm

        pbar = tqdm(total=len(envs) * (1 + len(shifts)), desc="learned_v2", unit="set")
    results: dict[str, Any] = {}
    try:
        for env_id in envs:
            rec = study_env(
                env_id,
                agents_dir / env_id.split("/")[-1],
                zoo=zoo,
                episodes=episodes,
                shift_episodes=shift_episodes,
                shifts=shifts,
                n_boot=n_boot,
                env_kwargs=env_kwargs,
                out=out,
                plots=not (args.quick or args.no_plots),
                progress=not args.quiet,
                pbar=pbar,
            )
            results[env_id] = rec
            for r in rec["rows"]:
                msg = r["error"] or row_line(r)
                line = f"{env_id} [{r['set']}]: {msg}"
                print(line, flush=True) if pbar is None else pbar.write(line)
    finally:
        if pbar is not None:
            pbar.close()
    wall = time.perf_counter() - t0
    platforms = sorted({platform_of(e) for e in envs})
    config = {
        "command": command,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "git": git,
        "versions": environment_versions(),
        "quick": args.quick,
        "episodes": episodes,
        "shift_episodes": shift_episodes,
        "n_boot": n_boot,
        "level": DEFAULT_LEVEL,
        "target_pct": TARGET_PCT,
        "agents_dir": str(agents_dir),
        "env_kwargs": env_kwargs,
        "seeds": {
            "held_out": {"kind": "eval", "offset": 0, "n": episodes, "first": seed_range("eval", 1)[0]},
            "shifts": {"kind": "eval", "offset": 0, "n": shift_episodes, "first": seed_range("eval", 1)[0]},
        },
        "shifts": {s: asdict(SHIFTS[s]) for s in shifts},
        "shift_kwargs": {pl: {s: SHIFT_KWARGS[pl][s] for s in shifts} for pl in platforms},
        "wall_s": round(wall, 1),
    }
    (out / "results.json").write_text(json.dumps(_json({**config, "envs": results}), indent=1) + "\n")
    (out / "table.md").write_text(report(results, config))
    rows = [r for e in results.values() for r in e["rows"]]
    print(full_table(rows))
    reasons = [
        why
        for cond, why in (
            (args.quick, "--quick"),
            (args.no_readme, "--no-readme"),
            (bool(args.envs), "--envs"),
            (not zoo, "--agents-dir is not the zoo"),
            (args.steps is not None, "--steps"),
            (not envs, "no v2 agent"),
        )
        if cond
    ]
    if reasons:
        print(f"READMEs not rewritten ({', '.join(reasons)})")
    else:
        replace_block(STUDY_README, full_table(rows) + "\n" + footer(config))
        link = "[`experiments/learned_v2/README.md`](experiments/learned_v2/README.md)"
        summary = f"{summary_table(rows)}\n{short_footer(config)} Every row: {link}."
        root = ROOT / "README.md"
        if BEGIN in root.read_text():  # the project README keeps a summary only where it asks for one
            replace_block(root, summary)
        print(f"rewrote the learned-v2 blocks of {STUDY_README.relative_to(ROOT)} (and README.md's, if any)")
    print(f"wrote {out}/ (results.json, table.md, <EnvName-v2>/<set>/) in {wall:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
