"""Gaussian filter update under per-row mixture noise: each measurement row its own outliers.

A GNSS receiver's pseudo-ranges (or a GPS and a GLONASS fix) are contaminated independently:
satellite 7 may be in a multipath segment while satellite 12 is clean. The two-component noise
of Benzerrouk 2014, eq. 71, applied **per row** ``i`` (with ``R`` diagonal, rows independent)::

    v_i ~ (1 - eps_i) N(0, R_ii) + eps_i N(0, ratio_i R_ii)

has ``2^m`` joint components; the exact posterior is a ``2^m``-term Gaussian sum. This module
processes the rows sequentially, the classical equivalent of a batch update with diagonal ``R``
(Bar-Shalom et al. 2001, §3.4: sequential processing of independent measurements), each row by
the Gaussian-sum update of :func:`filters.gaussian_sum.update` (eq. 72-74: two base-filter
updates, ``alpha_ij ∝ pi_ij N(v_i; 0, S_ij)``) followed by moment matching to one Gaussian
(eq. 75-76), so the cost is ``2m`` single-row updates and the belief stays Gaussian. With every
``eps_i = 0`` (or 1) and a linear model it equals the Kalman update with ``R`` (or with every
row inflated by its ratio) exactly; the reduction after each row is the approximation (the same
as Runnalls' reduction to one component, Runnalls 2007).

The loop runs over the ``m`` rows (at most a few tens): sequential processing is the algorithm;
the batch axis stays vectorized.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from filters import gaussian_sum
from filters.core.models import ObservationModel
from filters.core.types import GaussianState
from filters.core.validation import as_float_array, check_gaussian, check_measurement
from filters.registry import GaussianFilter
from filters.registry import get as get_filter

__all__ = ["RowMixtureInfo", "update"]


class RowMixtureInfo(NamedTuple):
    """Diagnostics of a per-row mixture update (the fields of ``UpdateInfo`` plus the weights).

    Attributes:
        innovation: each row's innovation when it was processed (the sequential innovation:
            row i against the belief updated with rows < i), ``(B, m)``, 0 on masked rows.
        S: diagonal ``(B, m, m)``: each row's mixture predictive variance at its turn
            (``(1 - a) S_nominal + a S_outlier`` with the prior weights); 1 on masked rows.
        nis: ``sum_i v_i^2 / S_ii`` over the rows used, ``(B,)``.
        log_likelihood: ``sum_i log p(z_i | z_<i)`` of the sequential mixture evidences, ``(B,)``.
        healthy: every row's update healthy and the posterior finite, ``(B,)``.
        n_meas: rows used, ``(B,)``.
        ess: None (particle filters only).
        resampled: None (particle filters only).
        outlier_posterior: posterior weight ``alpha_i`` of the outlier component per row,
            ``(B, m)``; the prior ``eps_i`` on masked rows (nothing was learned).

    """

    innovation: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    log_likelihood: np.ndarray
    healthy: np.ndarray
    n_meas: np.ndarray
    ess: np.ndarray | None
    resampled: np.ndarray | None
    outlier_posterior: np.ndarray


def update(
    state: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    *,
    eps: np.ndarray,
    variance_ratio: float | np.ndarray = 100.0,
    base: GaussianFilter | str = "ckf",
) -> tuple[GaussianState, RowMixtureInfo]:
    """Sequential per-row Gaussian-sum update (see the module docstring for the equations).

    Args:
        state: predicted beliefs ``(B, n)``, ``(B, n, n)``.
        z: measurements ``(B, m)``.
        model: observation model of the base filter; its ``R`` ``(m, m)`` or ``(B, m, m)`` must
            be diagonal (independent rows).
        mask: ``(B, m)`` booleans or None; a masked row contributes exactly nothing.
        eps: prior outlier weight per row, ``(B, m)`` or ``(m,)``, in [0, 1].
        variance_ratio: outlier variance over nominal variance, a scalar or ``(m,)``, > 1.
        base: base filter (registry name or :class:`~filters.registry.GaussianFilter`).

    Returns:
        ``(posterior GaussianState, RowMixtureInfo)``.

    """
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    m = z.shape[1]
    R = as_float_array(model.R, "model.R")
    if R.shape not in ((m, m), (B, m, m)):
        raise ValueError(f"model.R must have shape ({m}, {m}) or ({B}, {m}, {m}); got {R.shape}")
    if np.any(R * (1.0 - np.eye(m)) != 0.0):
        raise ValueError("model.R must be diagonal: the per-row mixture assumes independent rows")
    e = as_float_array(eps, "eps")
    e = np.broadcast_to(e, (B, m)) if e.shape in ((m,), (B, m)) else None
    if e is None:
        raise ValueError(f"eps must have shape ({B}, {m}) or ({m},); got {np.shape(eps)}")
    if not (np.isfinite(e).all() and (e >= 0.0).all() and (e <= 1.0).all()):
        raise ValueError("eps must lie in [0, 1]")
    ratio = np.broadcast_to(as_float_array(variance_ratio, "variance_ratio"), (m,))
    if not (np.isfinite(ratio).all() and (ratio > 1.0).all()):
        raise ValueError(f"variance_ratio must be finite and > 1; got {variance_ratio!r}")

    flt = get_filter(base) if isinstance(base, str) else base
    R_b = np.broadcast_to(R, (B, m, m))
    with np.errstate(divide="ignore"):  # log 0 = -inf: a component of weight 0
        log_pi = np.log(np.stack([1.0 - e, e], axis=2))  # (B, m, 2)
    rows = np.arange(m)
    v = np.zeros((B, m))
    s = np.ones((B, m))
    ll = np.zeros(B)
    healthy = np.ones(B, dtype=bool)
    alpha = e.copy()
    post = state
    for i in range(m):
        R_out = R_b.copy()
        R_out[:, i, i] *= ratio[i]
        row_mask = mask & (rows == i)
        # the inputs were checked above (R diagonal and finite, eps in [0, 1], ratio > 1): the
        # row's Gaussian-sum update without re-checking them (the same numbers)
        new, info = gaussian_sum.update_checked(
            post, z, model, row_mask, np.stack([R_b, R_out], axis=1), log_pi[:, i], flt
        )
        used = mask[:, i]
        # a filter without row i keeps its belief bit for bit (no rounding of a moment match)
        post = GaussianState(
            np.where(used[:, None], new.m, post.m), np.where(used[:, None, None], new.P, post.P)
        )
        v[:, i] = np.where(used, info.innovation[:, i], 0.0)
        s[:, i] = np.where(used, info.S[:, i, i], 1.0)
        ll += np.where(used, info.log_likelihood, 0.0)
        healthy &= info.healthy | ~used
        alpha[:, i] = np.where(used, np.exp(info.log_weights[:, 1]), e[:, i])
    S = np.zeros((B, m, m))
    S[:, rows, rows] = s
    out = RowMixtureInfo(
        innovation=v,
        S=S,
        nis=(v * v / s).sum(axis=1),
        log_likelihood=ll,
        healthy=healthy & np.isfinite(post.m).all(axis=1) & np.isfinite(post.P).all(axis=(1, 2)),
        n_meas=mask.sum(axis=1),
        ess=None,
        resampled=None,
        outlier_posterior=alpha,
    )
    return post, out
