"""Extended and cubature (sigma-point) information filters (Benzerrouk 2014, eq. 22-23, 79-82).

The state is carried as ``Y = P^-1`` and ``y = Y m`` (eq. 22). Measurements add information
(eq. 23)::

    I = H^T R^-1 H,   i = H^T R^-1 (v + H m-),   Y+ = Y- + I,   y+ = y- + i

with ``v = z - h(m-)``. The EIF linearizes with the Jacobian ``H``; the cubature information
filter (CIF, Pakki et al. 2011; Benzerrouk 2014, eq. 79-82) uses the statistical linearization
``H = (P-^-1 P_xz)^T`` from sigma points, so any :class:`~filters.core.quadrature.Quadrature`
gives a sigma-point information filter. The time update goes through covariance form (the
prediction of an information filter needs ``Y^-1`` anyway for a nonlinear ``f``).
Masked measurement rows get zero rows and columns in ``R^-1``, hence add no information.
"""

from __future__ import annotations

import numpy as np

from filters import kalman, sigma_point
from filters.core.conditioning import health, masked_covariance
from filters.core.linalg import LOG_2PI, spd_inverse, symmetrize
from filters.core.models import (
    LinearizedObservation,
    LinearizedTransition,
    ObservationModel,
    TransitionModel,
    innovation,
)
from filters.core.quadrature import Cubature, Quadrature
from filters.core.types import GaussianState, InformationState, UpdateInfo
from filters.core.validation import batched_matrix, check_measurement

__all__ = [
    "to_information",
    "to_gaussian",
    "eif_predict",
    "eif_update",
    "cif_predict",
    "cif_update",
]


def check_information(state: InformationState, name: str = "state") -> tuple[int, int]:
    """Validate an :class:`InformationState`; return ``(B, n)``."""
    y, Y = np.asarray(state.y), np.asarray(state.Y)
    if y.ndim != 2:
        raise ValueError(f"{name}.y must have shape (B, n); got {y.shape}")
    B, n = y.shape
    if Y.shape != (B, n, n):
        raise ValueError(f"{name}.Y must have shape {(B, n, n)}; got {Y.shape}")
    if not (np.isfinite(y).all() and np.isfinite(Y).all()):
        raise ValueError(f"{name} has non-finite entries")
    return B, n


def to_information(state: GaussianState) -> InformationState:
    """``Y = P^-1``, ``y = Y m`` (Benzerrouk 2014, eq. 22)."""
    Y = symmetrize(np.linalg.inv(state.P))
    return InformationState((Y @ state.m[:, :, None])[:, :, 0], Y)


def to_gaussian(state: InformationState) -> GaussianState:
    """``P = Y^-1``, ``m = P y``."""
    P = symmetrize(np.linalg.inv(state.Y))
    return GaussianState((P @ state.y[:, :, None])[:, :, 0], P)


def eif_predict(
    state: InformationState,
    model: LinearizedTransition,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    fading: np.ndarray | float | None = None,
    Q: np.ndarray | None = None,
) -> InformationState:
    """EIF time update: the EKF prediction of the equivalent Gaussian, back to information form."""
    check_information(state)
    return to_information(kalman.predict(to_gaussian(state), model, u, dt, fading=fading, Q=Q))


def cif_predict(
    state: InformationState,
    model: TransitionModel,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    rule: Quadrature = Cubature(),
    fading: np.ndarray | float | None = None,
    Q: np.ndarray | None = None,
) -> InformationState:
    """CIF time update: cubature prediction (Benzerrouk 2014, eq. 51-54) in information form."""
    check_information(state)
    pred = sigma_point.predict(to_gaussian(state), model, u, dt, rule=rule, fading=fading, Q=Q)
    return to_information(pred)


def _add_information(
    state: InformationState,
    m_pred: np.ndarray,
    P_pred: np.ndarray,
    H: np.ndarray,
    R: np.ndarray,
    v: np.ndarray,
    mask: np.ndarray,
) -> tuple[InformationState, UpdateInfo]:
    """Information update (Benzerrouk 2014, eq. 23, 80-81) for (pseudo-)observation matrix ``H (B, m, n)``."""
    B, mdim = v.shape
    w = mask.astype(np.float64)
    Rm = masked_covariance(np.asarray(R), w)
    R_inv, _, ok_R = spd_inverse(Rm)
    R_inv = R_inv * (w[:, :, None] * w[:, None, :])
    v = v * w
    Ht = np.swapaxes(H, -1, -2)
    HtRinv = Ht @ R_inv
    I = symmetrize(HtRinv @ H)
    i = (HtRinv @ (v + (H @ m_pred[:, :, None])[:, :, 0])[:, :, None])[:, :, 0]
    Y_new = symmetrize(state.Y + I)
    y_new = state.y + i
    # Diagnostics in innovation space: S = H P- H^T + R over the unmasked rows.
    S = masked_covariance(H @ P_pred @ Ht + Rm, w)
    S_inv, logdet, ok_S = spd_inverse(S)
    nis = (v * (S_inv @ v[:, :, None])[:, :, 0]).sum(axis=1)
    n_meas = mask.sum(axis=1)
    log_lik = -0.5 * (nis + logdet + n_meas * LOG_2PI)
    healthy = ok_R & ok_S & health(y_new, Y_new)
    return InformationState(y_new, Y_new), UpdateInfo(v, S, nis, log_lik, healthy, n_meas)


def eif_update(
    state: InformationState,
    z: np.ndarray,
    model: LinearizedObservation,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
) -> tuple[InformationState, UpdateInfo]:
    """Extended information filter update (Benzerrouk 2014, eq. 23) linearized at ``m- = Y^-1 y``."""
    B, n = check_information(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    R = batched_matrix(model.R if R is None else R, B, (mdim, mdim), "R")
    prior = to_gaussian(state)
    H = np.broadcast_to(batched_matrix(model.H(prior.m), B, (mdim, n), "H"), (B, mdim, n))
    v = innovation(model, z, model.h(prior.m))
    return _add_information(state, prior.m, prior.P, H, R, v, mask)


def cif_update(
    state: InformationState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    rule: Quadrature = Cubature(),
    R: np.ndarray | None = None,
) -> tuple[InformationState, UpdateInfo]:
    """Cubature information filter update (Benzerrouk 2014, eq. 79-82).

    ``P_xz`` from sigma points drawn from ``N(m-, P-)`` (eq. 82), pseudo-observation matrix
    ``H = (Y- P_xz)^T`` (eq. 79), then ``I`` and ``i`` of eq. 80-81.
    """
    B, n = check_information(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    R = batched_matrix(model.R if R is None else R, B, (mdim, mdim), "R")
    prior = to_gaussian(state)
    mom = sigma_point.predict_measurement(prior, z, model, rule)
    H = np.swapaxes(state.Y @ mom.P_xz, -1, -2)
    post, info = _add_information(state, prior.m, prior.P, H, R, mom.v, mask)
    return post, info._replace(healthy=info.healthy & mom.ok)
