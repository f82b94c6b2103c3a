"""The v3 agents on real data: ``navgym/ReplayRowScale-v3`` (the packaged walk, injected events).

``python -m experiments.learned_v3 replay [--episodes 256]``: on held-out windows of the walk
(evaluation seeds of :mod:`agents.seeds`; each seed draws a window and its injected events), the
plain filter, the best tuned baseline of the replay id (the bar: :func:`agents.baselines.registry.best_tuned`,
tuned on tuning windows with ``navgym tune --env navgym/ReplayRowScale-v3 --episodes 256``), and
the simulation-trained agents of ``navgym/QuadrotorRowScale-v3`` run untouched (the replay id has
its observation layout): the supervised agent and the PPO zoo agent. Nothing is trained on the walk.
No target (the issue asks for the number, whatever it is): a walker's IMU is far from a
quadrotor's (its ``imu_activity`` sits where a quadrotor's vibration bursts do), so this measures
how the simulation-trained agents transfer, not what an agent trained on walks could do.

Writes ``OUT/replay.json`` (per-episode RMSEs) and ``OUT/replay.md``; ``--readme`` puts the table
into this study's README (between ``<!-- learned-v3-replay:begin/end -->``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from experiments.learned_v3.policies import plain_and_bar, rmse_of

#: The real-data id and the simulated id whose agents run on it.
REPLAY_ID = "navgym/ReplayRowScale-v3"
SOURCE_ID = "navgym/QuadrotorRowScale-v3"
ZOO = Path("agents/zoo")
BEGIN, END = "<!-- learned-v3-replay:begin -->", "<!-- learned-v3-replay:end -->"


def replay_policies() -> tuple[dict[str, Any], str]:
    """``({name: env -> policy}, bar name)``: plain, the replay id's bar, the Quadrotor's agents."""
    from agents.supervised.files import load_policy
    from agents.training import load_agent

    pol, bar = plain_and_bar(REPLAY_ID)
    name = SOURCE_ID.split("/")[-1]
    pol[f"supervised ({name})"] = lambda env: load_policy(ZOO / f"{name}-supervised", env)
    pol[f"PPO ({name})"] = lambda env: load_agent(ZOO / name, env=env)
    return pol, bar


def evaluate_replay(episodes: int, n_boot: int) -> dict[str, Any]:
    """Every policy's per-episode RMSE on the same held-out windows, and the paired comparisons."""
    from agents.evaluation.comparison import delta_rmse
    from agents.seeds import seeds as seed_range

    pol, bar = replay_policies()
    rm = rmse_of(REPLAY_ID, pol, seed_range("eval", episodes), {})
    return {
        "env_id": REPLAY_ID,
        "episodes": episodes,
        "bar": bar,
        "rmse_m": {k: float(np.nanmean(v)) for k, v in rm.items()},
        "vs_plain": {k: delta_rmse(v, rm["plain"], n_boot) for k, v in rm.items() if k != "plain"},
        "vs_bar": {k: delta_rmse(v, rm[bar], n_boot) for k, v in rm.items() if k not in ("plain", bar)},
        "per_episode_rmse_m": {k: v.tolist() for k, v in rm.items()},
    }


def _pct(d: Mapping[str, Any] | None) -> str:
    return "" if d is None else f"{d['delta_pct']:+.1f} [{d['low_pct']:+.1f}, {d['high_pct']:+.1f}]"


def replay_rows(res: Mapping[str, Any]) -> list[dict[str, str]]:
    """One row per policy: RMSE, ΔRMSE % against plain and against the bar (paired 95 % CIs)."""
    rows = []
    for k, v in res["rmse_m"].items():
        role = {"plain": "plain EKF", res["bar"]: "bar (best tuned on the replay id)"}.get(
            k, "simulation-trained"
        )
        rows.append(
            {
                "policy": f"`{k}`",
                "role": role,
                "RMSE m": f"{v:.3f}",
                "vs plain % [95% CI]": _pct(res["vs_plain"].get(k)),
                "vs bar % [95% CI]": _pct(res["vs_bar"].get(k)),
            }
        )
    return rows
