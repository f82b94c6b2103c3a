"""Sigma-point Kalman filter with a pluggable quadrature rule: UKF, CKF and GHKF in one.

Time update (Benzerrouk 2014, eq. 51-54): ``X_l = m + chol(P) xi_l``, ``X*_l = f(X_l)``,
``m- = sum wm_l X*_l``, ``P- = lambda sum wc_l (X*_l - m-)(X*_l - m-)^T + Q`` where the fading
factor ``lambda`` (Benzerrouk 2014, eq. 64, applied to the centred spread) defaults to 1.

Measurement update (eq. 55-62): sigma points are redrawn from the predicted ``N(m-, P-)``
(so ``Q`` is seen by the measurement prediction, as filterpy's UKF does),
``Z_l = h(X_l)``, ``z_hat = sum wm Z``, ``S = sum wc (Z - z_hat)(Z - z_hat)^T + R``,
``P_xz = sum wc (X - m-)(Z - z_hat)^T``, then :func:`filters.core.conditioning.condition`.

The rule is an argument: :class:`~filters.core.quadrature.Unscented` gives the UKF,
:class:`~filters.core.quadrature.Cubature` the CKF and
:class:`~filters.core.quadrature.GaussHermite` the GHKF.
"""

from __future__ import annotations

import numpy as np

from filters.core.conditioning import condition_moments
from filters.core.linalg import cholesky, symmetrize
from filters.core.models import ObservationModel, TransitionModel, innovation
from filters.core.quadrature import Cubature, Quadrature, SigmaPoints
from filters.core.types import GaussianState, MeasurementMoments, UpdateInfo
from filters.core.validation import batched_matrix, check_gaussian, check_measurement, fading_factor

__all__ = ["predict", "update", "sigma_points", "moments", "measurement_moments", "predict_measurement"]


def sigma_points(state: GaussianState, rule: Quadrature) -> tuple[np.ndarray, SigmaPoints, np.ndarray]:
    """Place a rule's points at ``m + chol(P) xi`` (Benzerrouk 2014, eq. 51).

    Returns:
        ``(X, points, ok)``: ``X`` of shape ``(B, S, n)``, the unit rule, and ``ok (B,)`` False where
        ``P`` needed jitter to be factorized.

    """
    m, P = state
    pts = rule.sigma_points(m.shape[1])
    chol_P, ok = cholesky(P)
    X = m[:, None, :] + pts.xi @ np.swapaxes(chol_P, -1, -2)
    return X, pts, ok


def moments(Y: np.ndarray, pts: SigmaPoints) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted mean, centred points and ``sum wc dY dY^T`` of transformed points ``(B, S, d)``."""
    y = pts.wm @ Y
    dY = Y - y[:, None, :]
    C = (np.swapaxes(dY, -1, -2) * pts.wc) @ dY
    return y, dY, C


def predict(
    state: GaussianState,
    model: TransitionModel,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    rule: Quadrature = Cubature(),
    fading: np.ndarray | float | None = None,
    Q: np.ndarray | None = None,
) -> GaussianState:
    """Sigma-point time update (Benzerrouk 2014, eq. 51-54; fading eq. 64).

    Args:
        state: filtered beliefs ``(B, n)``, ``(B, n, n)``.
        model: transition model (``f`` broadcasting over ``(B, S, n)``, ``Q``).
        u: control ``(B, p)`` or None; the model receives it unchanged.
        dt: time step, seconds.
        rule: quadrature rule (default: cubature, i.e. the CKF).
        fading: fading factor ``lambda`` scalar or ``(B,)``; None means 1.
        Q: process noise override.

    Returns:
        The predicted state.

    """
    B, n = check_gaussian(state)
    Q = batched_matrix(model.Q if Q is None else Q, B, (n, n), "Q")
    lam = fading_factor(fading, B)
    X, pts, _ = sigma_points(state, rule)
    Xf = model.f(X, u, dt)
    if Xf.shape != X.shape:
        raise ValueError(f"model.f returned shape {Xf.shape} for sigma points {X.shape}")
    m_pred, _, C = moments(Xf, pts)
    if lam is not None:
        C = lam[:, None, None] * C
    return GaussianState(m_pred, symmetrize(C + Q))


def measurement_moments(
    state: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    rule: Quadrature = Cubature(),
) -> MeasurementMoments:
    """Sigma-point measurement prediction of :func:`update` (Benzerrouk 2014, eq. 55-59), R excluded.

    ``Z_l = h(X_l)`` at points drawn from ``N(m, P)``, then ``z_hat``, ``C`` and ``P_xz``. The
    noise enters only through ``S = C + R``, so updates of one prior under several noise
    covariances (Gaussian-sum filters, Benzerrouk 2014, eq. 72: ``S_j = P_yy + R_j``) share these
    moments: :func:`filters.gaussian_sum.mixture_update` computes them once per filter.

    Args:
        state: predicted beliefs.
        z: measurements ``(B, m)``; masked rows may hold NaN.
        model: observation model (``h`` broadcasting over ``(B, S, n)``).
        mask: ``(B, m)`` booleans (masked entries of ``z`` are ignored).
        rule: quadrature rule (default cubature).

    Returns:
        :class:`MeasurementMoments`.
    """
    B, _ = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    return predict_measurement(state, z, model, rule)


def predict_measurement(
    state: GaussianState, z: np.ndarray, model: ObservationModel, rule: Quadrature = Cubature()
) -> MeasurementMoments:
    """:func:`measurement_moments` for inputs already checked (``z`` with masked rows zeroed).

    The one implementation shared by :func:`update`, the adaptive filters of
    :mod:`filters.adaptive` and the Gaussian-sum filters.
    """
    X, pts, ok = sigma_points(state, rule)
    Z = model.h(X)
    B, S = X.shape[:2]
    if Z.shape != (B, S, z.shape[1]):
        raise ValueError(f"model.h returned shape {Z.shape}; expected {(B, S, z.shape[1])}")
    z_hat, dZ, C = moments(Z, pts)
    dX = X - state.m[:, None, :]
    P_xz = (np.swapaxes(dX, -1, -2) * pts.wc) @ dZ
    return MeasurementMoments(innovation(model, z, z_hat), C, P_xz, ok)


def update(
    state: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    rule: Quadrature = Cubature(),
    R: np.ndarray | None = None,
) -> tuple[GaussianState, UpdateInfo]:
    """Sigma-point measurement update (Benzerrouk 2014, eq. 55-62).

    Args:
        state: predicted beliefs.
        z: measurements ``(B, m)``; masked rows may hold NaN.
        model: observation model (``h`` broadcasting over ``(B, S, n)``, ``R``).
        mask: ``(B, m)`` booleans, False rows are ignored exactly.
        rule: quadrature rule (default cubature).
        R: measurement noise override.

    Returns:
        ``(filtered state, UpdateInfo)``.

    """
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    R = batched_matrix(model.R if R is None else R, B, (mdim, mdim), "R")
    mom = predict_measurement(state, z, model, rule)
    return condition_moments(state.m, state.P, mom, R, mask)
