"""``python -m experiments.replay [--quick] [--out results/replay]``: INS/GNSS on a real walk.

The packaged recording GNSS_IMU walk_0827 (:mod:`navgym.recordings`) replayed by
``navgym/ReplayFading-v2`` and ``navgym/ReplayNoiseScale-v2``: the real MEMS IMU drives the
strapdown INS (the Quadrotor's 15-state direct EKF, Benzerrouk 2014, eq. 3-7, 11-14) and the
real RTK fixes are its measurements; the RTK-fixed epochs are the truth. Episodes here cover
the whole truth span (``episode_steps = 340``, 85 s; the window starting 1.25 s into the walk,
where the IMU begins) with pinned scenarios (nothing injected but the outages), so every
number below is a deterministic function of the recording and the policy.

1. **No outage**: the plain filter's horizontal error at the RTK-fixed epochs (``exact``; the
   interpolated float epochs are not scored): RMS, median, 95th percentile, max.
2. **Outage-end error**: one outage of ``L`` = 5, 10, 30 s (fixes withheld, still scored) at
   starts every 5 s from 10 s into the window while it ends by 80 s; the horizontal error at
   the last truth epoch before the fixes return (outage end), averaged over the starts, for

   * the plain filter (nominal Q and R, the neutral action);
   * the best classical **adaptive** baseline: the tuned adaptive baseline (not ``plain`` or
     ``constant``) with the best tuning score of the replay ids' tuned files
     (``agents/baselines/tuned/Replay*-v2.json``, tuned on injected-event windows of the walk);
   * the **simulation-trained agent** ``agents/zoo/QuadrotorNoiseScale-v2`` (residual PPO over
     Sage-Husa, trained on simulated Quadrotor v2 flights only) run untouched on
     ``ReplayNoiseScale-v2``, whose observation has the Quadrotor v2 layout (sim-to-real).

3. **Plot** ``walk.png``: the walk's RTK truth, the plain filter's estimate through a 10 s
   outage and the outage's withheld stretch.

Writes ``results/replay/{table.csv, report.md, walk.png, manifest.json}``.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import navgym  # noqa: F401  (registers the ids)
from agents.baselines import ConstantAction
from agents.baselines.registry import load_tuned, make_baseline, tuned_path
from agents.evaluation.runner import OneEpisodeStepper
from agents.policy_runner import PredictRunner
from agents.reporting import markdown_table
from experiments.outputs import write_manifest
from navgym.scenarios import Outage, Scenario

#: Episode of the study: the whole truth span of the walk (340 steps of 0.25 s).
STEPS = 340
DT = 0.25
#: Outage lengths [s] and the spacing [s] of their starts.
LENGTHS = (5.0, 10.0, 30.0)
FIRST_START, SPACING, LAST_END = 10.0, 5.0, 80.0
#: The window's seed (the start drawn is the first window: any seed gives one of 8 starts).
SEED = 0
ZOO_AGENT = Path("agents/zoo/QuadrotorNoiseScale-v2")
IDS = {"fading": "navgym/ReplayFading-v2", "noisescale": "navgym/ReplayNoiseScale-v2"}


def placements(length: float, quick: bool = False) -> list[float]:
    """Outage starts [s] for one length (every SPACING s from FIRST_START, ending by LAST_END)."""
    out = list(np.arange(FIRST_START, LAST_END - length + 1e-9, SPACING))
    return out[:2] if quick else out


def make_env(env_id: str, n: int, steps: int) -> Any:
    """A native vector env of ``n`` rows over the whole truth span."""
    return gym.make_vec(
        env_id,
        num_envs=n,
        vectorization_mode="vector_entry_point",
        episode_steps=steps,
        max_episode_steps=steps,
    )


def run(env_id: str, policy_factory: Any, scenarios: list[Scenario], steps: int) -> dict[str, np.ndarray]:
    """One episode per scenario (same window); per-step errors, truth flags, fixes, estimates."""
    env = make_env(env_id, len(scenarios), steps)
    policy = policy_factory(env)
    obs, _ = env.reset(seed=[SEED] * len(scenarios), options={"scenario": scenarios})
    core = env.unwrapped.core
    runner = PredictRunner(policy, True)
    runner.reset()
    stepper = OneEpisodeStepper(env)
    B = len(scenarios)
    err, est, truth = (
        np.full((B, steps), np.nan),
        np.full((B, steps, 2), np.nan),
        np.full((B, steps, 2), np.nan),
    )
    alive = np.ones(B, dtype=bool)
    exact, fix = core.episodes.exact[:, 1:].copy(), core.episodes.fix[:, 1:].copy()
    for t in range(steps):
        obs, _r, term, trunc, info = stepper.step(runner.act(obs))
        err[alive, t] = np.asarray(info["pos_err_m"])[alive]
        est[alive, t], truth[alive, t] = (
            np.asarray(info["est_pos"])[alive],
            np.asarray(info["truth_pos"])[alive],
        )
        alive &= ~(np.asarray(term) | np.asarray(trunc))
        if not alive.any():
            break
    env.close()
    return {"err": err, "exact": exact, "fix": fix, "est": est, "truth": truth}


def neutral(env: Any) -> Any:
    """The plain filter: the task's neutral action."""
    from navgym.envs.base import navigation_env

    task = navigation_env(env).task
    return ConstantAction(task.action_space, task.neutral_action(), "plain")


