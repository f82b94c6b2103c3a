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

:func:`predict` and :func:`predict_measurement` (so :func:`update` and every update built on
its moments) run the parts around the model calls as compiled kernels
(:mod:`filters.core.sigma_point_kernels`: the points, then their moments, one pass each) for
float64 beliefs of up to 24 states and 128 points, the model's ``f``/``h`` seeing the points
as the NumPy path does (a C-contiguous batch-first ``(B, S, n)`` array: a model's reductions,
e.g. a range's sum of squares, round differently on other memory layouts), or, for a model that
declares itself element-wise (:class:`~filters.core.models.ElementwiseModel`), as a ``(B, S, n)``
view of the kernels' state-major points (the same numbers without the copy); a filter whose ``P``
is not numerically positive definite gets the NumPy path's jittered points (and is flagged),
the others keep the kernel's numbers; otherwise, or under
:func:`filters.core.compiled.numpy_only`, the NumPy code below, which stays the reference.
:func:`sigma_points` and :func:`moments` are always NumPy.
"""

from __future__ import annotations

import numpy as np

from filters.core import gaussian_kernels, sigma_point_kernels
from filters.core.compiled import compiled_enabled
from filters.core.conditioning import condition_moments
from filters.core.linalg import cholesky, symmetrize
from filters.core.models import ElementwiseModel, ObservationModel, TransitionModel, innovation
from filters.core.quadrature import Cubature, GaussHermite, Quadrature, SigmaPoints
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
    if _compiled(state.P, n, rule):
        return _compiled_predict(state, model, u, dt, rule, rule.sigma_points(n), lam, Q)
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
    n = state.m.shape[1]
    if _compiled(state.P, n, rule):
        return _compiled_moments(state, z, model, rule, rule.sigma_points(n))
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


def _compiled(P: np.ndarray, n: int, rule: Quadrature) -> bool:
    """Whether the kernels of :mod:`filters.core.sigma_point_kernels` take the step."""
    if not (compiled_enabled() and P.dtype == np.float64 and 0 < n <= gaussian_kernels.MAX_STATES):
        return False
    if isinstance(rule, GaussHermite) and rule.p**n > sigma_point_kernels.MAX_POINTS:
        return False  # before building a huge rule
    return rule.sigma_points(n).xi.shape[0] <= sigma_point_kernels.MAX_POINTS


def _stacked(A: np.ndarray) -> np.ndarray:
    """A shared ``(r, c)`` matrix as ``(1, r, c)``, a batch ``(B, r, c)`` as it is; C-contiguous float64."""
    return np.ascontiguousarray(A[None] if A.ndim == 2 else A, dtype=np.float64)


def _points(state: GaussianState, pts: SigmaPoints, rule: Quadrature) -> tuple[np.ndarray, np.ndarray]:
    """State-major points ``Xt (n, B, S)`` of ``N(m, P)`` and ``ok (B,)`` (kernel ``points_pass``).

    A filter whose ``P`` is not numerically positive definite gets the points of
    :func:`sigma_points` (the NumPy path's jitter fallback) and its ``ok`` flag; the other
    filters keep the kernel's points, so their numbers do not depend on a neighbour's failure.
    """
    m, P = state
    B, n = m.shape
    Xt = np.empty((n, B, pts.xi.shape[0]))
    ok = np.empty(B, dtype=bool)
    sigma_point_kernels.points_pass(
        np.ascontiguousarray(m, dtype=np.float64), np.ascontiguousarray(P), _unit(pts.xi), Xt, ok
    )
    if not ok.all():
        bad = ~ok
        X_np, _, ok_np = sigma_points(GaussianState(m[bad], P[bad]), rule)
        Xt[:, bad] = X_np.transpose(2, 0, 1)
        ok[bad] = ok_np
    return Xt, ok


def _batch_first(Xt: np.ndarray) -> np.ndarray:
    """State-major points as the C-contiguous ``(B, S, n)`` array the NumPy path gives a model."""
    return np.ascontiguousarray(Xt.transpose(1, 2, 0))


def _model_points(Xt: np.ndarray, model: object) -> np.ndarray:
    """The points ``(B, S, n)`` a model's ``f``/``h`` gets from the state-major ``Xt (n, B, S)``.

    An :class:`~filters.core.models.ElementwiseModel` gets the view ``Xt.transpose(1, 2, 0)``
    (its numbers do not depend on the layout, and each state component is one contiguous block),
    any other model the batch-first copy of :func:`_batch_first` (its reductions would round
    differently on the view).
    """
    return Xt.transpose(1, 2, 0) if isinstance(model, ElementwiseModel) else _batch_first(Xt)


def _unit(a: np.ndarray) -> np.ndarray:
    """A rule's array as the kernels take it: C-contiguous float64 (the rules' own are, read-only)."""
    return np.ascontiguousarray(a, dtype=np.float64)


def _compiled_predict(
    state: GaussianState,
    model: TransitionModel,
    u,
    dt: float,
    rule: Quadrature,
    pts: SigmaPoints,
    lam,
    Q: np.ndarray,
) -> GaussianState:
    """:func:`predict` by the compiled kernels."""
    Xt, _ = _points(state, pts, rule)
    X = _model_points(Xt, model)
    Xf = model.f(X, u, dt)
    if Xf.shape != X.shape:
        raise ValueError(f"model.f returned shape {Xf.shape} for sigma points {X.shape}")
    B, n = state.m.shape
    m_pred, P_pred = np.empty((B, n)), np.empty((B, n, n))
    lam = np.ones(B) if lam is None else np.ascontiguousarray(lam, dtype=np.float64)
    sigma_point_kernels.predict_pass(
        sigma_point_kernels.state_major(Xf), _unit(pts.wm), _unit(pts.wc), lam, _stacked(Q), m_pred, P_pred
    )
    return GaussianState(m_pred, P_pred)


def _compiled_moments(
    state: GaussianState, z: np.ndarray, model: ObservationModel, rule: Quadrature, pts: SigmaPoints
) -> MeasurementMoments:
    """:func:`predict_measurement` by the compiled kernels.

    A filter whose ``P`` is not numerically positive definite takes the NumPy path's jittered
    points and is flagged (``ok`` False), as on the NumPy path.
    """
    Xt, ok = _points(state, pts, rule)
    B, n = state.m.shape
    S, k = pts.xi.shape[0], z.shape[1]
    Z = model.h(_model_points(Xt, model))
    if Z.shape != (B, S, k):
        raise ValueError(f"model.h returned shape {Z.shape}; expected {(B, S, k)}")
    # z_hat = sum wm Z by the NumPy path's own product, on the same batch-first layout: the same
    # bits. Its summation order shows: pseudo-ranges of 2e7 m round at 4e-9 m, and z_hat is
    # subtracted from z (GpsInsMixture's CKF traces moved by 5e-9 m with a kernel's order).
    z_hat = pts.wm @ np.ascontiguousarray(Z, dtype=np.float64)
    Zt = sigma_point_kernels.state_major(Z)
    zt = np.ascontiguousarray(z_hat.T)
    C, P_xz = np.empty((B, k, k)), np.empty((B, n, k))
    sigma_point_kernels.moments_pass(
        np.ascontiguousarray(state.m, dtype=np.float64), Xt, Zt, zt, _unit(pts.wc), C, P_xz
    )
    return MeasurementMoments(innovation(model, z, z_hat), C, P_xz, ok)
