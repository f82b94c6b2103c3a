"""Kalman filter, extended Kalman filter and iterated EKF, batched over a leading axis.

The KF is the EKF on a :class:`~filters.core.models.LinearGaussianModel`: prediction
``m- = f(m)``, ``P- = lambda F P F^T + Q`` (Benzerrouk 2014, eq. 17-18, with the fading factor
``lambda`` of eq. 67-69; ``lambda = 1`` is the plain filter), update eq. 19-21 in whitened
(Cholesky) form, ``P+ = P - W W^T`` (:mod:`filters.core.conditioning`).
"""

from __future__ import annotations

import numpy as np

from filters.core import gaussian_kernels, observed_kernels
from filters.core.compiled import compiled_enabled
from filters.core.conditioning import (
    MAX_OBSERVED_STATES,
    condition,
    condition_bank,
    condition_observed,
    diagonal_noise,
    observed_states,
)
from filters.core.linalg import cross, sandwich
from filters.core.models import LinearizedObservation, LinearizedTransition, innovation
from filters.core.types import GaussianState, MeasurementMoments, UpdateInfo
from filters.core.validation import (
    batched_matrix,
    check_gaussian,
    check_measurement,
    fading_factor,
)

__all__ = [
    "predict",
    "update",
    "update_bank",
    "measurement_moments",
    "iterated_update",
    "kf_predict",
    "kf_update",
]


def predict(
    state: GaussianState,
    model: LinearizedTransition,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    fading: np.ndarray | float | None = None,
    Q: np.ndarray | None = None,
) -> GaussianState:
    """EKF time update (Benzerrouk 2014, eq. 17-18; fading form eq. 67-69).

    ``m- = f(m, u, dt)``, ``P- = lambda F P F^T + Q`` with ``F = df/dx`` at ``m``. ``P`` must be
    symmetric (updates return exactly symmetric covariances); ``P-`` is symmetric up to rounding.

    Args:
        state: filtered beliefs ``m (B, n)``, ``P (B, n, n)``.
        model: transition model with ``f``, Jacobian ``F`` and ``Q``.
        u: control input ``(B, p)`` or None.
        dt: time step in seconds.
        fading: fading factor ``lambda``, scalar or ``(B,)``; None means 1.
        Q: process noise override ``(n, n)`` or ``(B, n, n)`` (e.g. Sage-Husa estimates).

    Returns:
        The predicted state.

    """
    B, n = check_gaussian(state)
    Q = batched_matrix(model.Q if Q is None else Q, B, (n, n), "Q")
    lam = fading_factor(fading, B)
    m, P = state
    F = batched_matrix(model.F(m, u, dt), B, (n, n), "F")
    m_pred = model.f(m, u, dt)
    if m_pred.shape != (B, n):
        raise ValueError(f"model.f returned shape {m_pred.shape}; expected {(B, n)}")
    if _compiled(P, n):
        out = np.empty((B, n, n))
        ones = np.ones(B) if lam is None else np.ascontiguousarray(lam, dtype=np.float64)
        gaussian_kernels.sandwich_pass(_stacked(F), np.ascontiguousarray(P), ones, _stacked(Q), out)
        return GaussianState(m_pred, out)
    FPFt = sandwich(F, P)
    if lam is not None:
        FPFt = lam[:, None, None] * FPFt
    return GaussianState(m_pred, FPFt + Q)