def best_adaptive() -> tuple[str, str, dict[str, Any], float]:
    """``(task, name, params, score)`` of the best tuned adaptive baseline of the replay ids."""
    best = None
    for task, env_id in IDS.items():
        p = tuned_path(env_id)
        if not p.is_file():
            continue
        base = json.loads(p.read_text()).get("baselines") or {}
        for name, rec in base.items():
            if name in ("plain", "constant"):
                continue
            if best is None or rec["score"] > best[3]:
                best = (task, name, dict(load_tuned(env_id).get(name, {})), float(rec["score"]))
    if best is None:
        raise FileNotFoundError("no tuned replay baselines: run navgym tune --env navgym/ReplayFading-v2 ...")
    return best


def sim_agent() -> Any:
    """The simulation-trained QuadrotorNoiseScale-v2 agent, untouched (None if not loadable)."""
    from agents.training.loading import load_agent

    if not ZOO_AGENT.is_dir():
        return None
    return load_agent(ZOO_AGENT, algo="ppo")


def outage_end_errors(res: dict[str, np.ndarray], starts: list[float], length: float) -> np.ndarray:
    """Error at the last truth epoch inside each row's outage ``[s, s + L)`` (NaN if none)."""
    t = (np.arange(res["err"].shape[1]) + 1) * DT
    out = np.full(len(starts), np.nan)
    for i, s in enumerate(starts):
        inside = (t >= s) & (t < s + length) & res["exact"][i]
        if inside.any():
            out[i] = res["err"][i, np.flatnonzero(inside)[-1]]
    return out


