"""The per-row regime oracle of the RowScale ids (v3): the reach gate G1.

The RowScale task's ``regime_oracle`` (:meth:`navgym.envs.tasks.RowScaleTask.regime_knob`) sets
each row's noise multiplier from that row's true regime at each step (*nominal*, *noisy*: a true
variance above twice the filter's, *biased*: a true mean error) and the motion states' process
noise scale from the motion's (*nominal*, *event*), read from the step's truth: a table of five
scales ``(s_nominal, s_noisy, s_biased, s_q_nominal, s_q_event)``. It is the upper reference of
a policy that recognizes which rows are in which event, never a baseline.

The table is searched on **tuning** seeds: from the tuned constant baseline's scales (one row
scale, one process scale; the best constant table of a grid where none is tuned), coordinate
descent entry by entry over the grids (two passes at most), scored by the mean episode RMSE;
then evaluated on held-out **evaluation** seeds beside the best tuned classical
baseline (context-using ones included) and the plain filter, on the same episodes.

**Gate G1**: the regime oracle beats the best tuned baseline by at least 25 % RMSE with a paired
95 % CI excluding 0.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from agents.baselines import ConstantAction
from agents.baselines.registry import best_tuned, load_tuned, make_baseline
from agents.evaluation.bootstrap import DEFAULT_RESAMPLES, paired_difference
from agents.evaluation.metrics import episode_metrics
from agents.evaluation.runner import make_vector_env, rollout
from agents.seeds import seeds as seed_range
from navgym.envs.base import navigation_env
from navgym.envs.distinct import EpisodeCache

#: The table's entries, in the order of ``regime_oracle``.
ENTRIES = ("s_nominal", "s_noisy", "s_biased", "s_q_nominal", "s_q_event")
#: Grid of the row multipliers (0.3 to exclusion) and of the process-noise scales.
ROW_GRID = (0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 1e3, 1e4)
Q_GRID = (0.1, 1.0, 10.0, 100.0, 1e3, 1e4)
#: The gate's margin: the regime oracle's RMSE at least this far below the best tuned baseline's.
G1_MARGIN = 0.25


class RowRegimeScorer:
    """Mean episode RMSE of regime-oracle tables on fixed seeds (one env per table, the episodes
    simulated once)."""

    def __init__(
        self, env_id: str, seeds: Sequence[int], env_kwargs: Mapping[str, Any] | None = None
    ) -> None:
        self.env_id = env_id
        self.seeds = [int(s) for s in seeds]
        self.kwargs = dict(env_kwargs or {})
        self.cache = EpisodeCache(maxsize=1)

    def episodes(self, table: Sequence[float] | None, policy: Any = None) -> np.ndarray:
        """Per-episode RMSE [m] of the oracle with ``table`` (None: ``policy`` on the plain env)."""
        extra = {} if table is None else {"regime_oracle": tuple(float(v) for v in table)}
        env = make_vector_env(self.env_id, len(self.seeds), {**self.kwargs, **extra})
        nav = navigation_env(env)
        if policy is None:
            policy = ConstantAction(env.single_action_space, nav.task.neutral_action(), "oracle")
        elif callable(policy) and not hasattr(policy, "predict"):
            policy = policy(env)
        with self.cache.active():
            roll = rollout(env, policy, self.seeds)
        out = episode_metrics(roll, float(nav.platform.divergence_m))["rmse_m"]
        env.close()
        return np.asarray(out)

    def __call__(self, table: Sequence[float]) -> float:
        return float(np.mean(self.episodes(table)))


def search_row_table(
    env_id: str,
    seeds: Sequence[int],
    progress: bool = True,
    env_kwargs: Mapping[str, Any] | None = None,
    start: Sequence[float] | None = None,
    passes: int = 2,
) -> tuple[np.ndarray, float, np.ndarray, float]:
    """A constant table to start from, then coordinate-descent passes over the five entries.

    The start is ``start`` (the tuned constant baseline's ``(s_r, s_r, s_r, s_q, s_q)``) or,
    without one, the best constant table on the grids; each pass tries every grid value of each
    entry in turn and keeps what lowers the mean RMSE; the search stops after ``passes`` passes
    or a pass that changed nothing. Returns ``(constant table, its mean RMSE, table, its mean
    RMSE)`` on ``seeds``.
    """
    score = RowRegimeScorer(env_id, seeds, env_kwargs)
    if start is None:
        constants = [np.array([r, r, r, q, q], dtype=np.float64) for r in ROW_GRID for q in Q_GRID]
    else:
        constants = [np.asarray(start, dtype=np.float64)]
    grids = (ROW_GRID, ROW_GRID, ROW_GRID, Q_GRID, Q_GRID)
    bar = tqdm(
        total=len(constants) + passes * sum(len(g) for g in grids),
        desc=env_id.split("/")[-1],
        disable=not progress,
    )
    best_c, best = constants[0], np.inf
    for c in constants:
        r = score(c)
        bar.update()
        if r < best:
            best_c, best = c, r
    table, best_t = best_c.copy(), best
    for _ in range(passes):
        changed = False
        for i, grid in enumerate(grids):
            for v in grid:
                trial = table.copy()
                trial[i] = v
                r = score(trial) if v != table[i] else best_t
                bar.update()
                if r < best_t - 1e-12:
                    table, best_t, changed = trial, r, True
        if not changed:
            break
    bar.close()
    return best_c, best, table, best_t


def tuned_constant_table(env_id: str) -> np.ndarray | None:
    """``(s_r, s_r, s_r, s_q, s_q)`` of the tuned ``constant`` RowScale baseline, or None."""
    c = load_tuned(env_id).get("constant")
    if not c or "s_r" not in c or "s_q" not in c:
        return None
    r, q = float(c["s_r"]), float(c["s_q"])
    return np.array([r, r, r, q, q])


def row_study(
    env_id: str,
    tune_episodes: int,
    episodes: int,
    n_boot: int = DEFAULT_RESAMPLES,
    progress: bool = True,
    env_kwargs: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Search the table on tuning seeds; evaluate it, the best tuned baseline and plain held out."""
    t0 = time.perf_counter()
    const, const_tune, table, table_tune = search_row_table(
        env_id, seed_range("tune", tune_episodes), progress, env_kwargs, start=tuned_constant_table(env_id)
    )
    score = RowRegimeScorer(env_id, seed_range("eval", episodes), env_kwargs)
    base_name, _ = best_tuned(env_id)
    params = load_tuned(env_id).get(base_name, {})
    rm = {
        "plain": score.episodes(None),
        base_name: score.episodes(None, lambda env: make_baseline(env, base_name, **params)),
        "regime oracle": score.episodes(table),
    }
    d = paired_difference(rm[base_name], rm["regime oracle"], n_boot=n_boot)
    b = float(np.mean(rm[base_name]))
    reach, low = float(d["mean_diff"]) / b, float(d["low"]) / b
    return {
        "env_id": env_id,
        "best_tuned": base_name,
        "constant_action": const.tolist(),
        "constant_tune_rmse_m": const_tune,
        "table": dict(zip(ENTRIES, table.tolist(), strict=True)),
        "table_tune_rmse_m": table_tune,
        "eval_rmse_m": {k: float(np.mean(v)) for k, v in rm.items()},
        "reach": reach,
        "reach_low": low,
        "reach_high": float(d["high"]) / b,
        "g1": bool(reach >= G1_MARGIN and low > 0.0),
        "tune_episodes": tune_episodes,
        "episodes": episodes,
        "seconds": time.perf_counter() - t0,
    }