def update(
    state: GaussianState,
    z: np.ndarray,
    model: LinearizedObservation,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
    H: np.ndarray | None = None,
) -> tuple[GaussianState, UpdateInfo]:
    """EKF measurement update (Benzerrouk 2014, eq. 19-21).

    ``v = z - h(m)``, ``S = H P H^T + R``, ``K = P H^T S^-1``, ``m+ = m + K v``,
    ``P+ = P - K S K^T`` (for this optimal gain, algebraically the Joseph form
    ``(I - K H) P (I - K H)^T + K R K^T``; see :mod:`filters.core.conditioning` for its numerics).

    Measurements with diagonal noise that depend on at most three states (the other columns of
    ``H`` zero, e.g. pseudo-ranges of an error-state INS) take the same posterior from 3 x 3
    algebra (:func:`~filters.core.conditioning.condition_observed`, or its compiled twin
    :func:`~filters.core.observed_kernels.observed_update`); otherwise it is computed in
    whitened form (:func:`~filters.core.conditioning.condition`).

    Args:
        state: predicted beliefs ``(B, n)``, ``(B, n, n)``.
        z: measurements ``(B, m)``; masked rows may hold NaN.
        model: observation model with ``h``, Jacobian ``H`` and ``R``.
        mask: ``(B, m)`` booleans, False rows are ignored exactly; None uses every row.
        R: measurement noise override ``(m, m)`` or ``(B, m, m)``.
        H: the Jacobian ``model.H(m)`` at the predicted mean when the caller has it already,
            ``(m, n)`` or ``(B, m, n)`` (None: evaluated here).

    Returns:
        ``(filtered state, UpdateInfo)``.

    """
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    R = batched_matrix(model.R if R is None else R, B, (mdim, mdim), "R")
    m, P = state
    H = batched_matrix(model.H(m) if H is None else H, B, (mdim, n), "H")
    v = innovation(model, z, model.h(m))
    if _compiled(P, n) and mdim <= min(n, gaussian_kernels.MAX_MEASUREMENTS):
        out = _compiled_update(m, P, v, H, R, mask)
        if out is not None:
            return out
    r = diagonal_noise(R)
    observed = _subspace(H, r)
    if observed is not None:
        out = None
        if _compiled(P, n):
            out = observed_kernels.observed_update(m, P, v, H, r, mask, observed)
        if out is None:
            out = condition_observed(m, P, v, np.broadcast_to(H, (B, mdim, n)), r, mask, observed)
        if out is not None:
            return out
    PHt = cross(P, H)
    S = H @ PHt + R
    return condition(m, P, v, S, PHt, mask)


def _compiled(P: np.ndarray, n: int) -> bool:
    """Whether the compiled kernels of :mod:`filters.core.gaussian_kernels` take the step."""
    return compiled_enabled() and P.dtype == np.float64 and 0 < n <= gaussian_kernels.MAX_STATES


def _stacked(A: np.ndarray) -> np.ndarray:
    """A shared ``(r, c)`` matrix as ``(1, r, c)``, a batch ``(B, r, c)`` as it is; C-contiguous float64."""
    return np.ascontiguousarray(A[None] if A.ndim == 2 else A, dtype=np.float64)


def _compiled_update(
    m: np.ndarray, P: np.ndarray, v: np.ndarray, H: np.ndarray, R: np.ndarray, mask: np.ndarray
) -> tuple[GaussianState, UpdateInfo] | None:
    """:func:`update` by :func:`filters.core.gaussian_kernels.update_pass`, or None.

    None (the NumPy path runs) when some filter's ``S`` is not positive definite or not
    finite: the NumPy path's jitter fallback handles it. The results equal the NumPy path's
    to rounding.
    """
    B, n = m.shape
    k = v.shape[1]
    m_new, P_new = np.empty((B, n)), np.empty((B, n, n))
    v_out, S = np.empty((B, k)), np.empty((B, k, k))
    nis, log_lik = np.empty(B), np.empty(B)
    ok_S, healthy = np.empty(B, dtype=bool), np.empty(B, dtype=bool)
    gaussian_kernels.update_pass(
        np.ascontiguousarray(m, dtype=np.float64), np.ascontiguousarray(P),
        np.ascontiguousarray(v, dtype=np.float64), _stacked(H), _stacked(R), mask.astype(np.float64),
        m_new, P_new, v_out, S, nis, log_lik, ok_S, healthy,
    )  # fmt: skip
    if not ok_S.all():
        return None
    info = UpdateInfo(v_out, S, nis, log_lik, healthy, mask.sum(axis=1))
    return GaussianState(m_new, P_new), info