def plot(res: dict[str, np.ndarray], row: int, start: float, length: float, path: Path) -> None:
    """The walk (north/east): RTK truth, the plain estimate, the outage's withheld stretch."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = (np.arange(res["err"].shape[1]) + 1) * DT
    tr, est, ex = res["truth"][row], res["est"][row], res["exact"][row]
    out = (t >= start) & (t < start + length)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.8), gridspec_kw={"width_ratios": [1.1, 1]})
    ax.plot(tr[ex, 1], tr[ex, 0], ".", ms=3, color="0.55", label="truth (RTK fixed)")
    ax.plot(est[:, 1], est[:, 0], "-", lw=1.0, color="tab:blue", label="INS/GNSS estimate (plain EKF)")
    ax.plot(
        est[out, 1], est[out, 0], "-", lw=2.0, color="tab:red", label=f"estimate in the {length:g} s outage"
    )
    ax.plot(
        tr[out & ex, 1], tr[out & ex, 0], "o", ms=3, mfc="none", color="tab:red", label="truth in the outage"
    )
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal")
    ax.legend(fontsize=7, loc="best")
    ax.set_title("walk_0827: truth, estimate, outage")
    bx.plot(t[ex], res["err"][row][ex], ".", ms=3, color="tab:blue")
    bx.axvspan(start, start + length, color="tab:red", alpha=0.15, label="fixes withheld")
    bx.set_xlabel("time in the window [s]")
    bx.set_ylabel("horizontal error at RTK-fixed epochs [m]")
    bx.set_yscale("log")
    bx.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Run the study (module docstring); print the report."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/replay")
    ap.add_argument("--quick", action="store_true", help="two placements per length, 160 steps")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    steps = 160 if args.quick else STEPS
    lengths = (5.0, 10.0) if args.quick else LENGTHS
    last_end = min(LAST_END, steps * DT - 5.0)

    # 1. no outage
    clean = run(IDS["fading"], neutral, [Scenario(duration=steps * DT)], steps)
    e = clean["err"][0][clean["exact"][0]]
    e = e[np.isfinite(e)]
    clean_row = {
        "epochs": int(e.size),
        "rms_m": float(np.sqrt(np.mean(e**2))),
        "median_m": float(np.median(e)),
        "p95_m": float(np.percentile(e, 95)),
        "max_m": float(e.max()),
    }

    # 2. outage-end errors
    task, name, params, score = best_adaptive()
    agent = sim_agent()
    policies: dict[str, tuple[str, Any]] = {
        "plain": ("fading", neutral),
        f"{name} ({task}, tuned)": (task, lambda env: make_baseline(env, name, **params)),
    }
    if agent is not None:
        policies["sim-trained PPO (QuadrotorNoiseScale-v2 zoo)"] = ("noisescale", lambda env: agent)
    rows, plot_data = [], None
    for L in lengths:
        starts = [s for s in placements(L, args.quick) if s + L <= last_end]
        scen = [Scenario(duration=steps * DT, outages=(Outage(s, s + L),)) for s in starts]
        row: dict[str, Any] = {"outage_s": L, "placements": len(starts)}
        for label, (tk, factory) in policies.items():
            res = run(IDS[tk], factory, scen, steps)
            end = outage_end_errors(res, starts, L)
            row[f"{label} mean m"] = float(np.nanmean(end))
            row[f"{label} max m"] = float(np.nanmax(end))
            if label == "plain" and L == 10.0:
                plot_data = (res, len(starts) // 2, starts[len(starts) // 2], L)
        rows.append(row)
    if plot_data is not None:
        plot(*plot_data, out / "walk.png")

    with open(out / "table.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    fmt = [
        {k: (f"{v:.2f}" if isinstance(v, float) and k != "outage_s" else v) for k, v in r.items()}
        for r in rows
    ]
    report = "\n".join(
        [
            "# Replay of walk_0827: INS/GNSS on a real walk",
            "",
            f"No outage, plain EKF, {clean_row['epochs']} RTK-fixed epochs: horizontal error RMS "
            f"{clean_row['rms_m']:.3f} m, median {clean_row['median_m']:.3f} m, 95th percentile "
            f"{clean_row['p95_m']:.3f} m, max {clean_row['max_m']:.3f} m.",
            "",
            f"Outage-end horizontal error [m] (mean and max over the placements); best adaptive: "
            f"{name} of Replay{'Fading' if task == 'fading' else 'NoiseScale'}-v2, tuning score {score:.1f}.",
            "",
            markdown_table(fmt),
            "",
        ]
    )
    (out / "report.md").write_text(report)
    write_manifest(
        out,
        "experiments.replay",
        sys.argv[1:] if argv is None else list(argv),
        no_outage=clean_row,
        best_adaptive={"task": task, "name": name, "params": params, "score": score},
        sim_agent=str(ZOO_AGENT) if agent is not None else None,
        steps=steps,
        seed=SEED,
    )
    print(report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
