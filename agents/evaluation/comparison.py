"""The learned agent against a fixed reference: ΔRMSE %, the clairvoyant capture share, the verdict.

Shared by ``navgym demo`` (:mod:`agents.demo`) and the study ``experiments.learned_v2``. Every
input is per-episode RMSEs on the **same** episodes (a paired comparison), the reference fixed
before the evaluation (e.g. :func:`agents.baselines.registry.best_tuned`, chosen on tuning
seeds).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from agents.evaluation.bootstrap import (
    DEFAULT_LEVEL,
    DEFAULT_RESAMPLES,
    paired_difference,
    paired_statistic_ci,
)

__all__ = ["NA", "TARGET_PCT", "capture_share", "delta_rmse", "verdict", "verdict_sentence"]

#: The improvement target of issue #22: ``target met`` needs ΔRMSE % <= -TARGET_PCT (and a CI below 0).
TARGET_PCT = 10.0
NA = "n/a"


def delta_rmse(
    agent: np.ndarray,
    reference: np.ndarray,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    seed: int = 0,
) -> dict[str, Any]:
    """``ΔRMSE % = 100 * mean_e(a_e - r_e) / mean_e(r_e)`` with its paired bootstrap CI.

    ``agent`` and ``reference`` are per-episode RMSEs on the same episodes (pairs with a
    non-finite value are dropped). The CI is :func:`~agents.evaluation.bootstrap.paired_difference`'s
    (percentile bootstrap over episodes of the differences) divided by the fixed ``mean_e(r_e)``.

    Returns:
        ``{"delta_m", "low_m", "high_m", "delta_pct", "low_pct", "high_pct", "reference_rmse_m", "n"}``.
    """
    a = np.asarray(agent, dtype=np.float64).ravel()
    r = np.asarray(reference, dtype=np.float64).ravel()
    d = paired_difference(a, r, n_boot, level, seed)
    ok = np.isfinite(a) & np.isfinite(r)
    ref = float(r[ok].mean()) if ok.any() else float("nan")
    scale = 100.0 / ref if ref > 0 else float("nan")
    return {
        "delta_m": d["mean_diff"],
        "low_m": d["low"],
        "high_m": d["high"],
        "delta_pct": d["mean_diff"] * scale,
        "low_pct": d["low"] * scale,
        "high_pct": d["high"] * scale,
        "reference_rmse_m": ref,
        "n": d["n"],
    }


def capture_share(
    plain: np.ndarray,
    agent: np.ndarray,
    clairvoyant: np.ndarray,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    seed: int = 0,
) -> dict[str, Any]:
    """``capture = (mean(plain) - mean(agent)) / (mean(plain) - mean(clairvoyant))`` with its CI.

    The three arrays are per-episode RMSEs on the same episodes (an episode with a non-finite
    value in any is dropped). Each of ``n_boot`` resamples draws episodes with replacement, the
    same for the three, and recomputes the ratio
    (:func:`~agents.evaluation.bootstrap.paired_statistic_ci`; a resample whose gap ``mean(plain)
    - mean(clairvoyant)`` is not positive has no ratio and is left out). NaN when the full
    sample's gap is not positive.

    Returns:
        ``{"capture", "low", "high", "n", "gap_m"}`` (fractions; ``gap_m`` the denominator).
    """
    p, a, c = (np.asarray(x, dtype=np.float64).ravel() for x in (plain, agent, clairvoyant))

    def capture(m: np.ndarray) -> np.ndarray:
        gap = m[..., 0] - m[..., 2]
        return np.where(gap > 0, (m[..., 0] - m[..., 1]) / gap, np.nan)

    share, lo, hi, n = paired_statistic_ci((p, a, c), capture, n_boot, level, seed)
    ok = np.isfinite(p) & np.isfinite(a) & np.isfinite(c)
    gap = float(p[ok].mean() - c[ok].mean()) if n else float("nan")
    return {"capture": share, "low": lo, "high": hi, "n": n, "gap_m": gap}


def verdict(delta_pct: float, low_pct: float, high_pct: float, target_pct: float = TARGET_PCT) -> str:
    """The agent against the reference from ΔRMSE % and its paired 95 % CI.

    ``"target met"``: the CI lies below 0 and ``delta_pct <= -target_pct``; ``"beats"``: the CI
    lies below 0; ``"worse"``: it lies above 0; ``"ties"``: it contains 0; ``"n/a"`` without a
    finite CI.
    """
    if not all(math.isfinite(x) for x in (delta_pct, low_pct, high_pct)):
        return NA
    if high_pct < 0:
        return "target met" if delta_pct <= -target_pct else "beats"
    if low_pct > 0:
        return "worse"
    return "ties"


def verdict_sentence(
    env_id: str, agent: str, reference: str, d: dict[str, Any], level: float = DEFAULT_LEVEL
) -> str:
    """One sentence: does ``agent`` beat ``reference`` on ``env_id``, with the paired CI of ΔRMSE %.

    ``d`` is :func:`delta_rmse`'s result (``n`` episodes).
    """
    v = verdict(d["delta_pct"], d["low_pct"], d["high_pct"])
    what = {
        "target met": "beats",
        "beats": "beats",
        "ties": "does not beat (a tie within the CI)",
        "worse": "does not beat (it is worse than)",
        NA: "cannot be compared with",
    }[v]
    return (
        f"On {env_id} ({d['n']} held-out episodes) the learned agent `{agent}` {what} the best "
        f"tuned classical baseline `{reference}`: ΔRMSE {d['delta_pct']:+.1f} % "
        f"[{d['low_pct']:+.1f}, {d['high_pct']:+.1f}] (paired {100 * level:.0f} % bootstrap CI; "
        f"RMSE {d['reference_rmse_m'] + d['delta_m']:.2f} m vs {d['reference_rmse_m']:.2f} m)."
    )
