"""Classical resampling triggers: per-filter decisions ``(B,)`` from the log-weights.

These are the hand-tuned baselines an agent's resampling decision competes with; both return a
``(B,)`` boolean that plugs into :func:`filters.particle.bootstrap.resample` (or ``update``'s
``decision``).
"""

from __future__ import annotations

import numpy as np

from filters.core.resampling import check_log_weights
from filters.core.validation import batched_vector
from filters.particle.estimates import ess, logsumexp

__all__ = ["ess_trigger", "redistribution_trigger"]


def _fraction(value: object, B: int, name: str, low_open: bool) -> np.ndarray:
    v = batched_vector(value, B, name)
    low_ok = (v > 0) if low_open else (v >= 0)
    if not (np.isfinite(v).all() and low_ok.all() and (v <= 1).all()):
        interval = "(0, 1]" if low_open else "[0, 1]"
        raise ValueError(f"{name} must lie in {interval}; got {value!r}")
    return v


def ess_trigger(log_w: np.ndarray, threshold_fraction: np.ndarray | float = 0.5) -> np.ndarray:
    """Resample when ``ESS < threshold_fraction * N`` (Kong, Liu & Wong 1994; Liu & Chen 1998).

    ``ESS = 1 / sum_i w_i^2`` of the normalized weights.

    Args:
        log_w: log-weights ``(B, N)``.
        threshold_fraction: in ``[0, 1]``, scalar or ``(B,)``; 0 never resamples, 1 resamples
            unless the weights are exactly uniform.

    Returns:
        ``(B,)`` booleans.

    Raises:
        ValueError: naming ``log_w`` or ``threshold_fraction``.

    """
    lw = check_log_weights(log_w)
    B, N = lw.shape
    thr = _fraction(threshold_fraction, B, "threshold_fraction", low_open=False)
    # a small relative slack keeps exactly uniform weights (ESS = N up to rounding) un-triggered
    return ess(lw) < thr * N * (1.0 - 1e-12)


def redistribution_trigger(
    log_w: np.ndarray,
    weight_factor: np.ndarray | float = 0.1,
    count_fraction: np.ndarray | float = 0.1,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Carvalho et al. 1997's redistribution rule (§V, the PF simulation; §III-D for the redistribution).

    "Redistribution occurs when the number of particles whose weights are smaller than
    ``1/(10N)`` is higher than 10% of the total number of particles N": with the defaults,
    ``#{i : w_i < weight_factor / N} > count_fraction * N``.

    Args:
        log_w: log-weights ``(B, N)`` (normalized internally).
        weight_factor: light-particle threshold relative to ``1/N``, in ``(0, 1]``, scalar or
            ``(B,)`` (Carvalho et al. 1997: 0.1).
        count_fraction: fraction of N that must be light, in ``[0, 1]``, scalar or ``(B,)``
            (Carvalho et al. 1997: 0.1).
        weights: the normalized linear weights ``exp(log_w)`` ``(B, N)`` if already computed
            (not re-checked): the rule is then ``w_i < weight_factor / N``, the same to
            rounding, without normalizing ``log_w`` again.

    Returns:
        ``(B,)`` booleans.

    Raises:
        ValueError: naming ``log_w``, ``weight_factor``, ``count_fraction`` or ``weights``.

    """
    lw = check_log_weights(log_w)
    B, N = lw.shape
    wf = _fraction(weight_factor, B, "weight_factor", low_open=True)
    cf = _fraction(count_fraction, B, "count_fraction", low_open=False)
    if weights is not None:
        if np.shape(weights) != (B, N):
            raise ValueError(f"weights must have shape {(B, N)} like log_w; got {np.shape(weights)}")
        light_count = (np.asarray(weights) < (wf / N)[:, None]).sum(axis=1)
    else:
        log_norm = logsumexp(lw, axis=1)
        light_count = ((lw - log_norm[:, None]) < np.log(wf / N)[:, None]).sum(axis=1)
    return light_count > cf * N
