"""The headroom of the best tuned baseline over the clairvoyant filter, and the gate of issue #21.

``headroom = (RMSE_base - RMSE_clairvoyant) / RMSE_base`` on the same episodes (RMSE: the mean
over episodes of each episode's RMSE), with a paired percentile-bootstrap CI over episodes
(:func:`headroom`); an id passes when the headroom is at least :data:`GATE` and its CI excludes
0 (:func:`passes`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES, paired_statistic_ci

__all__ = ["GATE", "headroom", "passes"]

#: Smallest headroom that passes (its CI must also exclude 0).
GATE = 0.20


def headroom(
    baseline: np.ndarray,
    clairvoyant: np.ndarray,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    seed: int = 0,
) -> dict[str, Any]:
    """``(mean(baseline) - mean(clairvoyant)) / mean(baseline)`` with its paired bootstrap CI.

    ``baseline`` and ``clairvoyant`` are per-episode RMSEs on the *same* episodes (pairs with a
    non-finite value are dropped); the CI is
    :func:`agents.evaluation.bootstrap.paired_statistic_ci`'s (episodes resampled as pairs, the
    ratio recomputed, its ``(1 -+ level)/2`` quantiles). NaN when ``mean(baseline) <= 0``.

    Returns:
        ``{"headroom", "low", "high", "n", "significant", "baseline_rmse", "clairvoyant_rmse"}``
        (``significant``: the CI excludes 0).
    """
    b = np.asarray(baseline, dtype=np.float64).ravel()
    c = np.asarray(clairvoyant, dtype=np.float64).ravel()
    h, lo, hi, n = paired_statistic_ci(
        (b, c), lambda m: np.where(m[..., 0] > 0, 1.0 - m[..., 1] / m[..., 0], np.nan), n_boot, level, seed
    )
    ok = np.isfinite(b) & np.isfinite(c)
    nan = float("nan")
    return {
        "headroom": h,
        "low": lo,
        "high": hi,
        "n": n,
        "significant": bool(n > 1 and (lo > 0 or hi < 0)),
        "baseline_rmse": float(b[ok].mean()) if n else nan,
        "clairvoyant_rmse": float(c[ok].mean()) if n else nan,
    }


def passes(h: Mapping[str, Any], threshold: float = GATE) -> bool:
    """The gate of #21: headroom >= ``threshold`` and its CI above 0."""
    return bool(np.isfinite(h["headroom"]) and h["headroom"] >= threshold and h["low"] > 0)
