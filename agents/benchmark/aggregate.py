"""Aggregates across training seeds: the interquartile mean and stratified-bootstrap CIs.

The estimators of Agarwal et al. 2021, "Deep Reinforcement Learning at the Edge of the
Statistical Precipice" (NeurIPS; the ``rliable`` library): with a handful of training seeds
(runs) per task, report the **IQM** (the 25 % trimmed mean over every run of every task,
``rliable.metrics.aggregate_iqm``, which is ``scipy.stats.trim_mean(scores, 0.25, axis=None)``)
and the mean, each with a **stratified percentile bootstrap** CI: every resample draws, for each
task (stratum) apart, as many runs as it has, with replacement, so the resamples keep every
task's share (``rliable.library.StratifiedBootstrap`` with ``task_bootstrap=False``).

Why not ``rliable`` itself: ``rliable 1.2.0`` (the newest) pins ``arch >= 5.3.1, < 8``, and the
newest such ``arch`` (7.2.0) fails at import with the project's pandas 3 (``deprecate_kwarg()
missing 1 required positional argument``); its ``StratifiedBootstrap`` also draws from NumPy's
global generator, not from the ``random_state`` it is given. This module is the two estimators
in NumPy (a seeded ``np.random.default_rng``), for ragged strata too (tasks with different
numbers of runs).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from agents.evaluation.bootstrap import DEFAULT_LEVEL

__all__ = ["SEED_RESAMPLES", "across_seeds", "iqm", "mean", "stratified_bootstrap_ci"]

#: Bootstrap resamples of the across-seed CIs (rliable's default ``reps``).
SEED_RESAMPLES = 50_000


def iqm(x: Any, axis: int | None = -1) -> Any:
    """Interquartile mean: the mean of the middle 50 % (``scipy.stats.trim_mean(x, 0.25)``).

    ``int(0.25 n)`` values are cut at each end (none for n < 4, where it is the mean), as
    ``rliable.metrics.aggregate_iqm``; ``axis=None`` over every value.
    """
    from scipy import stats  # imported here: `navgym -h` loads this module, scipy.stats takes ~0.5 s

    return stats.trim_mean(np.asarray(x, dtype=np.float64), 0.25, axis=axis)


def mean(x: Any, axis: int | None = -1) -> Any:
    """The plain mean (``np.mean``), the other aggregate of the leaderboard."""
    return np.mean(np.asarray(x, dtype=np.float64), axis=axis)


def _strata(scores: Any) -> list[np.ndarray]:
    """The runs of each task: a ``(runs, tasks)`` matrix's columns, one task's runs (1-D), or a list."""
    if isinstance(scores, np.ndarray):
        if scores.ndim == 1:
            return [scores.astype(np.float64)]
        if scores.ndim == 2:
            return [scores[:, j].astype(np.float64) for j in range(scores.shape[1])]
        raise ValueError(f"scores must be (runs,) or (runs, tasks); got shape {scores.shape}")
    if all(np.ndim(s) == 0 for s in scores):  # a list of numbers: one task's runs
        return [np.asarray(scores, dtype=np.float64)]
    return [np.asarray(s, dtype=np.float64).ravel() for s in scores]


def stratified_bootstrap_ci(
    scores: np.ndarray | Sequence[Any],
    statistic: Callable[..., Any] = iqm,
    reps: int = SEED_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    seed: int = 0,
) -> tuple[float, float, float]:
    """``statistic`` of every run of every task, with its stratified percentile bootstrap CI.

    Args:
        scores: a ``(runs, tasks)`` matrix (rliable's layout), one task's runs (a 1-D array or
            a list of numbers), or a list of each task's runs (ragged).
        statistic: maps ``(..., n)`` (every run of every task, tasks side by side) to ``(...)``
            along the last axis, e.g. :func:`iqm`, :func:`mean`.
        reps: bootstrap resamples.
        level: confidence level.
        seed: seed of ``np.random.default_rng``.

    Returns:
        ``(value, low, high)``; ``low = high = value`` when every task has one run.

    Raises:
        ValueError: no task, a task without runs, a non-finite score, ``level`` outside (0, 1)
            or ``reps < 1``.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1); got {level}")
    if reps < 1:
        raise ValueError(f"reps must be >= 1; got {reps}")
    strata = _strata(scores)
    if not strata or any(s.size == 0 for s in strata):
        raise ValueError(
            f"scores need at least one task and one run per task; got {[s.size for s in strata]}"
        )
    if not all(np.isfinite(s).all() for s in strata):
        raise ValueError("scores must be finite")
    value = float(statistic(np.concatenate(strata)))
    if all(s.size == 1 for s in strata):
        return value, value, value
    rng = np.random.default_rng(seed)
    boot = np.concatenate([s[rng.integers(0, s.size, size=(reps, s.size))] for s in strata], axis=1)
    lo, hi = np.quantile(np.asarray(statistic(boot), dtype=np.float64), [(1 - level) / 2, (1 + level) / 2])
    return value, float(lo), float(hi)


def across_seeds(
    scores: np.ndarray | Sequence[Any],
    reps: int = SEED_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    seed: int = 0,
) -> dict[str, Any]:
    """Mean and IQM of per-seed scores with their stratified-bootstrap CIs (strata: the tasks).

    Returns:
        ``{"n_runs", "mean", "mean_low", "mean_high", "iqm", "iqm_low", "iqm_high"}``.
    """
    strata = _strata(scores)
    out: dict[str, Any] = {"n_runs": int(sum(s.size for s in strata))}
    for name, fn, offset in (("mean", mean, 0), ("iqm", iqm, 1)):
        v, lo, hi = stratified_bootstrap_ci(strata, fn, reps, level, seed + offset)
        out.update({name: v, f"{name}_low": lo, f"{name}_high": hi})
    return out