def update_bank(
    state: GaussianState,
    z: np.ndarray,
    model: LinearizedObservation,
    mask: np.ndarray | None,
    R_components: np.ndarray,
) -> tuple[GaussianState, UpdateInfo]:
    """The K EKF updates of each prior, one per noise covariance ``R_j`` (Benzerrouk 2014, eq. 72).

    The bank of a Gaussian-sum EKF: ``h``, ``H`` and the innovation are evaluated once per
    filter (``S_j = H P H^T + R_j``, ``P_xz = P H^T`` shared) and only the K conditionings
    differ; with diagonal components and measurements on at most three states,
    :func:`~filters.core.conditioning.condition_observed` also shares the prior's
    factorization. Each component's numbers are those of :func:`update` with ``R = R_j``.

    Args:
        state: predicted beliefs ``(B, n)``, ``(B, n, n)``.
        z: measurements ``(B, m)``; masked rows may hold NaN.
        model: observation model with ``h`` and Jacobian ``H``.
        mask: ``(B, m)`` booleans or None.
        R_components: noise covariances ``(B, K, m, m)``.

    Returns:
        ``(filtered states, UpdateInfo)`` of the ``(B*K)`` batch, filter-major (component j of
        filter b at ``b*K + j``).
    """
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    K = R_components.shape[1]
    if R_components.shape != (B, K, mdim, mdim):
        raise ValueError(f"R_components must have shape ({B}, K, {mdim}, {mdim}); got {R_components.shape}")
    m, P = state
    H, v = _linearization(m, z, model)
    if _compiled(P, n) and mdim <= min(n, gaussian_kernels.MAX_MEASUREMENTS):
        # the compiled update of each (prior, R_j) pair: the numbers of update() with R = R_j
        def rep(a: np.ndarray) -> np.ndarray:
            return np.repeat(a, K, axis=0)

        out = _compiled_update(
            rep(m), rep(P), rep(v), rep(H), R_components.reshape(B * K, mdim, mdim), rep(mask)
        )
        if out is not None:
            return out
    r = diagonal_noise(R_components)
    observed = _subspace(H, r)
    if observed is not None:
        out = condition_observed(m, P, v, H, r, mask, observed)
        if out is not None:
            return out
    # the EKF's measurement prediction, S_j = H P H^T + R_j
    return condition_bank(m, P, _linearized_moments(P, H, v), R_components, mask)


def measurement_moments(
    state: GaussianState, z: np.ndarray, model: LinearizedObservation, mask: np.ndarray | None = None
) -> MeasurementMoments:
    """The EKF's measurement prediction at the mean, R excluded (Benzerrouk 2014, eq. 19-20).

    ``v = z - h(m)`` (the model's ``residual``), ``C = H P H^T``, ``P_xz = P H^T`` with
    ``H = model.H(m)``: the moments every update of the prior under some ``R`` shares
    (``S = C + R``), as :func:`update_bank` forms them.
    """
    B, _ = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    H, v = _linearization(state.m, z, model)
    return _linearized_moments(state.P, H, v)


def _linearization(
    m: np.ndarray, z: np.ndarray, model: LinearizedObservation
) -> tuple[np.ndarray, np.ndarray]:
    """The Jacobian ``H (B, m, n)`` and the innovation ``v = z - h(m)`` at the means ``m (B, n)``."""
    B, n = m.shape
    mdim = z.shape[1]
    H = np.broadcast_to(batched_matrix(model.H(m), B, (mdim, n), "H"), (B, mdim, n))
    return H, innovation(model, z, model.h(m))


