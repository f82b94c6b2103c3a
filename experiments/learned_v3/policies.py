"""The study's shared pieces: the plain filter and the bar as policies, and the per-episode RMSE runner.

Both :mod:`experiments.learned_v3.__main__` (the simulated v3 ids) and
:mod:`experiments.learned_v3.replay` (the walk) score their agents beside these two references on
the same episodes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


def plain_and_bar(env_id: str) -> tuple[dict[str, Any], str]:
    """``({"plain": f, bar: f}, bar)``: policy factories ``env -> policy`` of the plain filter (the
    task's neutral action) and of the bar, the best tuned baseline of ``env_id`` by its tuning score
    (:func:`agents.baselines.registry.best_tuned`) with its tuned parameters."""
    from agents.baselines import ConstantAction
    from agents.baselines.registry import best_tuned, load_tuned, make_baseline
    from navgym.envs.base import navigation_env

    bar, _ = best_tuned(env_id)
    params = load_tuned(env_id).get(bar, {})
    return {
        "plain": lambda env: ConstantAction(
            env.single_action_space, navigation_env(env).task.neutral_action(), "plain"
        ),
        bar: lambda env: make_baseline(env, bar, **params),
    }, bar


def rmse_of(
    env_id: str, policies: Mapping[str, Any], seeds: Sequence[int], kwargs: Mapping[str, Any]
) -> dict[str, np.ndarray]:
    """Per-episode RMSE [m] of each policy (a factory ``env -> policy``) on the same episodes."""
    from agents.evaluation.runner import run_policies

    _, episodes, _, _ = run_policies(env_id, policies, list(seeds), dict(kwargs), progress=False)
    return {name: np.asarray(m["rmse_m"], dtype=float) for name, m in episodes.items()}
