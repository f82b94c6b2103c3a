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
the batch axis stays vectorized, and a row that no filter of the batch has is skipped (it would
change nothing). Each row needs the base filter's measurement prediction of the current belief
(its sigma points and ``h``, or the EKF's ``h`` and ``H``; ``h`` of that row alone where the
model can predict one row, :class:`~filters.core.models.RowMaskable`); the rest, two
conditionings on one
scalar row and their moment match, is the compiled
:func:`filters.core.row_mixture_kernels.row_pass` where :mod:`filters.core.compiled` allows it
(float64 beliefs, a base filter with a measurement prediction: sigma-point, divided-difference,
KF/EKF). The reference is the base filter's banked Gaussian-sum update of the row,
:func:`filters.gaussian_sum.update_checked`, on the ``m``-row measurement with the other rows
masked; it runs under :func:`~filters.core.compiled.numpy_only`, for the other base filters (the
iterated EKF), and for any row where some filter is not one the kernel takes (jittered points,
an unhealthy component). The two agree to rounding.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from filters import gaussian_sum
from filters.core import row_mixture_kernels
from filters.core.compiled import compiled_enabled
from filters.core.models import ObservationModel, RowMaskable
from filters.core.types import GaussianState, MeasurementMoments
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
    # the base filter's measurement prediction (sigma-point, divided-difference, KF/EKF; None:
    # the iterated EKF, which relinearizes per component) feeds the compiled row kernel
    row_moments = flt.moments if compiled_enabled() and state.P.dtype == np.float64 else None
    # a model that can predict one row alone (RowMaskable) predicts only the row of each turn
    only_rows = model.only_rows if row_moments is not None and _row_maskable(type(model)) else None
    v = np.zeros((B, m))
    s = np.ones((B, m))
    ll = np.zeros(B)
    healthy = np.ones(B, dtype=bool)
    alpha = e.copy()
    post = state
    for i in range(m):
        used = mask[:, i]
        if not used.any():
            continue  # every filter keeps its belief; v 0, s 1, alpha eps: the defaults above
        row_mask = mask & (np.arange(m) == i)
        out = None
        if row_moments is not None:
            row_model = model if only_rows is None else only_rows(np.array([i]))
            out = _compiled_row(
                post, z, row_model, row_mask, row_moments, i, R_b, ratio[i], log_pi[:, i], used
            )
        if out is None:
            out = _row(post, z, model, row_mask, i, R_b, ratio[i], log_pi[:, i], used, flt)
        post, v_i, s_i, ll_i, healthy_i, alpha_i = out
        v[:, i] = v_i
        s[:, i] = s_i
        ll += ll_i
        healthy &= healthy_i
        alpha[:, i] = np.where(used, alpha_i, e[:, i])
    S = np.zeros((B, m, m))
    S[:, np.arange(m), np.arange(m)] = s
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


@lru_cache(maxsize=64)
def _row_maskable(cls: type) -> bool:
    """Whether a model class is :class:`~filters.core.models.RowMaskable`, looked up once per class.

    ``isinstance`` against the runtime-checkable Protocol costs about 7 us a call (more for a
    model without the method), in every update; the class's answer is cached.
    """
    return issubclass(cls, RowMaskable)


class _Row(NamedTuple):
    """One row's update of the batch: the belief after it and the row's diagnostics, all ``(B, ...)``.

    ``v`` the row's innovation (0 where unused), ``s`` the mixture's predictive variance (1 where
    unused), ``ll`` the log-evidence (0 where unused), ``healthy`` (True where unused) and
    ``alpha`` the outlier component's posterior weight (read where used only).
    """

    post: GaussianState
    v: np.ndarray
    s: np.ndarray
    ll: np.ndarray
    healthy: np.ndarray
    alpha: np.ndarray


def _row(
    post: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    row_mask: np.ndarray,
    i: int,
    R_b: np.ndarray,
    ratio: float,
    log_pi: np.ndarray,
    used: np.ndarray,
    flt: GaussianFilter,
) -> _Row:
    """Row ``i`` by the base filter's Gaussian-sum update (the reference path)."""
    R_out = R_b.copy()
    R_out[:, i, i] *= ratio
    # the inputs were checked by update() (R diagonal and finite, eps in [0, 1], ratio > 1): the
    # row's Gaussian-sum update without re-checking them (the same numbers)
    R_components = np.stack([R_b, R_out], axis=1)
    new, info = gaussian_sum.update_checked(post, z, model, row_mask, R_components, log_pi, flt)
    # a filter without row i keeps its belief bit for bit (no rounding of a moment match)
    kept = GaussianState(np.where(used[:, None], new.m, post.m), np.where(used[:, None, None], new.P, post.P))
    return _Row(
        kept,
        np.where(used, info.innovation[:, i], 0.0),
        np.where(used, info.S[:, i, i], 1.0),
        np.where(used, info.log_likelihood, 0.0),
        info.healthy | ~used,
        np.exp(info.log_weights[:, 1]),
    )


def _compiled_row(
    post: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    row_mask: np.ndarray,
    row_moments: Callable[..., MeasurementMoments],
    i: int,
    R_b: np.ndarray,
    ratio: float,
    log_pi: np.ndarray,
    used: np.ndarray,
) -> _Row | None:
    """Row ``i`` by :func:`filters.core.row_mixture_kernels.row_pass`, or None (take :func:`_row`).

    The base filter's measurement prediction of the row (its points and ``h``, or the EKF's ``h``
    and ``H``) is formed as its bank forms it (``model``: the whole model, or a
    :class:`~filters.core.models.RowMaskable` model's prediction of row ``i`` alone, the same
    numbers); the two-component conditioning and the moment
    matching, scalar for one row, are the kernel's. None where some filter with the row needed
    jitter for its points or is not taken by the kernel (the reference path handles those).
    """
    mom = row_moments(post, z, model, row_mask)
    if not (mom.ok | ~used).all():
        return None
    m, P = post
    B, n = m.shape
    m_new, P_new = np.empty((B, n)), np.empty((B, n, n))
    s, ll, alpha = np.empty(B), np.empty(B), np.empty(B)
    ok = np.empty(B, dtype=bool)
    f64 = np.float64
    row_mixture_kernels.row_pass(
        np.ascontiguousarray(m, dtype=f64), np.ascontiguousarray(P, dtype=f64),
        np.ascontiguousarray(mom.v[:, i], dtype=f64), np.ascontiguousarray(mom.C[:, i, i], dtype=f64),
        np.ascontiguousarray(mom.P_xz[:, :, i], dtype=f64), np.ascontiguousarray(R_b[:, i, i], dtype=f64),
        float(ratio), np.ascontiguousarray(log_pi, dtype=f64), np.ascontiguousarray(used),
        m_new, P_new, s, ll, alpha, ok,
    )  # fmt: skip
    if not ok.all():
        return None
    v = np.where(used, mom.v[:, i], 0.0)
    return _Row(GaussianState(m_new, P_new), v, s, ll, np.ones(B, dtype=bool), alpha)