def _linearized_moments(P: np.ndarray, H: np.ndarray, v: np.ndarray) -> MeasurementMoments:
    """``MeasurementMoments(v, H P H^T, P H^T, ok)`` of Jacobians ``H (B, m, n)`` and innovations ``v``."""
    PHt = cross(P, H)
    return MeasurementMoments(v, H @ PHt, PHt, np.ones(P.shape[0], dtype=bool))


def _subspace(H: np.ndarray, r: np.ndarray | None) -> np.ndarray | None:
    """The states :func:`~filters.core.conditioning.condition_observed` conditions, or None.

    It applies to diagonal noise (``r`` not None) and measurements on at most
    ``MAX_OBSERVED_STATES`` states, fewer than both the rows and the states.
    """
    if r is None:
        return None
    observed = observed_states(H)
    mdim, n = H.shape[-2:]
    return observed if 0 < observed.size <= MAX_OBSERVED_STATES and observed.size < min(mdim, n) else None


def iterated_update(
    state: GaussianState,
    z: np.ndarray,
    model: LinearizedObservation,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
    max_iter: int = 10,
    tol: float = 1e-8,
) -> tuple[GaussianState, UpdateInfo]:
    """Iterated EKF update in Gauss-Newton form (Belles et al. 2022, eq. 14-15; Bell & Cathey 1993).

    ``x(i+1) = m + K(i) (z - h(x(i)) + H(i) (x(i) - m))`` with
    ``K(i) = P H(i)^T (H(i) P H(i)^T + R)^-1`` and ``H(i) = dh/dx`` at ``x(i)``, starting at
    ``x(0) = m``; iterations stop when every filter moved less than ``tol`` (relative) or after
    ``max_iter``. The covariance uses the last linearization. ``max_iter = 1`` is
    the EKF update. The reported innovation is the linearized one, ``z - h(x) + H (x - m)``.

    Args:
        state: predicted beliefs ``(B, n)``, ``(B, n, n)``.
        z: measurements ``(B, m)``; masked rows may hold NaN.
        model: observation model with ``h``, Jacobian ``H`` and ``R``.
        mask: ``(B, m)`` booleans, False rows are ignored exactly.
        R: measurement noise override.
        max_iter: maximum number of Gauss-Newton iterations (>= 1).
        tol: convergence tolerance on ``|dx| / (1 + |x|)``.

    """
    if max_iter < 1:
        raise ValueError(f"max_iter must be >= 1; got {max_iter}")
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    R = batched_matrix(model.R if R is None else R, B, (mdim, mdim), "R")
    m, P = state
    x = m
    active = np.ones(B, dtype=bool)
    result: tuple[GaussianState, UpdateInfo] | None = None
    for _ in range(max_iter):
        H = np.broadcast_to(batched_matrix(model.H(x), B, (mdim, n), "H"), (B, mdim, n))
        v = innovation(model, z, model.h(x)) + (H @ (x - m)[:, :, None])[:, :, 0]
        PHt = P @ np.swapaxes(H, -1, -2)
        post, info = condition(m, P, v, H @ PHt + R, PHt, mask)
        # Filters that converged earlier keep the result of their last active iteration, so a
        # batch equals separate runs.
        result = (post, info) if result is None else _select(active, (post, info), result)
        step = np.linalg.norm(post.m - x, axis=1) / (1.0 + np.linalg.norm(x, axis=1))
        x = np.where(active[:, None], post.m, x)
        active = active & (step > tol)
        if not active.any():
            break
    return result


def _select(active: np.ndarray, new: tuple, old: tuple) -> tuple:
    """Per-filter choice between two (state, info) pairs of NamedTuples."""

    def pick(a, b):
        if a is None:
            return None
        return np.where(active.reshape(-1, *([1] * (a.ndim - 1))), a, b)

    return tuple(
        type(n)(*(pick(a, b) for a, b in zip(n, o, strict=True))) for n, o in zip(new, old, strict=True)
    )


kf_predict = predict
kf_update = update
