"""Per-episode evaluation metrics from a batched :class:`~agents.evaluation.runner.Rollout`.

All errors are horizontal position errors ``info["pos_err_m"]`` [m] over the steps of the
episode (until it terminates or is truncated); a non-finite error (possible at a divergence)
counts as the env's ``divergence_m``. Definitions:

* ``return``: sum of rewards (accuracy, costs, divergence penalty).
* ``rmse_m``: ``sqrt(mean(err^2))``; ``p95_err_m``: 95th percentile; ``max_err_m``.
* ``scored_rmse_m``: ``sqrt(mean((err + extra)^2))`` of the error the reward charges
  (:mod:`navgym.envs.core`: ``extra = info["extra_err"]``, the platform's
  ``PositionError.extra_error``: Jpa's weighted attitude error, SignalTracking's weighted Doppler
  error); equal to ``rmse_m`` on platforms without one.
* ``outage_mean_err_m``: mean error over the steps without any GNSS measurement
  (``info["gnss_available"]`` False); NaN for an episode without such steps.
* ``outage_end_err_m``: error at the last step of each outage (maximal run of steps without
  GNSS), averaged over the episode's outages; NaN without outages. ``n_outages`` counts them.
* ``mean_nees``: mean NEES over the steps (finite, non-negative values only: a negative value
  means an indefinite covariance). Degenerate covariances (e.g. a particle filter whose weights
  collapsed) give astronomically large values, so tables also show the median over episodes.
* ``diverged``: 1 if the episode terminated (health flag or divergence bound), else 0.
* ``resamples``: resamplings in the episode (Resample tasks; NaN elsewhere).
* ``mean_knob``: mean knob value (lambda, eps, or resampling rate).
* ``length``: steps.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["METRICS", "PAIRED_METRICS", "episode_metrics", "outage_runs"]

#: Metrics in table order.
METRICS = (
    "return",
    "rmse_m",
    "scored_rmse_m",
    "p95_err_m",
    "max_err_m",
    "outage_mean_err_m",
    "outage_end_err_m",
    "n_outages",
    "mean_nees",
    "diverged",
    "resamples",
    "mean_knob",
    "length",
)
#: Metrics compared pairwise against the reference policy.
PAIRED_METRICS = (
    "return",
    "rmse_m",
    "scored_rmse_m",
    "p95_err_m",
    "outage_mean_err_m",
    "outage_end_err_m",
    "mean_nees",
    "diverged",
)


def outage_runs(no_gnss: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs ``[start, end)`` of True in a 1-D boolean array."""
    x = np.concatenate([[False], np.asarray(no_gnss, dtype=bool), [False]])
    d = np.diff(x.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def episode_metrics(roll: Any, divergence_m: float) -> dict[str, np.ndarray]:
    """``{metric: (B,)}`` for the metrics of :data:`METRICS` (module docstring).

    Array passes over the ``(B, T)`` records (no loop over episodes: a tuning rollout holds up to
    1024 of them); an episode of no steps gets NaN everywhere but ``return``, ``length`` and
    ``diverged``. The 95th percentile is NumPy's linear one over the episode's own steps.
    """
    alive = np.asarray(roll.alive, dtype=bool)
    B, T = alive.shape
    n = np.asarray(roll.length, dtype=np.int64)
    has = n > 0
    err = roll.steps["pos_err_m"]
    err = np.where(np.isfinite(err), err, divergence_m)
    err = np.where(alive, err, np.nan)
    extra = roll.steps.get("extra_err")
    scored = err if extra is None else err + np.where(np.isfinite(extra), extra, 0.0)
    out: dict[str, np.ndarray] = {m: np.full(B, np.nan) for m in METRICS}
    out["return"] = np.where(alive, roll.steps["reward"], 0.0).sum(axis=1)
    out["length"] = n.astype(np.float64)
    out["diverged"] = np.asarray(roll.terminated).astype(np.float64)
    e0 = np.where(alive, err, 0.0)
    count = np.maximum(n, 1)
    out["rmse_m"] = np.where(has, np.sqrt((e0 * e0).sum(axis=1) / count), np.nan)
    s0 = np.where(alive, scored, 0.0)
    out["scored_rmse_m"] = np.where(has, np.sqrt((s0 * s0).sum(axis=1) / count), np.nan)
    out["max_err_m"] = np.where(has, np.where(alive, err, -np.inf).max(axis=1), np.nan)
    out["p95_err_m"] = np.where(has, _percentile_of_prefix(err, n, 95.0), np.nan)
    gnss = roll.steps.get("gnss_available")
    if gnss is not None:
        no = alive & ~np.asarray(gnss, dtype=bool)
        before = np.zeros_like(no)
        before[:, 1:] = no[:, :-1]
        after = np.zeros_like(no)
        after[:, :-1] = no[:, 1:]
        starts, ends = no & ~before, no & ~after  # the first and last step of each outage
        runs = starts.sum(axis=1)
        out["n_outages"] = np.where(has, runs, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean_out = np.where(no, e0, 0.0).sum(axis=1) / no.sum(axis=1)
            end_out = np.where(ends, e0, 0.0).sum(axis=1) / runs
        out["outage_mean_err_m"] = np.where(has & (runs > 0), mean_out, np.nan)
        out["outage_end_err_m"] = np.where(has & (runs > 0), end_out, np.nan)
    nees = roll.steps.get("nees")
    if nees is not None:
        with np.errstate(invalid="ignore"):
            ok = alive & np.isfinite(nees) & (nees >= 0)
        out["mean_nees"] = _mean_where(nees, ok)
    knob = roll.steps.get("knob")
    if knob is not None:
        k = np.asarray(knob, dtype=np.float64)
        out["mean_knob"] = _mean_where(k, alive & np.isfinite(k))
    res = roll.steps.get("resampled")
    if res is not None:
        out["resamples"] = np.where(has, (alive & np.asarray(res, dtype=bool)).sum(axis=1), np.nan).astype(
            float
        )
    return out


def _mean_where(x: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Per row, the mean of ``x`` over ``ok``; NaN for a row without such entries."""
    cnt = ok.sum(axis=1)
    total = np.where(ok, x, 0.0).sum(axis=1)
    return np.where(cnt > 0, total / np.maximum(cnt, 1), np.nan)


def _percentile_of_prefix(x: np.ndarray, n: np.ndarray, q: float) -> np.ndarray:
    """Per row, NumPy's linear ``q``-th percentile of ``x[i, :n_i]`` (NaN elsewhere in the row).

    ``np.sort`` puts the NaN last, so the row's values are its first ``n_i`` sorted entries; the
    virtual index ``(n_i - 1) q / 100`` is interpolated between its neighbours as
    :func:`numpy.percentile`'s ``"linear"`` method does (NaN where ``n_i = 0``).
    """
    s = np.sort(x, axis=1)
    pos = (np.maximum(n, 1) - 1) * (q / 100.0)
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, np.maximum(n, 1) - 1)
    rows = np.arange(x.shape[0])
    a, b = s[rows, lo], s[rows, hi]
    g = pos - lo
    # numpy's _lerp: a + (b - a) g, from the upper end where g >= 0.5 (exact at both ends)
    val = np.where(g >= 0.5, b - (b - a) * (1.0 - g), a + (b - a) * g)
    return np.where(n > 0, val, np.nan)
