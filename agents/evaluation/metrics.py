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
    """``{metric: (B,)}`` for the metrics of :data:`METRICS` (module docstring)."""
    alive = roll.alive
    B = alive.shape[0]
    err = roll.steps["pos_err_m"]
    err = np.where(np.isfinite(err), err, divergence_m)
    err = np.where(alive, err, np.nan)
    extra = roll.steps.get("extra_err")
    scored = err if extra is None else err + np.where(np.isfinite(extra), extra, 0.0)
    out: dict[str, np.ndarray] = {m: np.full(B, np.nan) for m in METRICS}
    out["return"] = np.where(alive, roll.steps["reward"], 0.0).sum(axis=1)
    out["length"] = roll.length.astype(np.float64)
    out["diverged"] = roll.terminated.astype(np.float64)
    gnss = roll.steps.get("gnss_available")
    nees = roll.steps.get("nees")
    knob = roll.steps.get("knob")
    res = roll.steps.get("resampled")
    for i in range(B):
        n = int(roll.length[i])
        if n == 0:
            continue
        e = err[i, :n]
        out["rmse_m"][i] = np.sqrt(np.mean(e**2))
        out["scored_rmse_m"][i] = np.sqrt(np.mean(scored[i, :n] ** 2))
        out["p95_err_m"][i] = np.percentile(e, 95)
        out["max_err_m"][i] = e.max()
        if gnss is not None:
            no = ~gnss[i, :n].astype(bool)
            runs = outage_runs(no)
            out["n_outages"][i] = len(runs)
            if runs:
                out["outage_mean_err_m"][i] = e[no].mean()
                out["outage_end_err_m"][i] = np.mean([e[b - 1] for _, b in runs])
        if nees is not None:
            v = nees[i, :n]
            v = v[np.isfinite(v) & (v >= 0)]
            if v.size:
                out["mean_nees"][i] = v.mean()
        if knob is not None:
            k = knob[i, :n].astype(np.float64)
            out["mean_knob"][i] = np.nanmean(k) if np.isfinite(k).any() else np.nan
        if res is not None:
            out["resamples"][i] = float(np.asarray(res[i, :n], dtype=bool).sum())
    return out
