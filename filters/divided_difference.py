"""Divided-difference filters DD1 and DD2 (Nørgaard, Poulsen & Ravn 2000; Benzerrouk 2014, eq. 24-41).

With ``s_j`` the columns of ``chol(P)`` and step ``h`` (``h^2 = 3`` is optimal for Gaussian
priors, Benzerrouk 2014, eq. 41), Stirling's interpolation gives the divided-difference matrices::

    S1[:, j] = (g(x + h s_j) - g(x - h s_j)) / (2 h)
    S2[:, j] = sqrt(h^2 - 1) / (2 h^2) (g(x + h s_j) + g(x - h s_j) - 2 g(x))

DD1 (first order): ``E[g] = g(x)``, ``Cov[g] = S1 S1^T``.
DD2 (second order; the central-difference Kalman filter, eq. 29-30 and 35-36):
``E[g] = (h^2 - n)/h^2 g(x) + 1/(2 h^2) sum_j (g(x + h s_j) + g(x - h s_j))``,
``Cov[g] = S1 S1^T + S2 S2^T``. The cross covariance is ``P_xg = chol(P) S1^T`` (eq. 37).

Noise is additive here (``Q`` and ``R`` added to the moments), the usual non-augmented form;
the augmented form of eq. 25-27 coincides with it for additive noise. Implemented in covariance
form (Cholesky factors are recomputed each step), so states stay :class:`GaussianState`.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from filters.core.conditioning import condition_moments
from filters.core.linalg import cholesky, gram, symmetrize
from filters.core.models import ObservationModel, TransitionModel, innovation
from filters.core.types import GaussianState, MeasurementMoments, UpdateInfo
from filters.core.validation import batched_matrix, check_gaussian, check_measurement, fading_factor

__all__ = ["predict", "update", "measurement_moments", "divided_differences", "DEFAULT_H"]

DEFAULT_H = float(np.sqrt(3.0))
Order = Literal[1, 2]


def divided_differences(
    g, x: np.ndarray, chol_P: np.ndarray, h: float, order: Order
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Mean and divided-difference matrices of ``g`` around ``x`` (Benzerrouk 2014, eq. 27-30).

    Args:
        g: function broadcasting over ``(B, S, n)``.
        x: centres ``(B, n)``.
        chol_P: lower Cholesky factors ``(B, n, n)``.
        h: interval length.
        order: 1 (DD1) or 2 (DD2).

    Returns:
        ``(mean (B, d), S1 (B, d, n), S2 (B, d, n) or None)``.

    """
    if order not in (1, 2):
        raise ValueError(f"order must be 1 or 2; got {order}")
    if not h > 1.0:
        raise ValueError(f"h must be > 1; got {h}")
    n = x.shape[1]
    steps = h * np.swapaxes(chol_P, -1, -2)  # (B, n, n): row j is h s_j
    X = np.concatenate([x[:, None, :], x[:, None, :] + steps, x[:, None, :] - steps], axis=1)
    G = g(X)
    g0, gp, gm = G[:, 0, :], G[:, 1 : n + 1, :], G[:, n + 1 :, :]
    S1 = np.swapaxes(gp - gm, -1, -2) / (2.0 * h)
    if order == 1:
        return g0, S1, None
    mean = (h * h - n) / (h * h) * g0 + (gp + gm).sum(axis=1) / (2.0 * h * h)
    S2 = np.swapaxes(gp + gm - 2.0 * g0[:, None, :], -1, -2) * (np.sqrt(h * h - 1.0) / (2.0 * h * h))
    return mean, S1, S2


def _spread(S1: np.ndarray, S2: np.ndarray | None) -> np.ndarray:
    C = gram(S1)
    if S2 is not None:
        C = C + gram(S2)
    return C


def predict(
    state: GaussianState,
    model: TransitionModel,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    order: Order = 2,
    h: float = DEFAULT_H,
    fading: np.ndarray | float | None = None,
    Q: np.ndarray | None = None,
) -> GaussianState:
    """DD1/DD2 time update (Benzerrouk 2014, eq. 28-30): ``P- = lambda (S1 S1^T + S2 S2^T) + Q``.

    Args:
        state: filtered beliefs.
        model: transition model with ``f`` and ``Q``.
        u: control input passed to ``f``.
        dt: time step passed to ``f``.
        order: 1 for DD1, 2 for DD2.
        h: interval length (default sqrt(3), eq. 41).
        fading: fading factor ``lambda``, None means 1.
        Q: process noise override.

    """
    B, n = check_gaussian(state)
    Q = batched_matrix(model.Q if Q is None else Q, B, (n, n), "Q")
    lam = fading_factor(fading, B)
    chol_P, _ = cholesky(state.P)
    m_pred, S1, S2 = divided_differences(lambda X: model.f(X, u, dt), state.m, chol_P, h, order)
    C = _spread(S1, S2)
    if lam is not None:
        C = lam[:, None, None] * C
    return GaussianState(m_pred, symmetrize(C + Q))


def measurement_moments(
    state: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    order: Order = 2,
    h: float = DEFAULT_H,
) -> MeasurementMoments:
    """DD1/DD2 measurement prediction of :func:`update` (Benzerrouk 2014, eq. 34-37), R excluded.

    ``z_hat``, ``C = S1 S1^T + S2 S2^T`` and ``P_xz = chol(P) S1^T``; ``S = C + R`` (see
    :func:`filters.sigma_point.measurement_moments` for why they are shared).
    """
    B, _ = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    return _predict_measurement(state, z, model, order, h)


def _predict_measurement(
    state: GaussianState, z: np.ndarray, model: ObservationModel, order: Order, h: float
) -> MeasurementMoments:
    """:func:`measurement_moments` for checked inputs (shared with :func:`update`)."""
    mdim = z.shape[1]
    chol_P, ok = cholesky(state.P)
    z_hat, S1, S2 = divided_differences(model.h, state.m, chol_P, h, order)
    if z_hat.shape != (z.shape[0], mdim):
        raise ValueError(f"model.h returned {z_hat.shape[1:]} per state; expected ({mdim},)")
    P_xz = chol_P @ np.swapaxes(S1, -1, -2)
    return MeasurementMoments(innovation(model, z, z_hat), _spread(S1, S2), P_xz, ok)


def update(
    state: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    order: Order = 2,
    h: float = DEFAULT_H,
    R: np.ndarray | None = None,
) -> tuple[GaussianState, UpdateInfo]:
    """DD1/DD2 measurement update (Benzerrouk 2014, eq. 34-40).

    ``S = S1 S1^T + S2 S2^T + R``, ``P_xz = chol(P) S1^T``, then the Kalman conditioning.
    """
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    R = batched_matrix(model.R if R is None else R, B, (mdim, mdim), "R")
    mom = _predict_measurement(state, z, model, order, h)
    return condition_moments(state.m, state.P, mom, R, mask)
