"""``python -m experiments.batch_width [--env ID] [--n-envs N ...]``: does a wider batch hurt learning?

The env's step has a fixed cost per call whatever the batch (``navgym bench step_profile``), so
more sub-environments per step train faster (``navgym bench train --n-envs N``). This study
checks what it does to learning: the id's PPO entry (``agents/configs/ppo.yml``) is trained at
each ``--n-envs`` with the **same rollout size** (``n_steps = n_envs x n_steps // N``: the same
number of PPO updates per environment step; only the GAE horizon per sub-environment shortens),
``--seeds`` each, on training seeds, and the periodic evaluation on 64 **tuning** episodes
(``eval/tune_rmse_m`` in TensorBoard, every ``eval_freq`` steps) gives the learning curve. No
held-out episode is used: this is a training-configuration question.

Writes ``OUT/curves.json`` (per setting and seed: steps, wall seconds, tuning RMSE), ``OUT/table.md``
(per setting: steps/s, the mean over seeds of the best and of the last tuning RMSE, the wall time to
reach the 16-env mean best within 5 %) and ``OUT/curves.png`` (tuning RMSE against steps and against
wall time, mean over seeds).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_ENV = "navgym/PedestrianNoiseScale-v3"
OUT = Path("results/batch_width")
QUICK_TIMESTEPS = 4096


def train_setting(env_id: str, n_envs: int, seed: int, out: Path, timesteps: int | None) -> dict[str, Any]:
    """One run of ``env_id``'s entry at ``n_envs`` (same rollout size); its curve and wall time."""
    from agents.training.config import load_config
    from agents.training.train import train
    from benchmarks.train import with_n_envs

    config = with_n_envs(load_config(env_id, "ppo"), n_envs)
    if timesteps is not None:
        config["eval_freq"] = max(1, timesteps // 4)
    t0 = time.perf_counter()
    folder = train(
        env_id, "ppo", config=config, seed=seed, total_timesteps=timesteps, out_dir=out, progress=False
    )
    wall = time.perf_counter() - t0
    steps, rmse = tuning_curve(folder / "tb")
    meta = json.loads((folder / "meta.json").read_text())
    return {
        "n_envs": n_envs,
        "n_steps": int(config["n_steps"]),
        "seed": seed,
        "wall_s": wall,
        "steps_per_s": meta["steps_per_s"],
        "steps": steps,
        "tune_rmse_m": rmse,
    }


def tuning_curve(tb: Path) -> tuple[list[int], list[float]]:
    """``(steps, eval/tune_rmse_m)`` of a run's TensorBoard logs (every event file under ``tb``)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    pts: dict[int, float] = {}
    for d in sorted({p.parent for p in tb.rglob("events.out.tfevents.*")}):
        acc = EventAccumulator(str(d))
        acc.Reload()
        if "eval/tune_rmse_m" in acc.Tags().get("scalars", []):
            pts.update({int(e.step): float(e.value) for e in acc.Scalars("eval/tune_rmse_m")})
    steps = sorted(pts)
    return steps, [pts[s] for s in steps]


def summary(runs: Sequence[dict[str, Any]]) -> list[dict[str, str]]:
    """One row per ``n_envs`` (module docstring)."""
    by: dict[int, list[dict[str, Any]]] = {}
    for r in runs:
        by.setdefault(r["n_envs"], []).append(r)
    base_n = min(by)
    target = float(np.mean([min(r["tune_rmse_m"]) for r in by[base_n]])) * 1.05
    rows = []
    for n, rs in sorted(by.items()):
        reach = []
        for r in rs:  # wall time to the target, steps converted at the run's mean rate
            hit = [s for s, v in zip(r["steps"], r["tune_rmse_m"], strict=True) if v <= target]
            reach.append(hit[0] / r["steps_per_s"] if hit else float("nan"))
        rows.append(
            {
                "n_envs x n_steps": f"{n} x {rs[0]['n_steps']}",
                "seeds": str(len(rs)),
                "steps/s": f"{np.mean([r['steps_per_s'] for r in rs]):,.0f}",
                "best tuning RMSE m (mean)": f"{np.mean([min(r['tune_rmse_m']) for r in rs]):.3f}",
                "last tuning RMSE m (mean)": f"{np.mean([r['tune_rmse_m'][-1] for r in rs]):.3f}",
                f"wall s to <= {target:.2f} m (per seed)": ", ".join(
                    "never" if not np.isfinite(x) else f"{x:.0f}" for x in reach
                ),
            }
        )
    return rows


def plot(runs: Sequence[dict[str, Any]], path: Path) -> None:
    """Mean tuning RMSE over seeds against steps and against wall time, one line per ``n_envs``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6))
    for n in sorted({r["n_envs"] for r in runs}):
        rs = [r for r in runs if r["n_envs"] == n]
        k = min(len(r["steps"]) for r in rs)
        steps = np.asarray(rs[0]["steps"][:k], float)
        mean = np.mean([r["tune_rmse_m"][:k] for r in rs], axis=0)
        rate = float(np.mean([r["steps_per_s"] for r in rs]))
        a1.plot(steps, mean, label=f"{n} sub-envs")
        a2.plot(steps / rate, mean, label=f"{n} sub-envs")
    a1.set_xlabel("environment steps")
    a2.set_xlabel("wall time [s] (steps / mean steps/s)")
    for a in (a1, a2):
        a.set_ylabel("tuning RMSE [m] (64 episodes, mean of seeds)")
        a.grid(alpha=0.3)
        a.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m experiments.batch_width", description=__doc__.split("\n\n")[1]
    )
    p.add_argument("--env", default=DEFAULT_ENV)
    p.add_argument("--n-envs", type=int, nargs="+", default=[16, 64])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--quick", action="store_true", help="a smoke run (tiny budgets)")
    a = p.parse_args(argv)
    import torch

    import navgym  # noqa: F401  (registers the ids)
    from agents.reporting import markdown_table
    from experiments.outputs import write_manifest

    torch.set_num_threads(1)
    timesteps = QUICK_TIMESTEPS if a.quick else None
    runs = []
    for n in a.n_envs:
        for s in a.seeds:
            r = train_setting(a.env, n, s, a.out / "runs" / f"n{n}" / f"seed_{s}", timesteps)
            print(
                f"  {n} sub-envs seed {s}: {r['wall_s']:.0f} s, best {min(r['tune_rmse_m']):.3f} m",
                flush=True,
            )
            runs.append(r)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "curves.json").write_text(json.dumps({"env_id": a.env, "runs": runs}, indent=1))
    table = markdown_table(summary(runs))
    (a.out / "table.md").write_text(table)
    plot(runs, a.out / "curves.png")
    write_manifest(a.out, "experiments.batch_width", argv, env_id=a.env, n_envs=a.n_envs, seeds=a.seeds)
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
