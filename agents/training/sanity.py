"""A quick check of a trained agent against a fixed policy on a few seeds (not the evaluation).

The held-out comparison with tuned baselines is :mod:`agents.evaluation`'s job, on evaluation
seeds. This module only answers "does the agent beat the plain filter at all?" on a handful of
training or tuning seeds, to decide whether more training is needed; the zoo READMEs quote it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from agents.policy_runner import CallableRunner, PolicyRunner, PredictRunner
from navgym.envs.base import navigation_env

#: A memoryless ``obs (B, d) -> actions`` function, or a :class:`PolicyRunner` (memory per episode).
Policy = Callable[[np.ndarray], np.ndarray] | PolicyRunner
#: Cap of a step's position error in the RMSE [m] (the GpsIns divergence bound).
ERROR_CAP_M = 2000.0


def constant_policy(action: Any) -> Policy:
    """A policy that always takes ``action`` (``-1``: the plain filter of Fading and Mixture)."""
    a = np.asarray(action)

    def act(obs: np.ndarray) -> np.ndarray:
        return np.broadcast_to(a, (obs.shape[0], *a.shape)).copy()

    return act


def ess_threshold_policy(obs_index: int, threshold: float = 0.5) -> Policy:
    """Resample (action 1) when the observed ESS / N falls below ``threshold``."""

    def act(obs: np.ndarray) -> np.ndarray:
        return (obs[:, obs_index] < threshold).astype(np.int64)

    return act


def agent_policy(agent: Any) -> PolicyRunner:
    """A policy from anything with SB3's ``predict`` (deterministic actions).

    Its state (a recurrent agent's LSTM states, stacked frames) is carried per episode.
    """
    return PredictRunner(agent, deterministic=True)


def as_runner(policy: Policy) -> PolicyRunner:
    """``policy`` itself when it is a :class:`PolicyRunner`, else a memoryless function's runner."""
    return policy if isinstance(policy, PolicyRunner) else CallableRunner(policy)


def run_episodes(
    policy: Policy, env_id: str, seeds: Sequence[int], env_kwargs: dict[str, Any] | None = None
) -> dict[str, np.ndarray]:
    """One episode per seed (all in one native vector env); per-episode return and errors.

    Returns a dict of ``(len(seeds),)`` arrays: ``return``, ``rmse_m`` (horizontal position RMSE
    over the whole horizon, each step's error capped at ``ERROR_CAP_M``; an episode that
    diverged counts the cap for every step it did not run, so ending early never looks good),
    ``mean_err_m`` (same convention), ``diverged`` and ``steps`` (steps actually run).
    """
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the environments

    kw = {"eval_info": False, **(env_kwargs or {})}
    env = gym.make_vec(env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", **kw)
    B = len(seeds)
    runner = as_runner(policy)
    obs, _ = env.reset(seed=[int(s) for s in seeds])
    runner.reset()
    ret, sq, err, steps = np.zeros(B), np.zeros(B), np.zeros(B), np.zeros(B, dtype=np.int64)
    diverged = np.zeros(B, dtype=bool)
    alive = np.ones(B, dtype=bool)
    while alive.any():
        obs, r, term, trunc, info = env.step(runner.act(obs))
        runner.reset(term | trunc)  # autoreset rows start new episodes (their records are ignored)
        e = np.nan_to_num(np.asarray(info["pos_err_m"], dtype=np.float64), nan=np.inf)
        ret += np.where(alive, r, 0.0)
        sq += np.where(alive, np.minimum(e, ERROR_CAP_M) ** 2, 0.0)
        err += np.where(alive, np.minimum(e, ERROR_CAP_M), 0.0)
        steps += alive
        diverged |= alive & term
        alive &= ~(term | trunc)
    horizon = navigation_env(env).horizon
    env.close()
    missing = np.maximum(horizon - steps, 0)
    sq += missing * ERROR_CAP_M**2
    err += missing * ERROR_CAP_M
    return {
        "return": ret,
        "rmse_m": np.sqrt(sq / max(horizon, 1)),
        "mean_err_m": err / max(horizon, 1),
        "diverged": diverged,
        "steps": steps,
    }


def compare(
    policies: dict[str, Policy], env_id: str, seeds: Sequence[int], env_kwargs: dict[str, Any] | None = None
) -> dict[str, dict[str, float]]:
    """Mean return, RMSE, divergences of each policy on the same seeds, and win rate vs the first."""
    runs = {name: run_episodes(p, env_id, seeds, env_kwargs) for name, p in policies.items()}
    ref = next(iter(runs.values()))["return"]
    out = {}
    for name, r in runs.items():
        out[name] = {
            "mean_return": float(r["return"].mean()),
            "sem_return": float(r["return"].std(ddof=1) / np.sqrt(len(seeds))) if len(seeds) > 1 else 0.0,
            "mean_rmse_m": float(r["rmse_m"].mean()),
            "median_rmse_m": float(np.median(r["rmse_m"])),
            "diverged": int(r["diverged"].sum()),
            "mean_diff_vs_first": float((r["return"] - ref).mean()),
            "win_rate_vs_first": float((r["return"] > ref).mean()),
        }
    return out


def format_table(results: dict[str, dict[str, float]]) -> str:
    """Markdown table of :func:`compare`'s result."""
    rows = [
        "| policy | mean return | +- sem | mean RMSE [m] | median RMSE [m] | diverged | diff vs 1st | wins |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, r in results.items():
        rows.append(
            f"| {name} | {r['mean_return']:.1f} | {r['sem_return']:.1f} | {r['mean_rmse_m']:.2f} | "
            f"{r['median_rmse_m']:.2f} | {r['diverged']} | {r['mean_diff_vs_first']:+.1f} | "
            f"{r['win_rate_vs_first']:.2f} |"
        )
    return "\n".join(rows)
