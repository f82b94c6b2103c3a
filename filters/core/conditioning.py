"""The linear-Gaussian conditioning step every Gaussian filter ends with.

Given a predicted state ``N(m, P)``, an innovation ``v = z - z_hat``, its covariance ``S``
and the state-measurement cross covariance ``P_xz``, the update is (seed 001 eq. 60-62)::

    K = P_xz S^-1,   m+ = m + K v,   P+ = P - K S K^T

computed in whitened (Cholesky) form: with ``S = L L^T``, ``W = P_xz L^-T`` and ``e = L^-1 v``
(one batched forward substitution), ``m+ = m + W e``, ``P+ = P - W W^T``, ``NIS = |e|^2`` and
``log det S = 2 sum log diag L``. ``S^-1`` is never formed. For the optimal gain ``K = W L^-1``
every term of the Joseph form ``P - K P_xz^T - P_xz K^T + K S K^T`` equals ``W W^T``, so this is
the Joseph form evaluated without forming K (the form is exactly symmetric after
:func:`~filters.core.linalg.symmetrize`; a lost positive diagonal is caught by the health flag).
KF, EKF, iterated EKF, sigma-point and divided-difference filters only differ in how they compute
``z_hat``, ``S`` and ``P_xz``.

Masked measurement rows (satellites out of view, outages) contribute exactly nothing: their
innovation, their cross covariance column and their cross terms in ``S`` are zeroed and their
diagonal of ``S`` is set to 1, so ``S^-1`` is block diagonal and ``K`` has zero columns there.
The result equals the update with those rows deleted.
"""

from __future__ import annotations

import numpy as np

from filters.core.linalg import LOG_2PI, chol_logdet, cholesky, solve_lower, symmetrize
from filters.core.types import GaussianState, UpdateInfo


def masked_covariance(C: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``C_ij w_i w_j + delta_ij (1 - w_i)``: masked rows and columns neutralized.

    With ``w`` the 0/1 row weights of a mask, the used block of ``C`` is kept, a masked row gets
    unit variance and no cross terms, so ``C^-1`` and its Cholesky factor are block diagonal and
    a zeroed residual on that row contributes exactly nothing (module docstring).

    Args:
        C: covariances ``(..., m, m)`` (e.g. ``(m, m)`` shared or ``(B, m, m)``).
        w: 0/1 weights ``(..., m)`` broadcastable against ``C``'s leading axes.

    Returns:
        A new array of the broadcast shape (the diagonal is set in place on it).
    """
    out = C * (w[..., :, None] * w[..., None, :])
    np.einsum("...ii->...i", out)[...] += 1.0 - w
    return out


def mask_moments(
    v: np.ndarray, S: np.ndarray, P_xz: np.ndarray, mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Neutralize masked rows: ``v_i = 0``, ``S_ij = delta_ij`` and ``P_xz[:, i] = 0`` for masked i.

    Args:
        v: innovations ``(B, m)``.
        S: innovation covariances ``(B, m, m)``.
        P_xz: cross covariances ``(B, n, m)``.
        mask: ``(B, m)`` booleans, True where the row is used.

    """
    if mask.all():
        return v, S, P_xz
    w = mask.astype(np.float64)
    v = v * w
    S = masked_covariance(S, w)
    P_xz = P_xz * w[:, None, :]
    return v, S, P_xz


def condition(
    m: np.ndarray,
    P: np.ndarray,
    v: np.ndarray,
    S: np.ndarray,
    P_xz: np.ndarray,
    mask: np.ndarray,
) -> tuple[GaussianState, UpdateInfo]:
    """Kalman update from first and second moments (seed 001 eq. 19-21, 60-62).

    Args:
        m: predicted means ``(B, n)``.
        P: predicted covariances ``(B, n, n)``.
        v: innovations ``(B, m)``.
        S: innovation covariances, measurement noise included, ``(B, m, m)``.
        P_xz: cross covariances ``(B, n, m)``.
        mask: ``(B, m)`` booleans; False rows are ignored exactly.

    Returns:
        The filtered state and the :class:`UpdateInfo` (innovation, S, NIS, log-likelihood,
        health flag).

    """
    v, S, P_xz = mask_moments(v, S, P_xz, mask)
    chol_S, ok = cholesky(S)  # jitter fallback; ok = False marks a non-positive-definite S
    n = m.shape[1]
    # Whitening by the Cholesky factor L of S: L [W^T | e] = [P_xz^T | v].
    X = solve_lower(chol_S, np.concatenate([np.swapaxes(P_xz, -1, -2), v[:, :, None]], axis=2))
    Wt, e = X[:, :, :n], X[:, :, n]
    m_new = m + (e[:, None, :] @ Wt)[:, 0, :]
    P_new = symmetrize(P - np.swapaxes(Wt, -1, -2) @ Wt)
    nis = (e * e).sum(axis=1)
    logdet = chol_logdet(chol_S)
    n_meas = mask.sum(axis=1)
    log_lik = -0.5 * (nis + logdet + n_meas * LOG_2PI)
    healthy = ok & health(m_new, P_new)
    info = UpdateInfo(v, S, nis, log_lik, healthy, n_meas)
    return GaussianState(m_new, P_new), info


def health(m: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Cheap per-filter health: finite mean and covariance, positive covariance diagonal.

    Symmetry is exact (:func:`~filters.core.linalg.symmetrize`) and ``S`` is Cholesky-checked;
    full positive definiteness of ``P`` is checked exactly by
    :func:`filters.core.linalg.is_positive_definite` (an O(n^3) factorization, not done per step).
    """
    # A sum is non-finite iff some term is (or it overflows, which is unhealthy too).
    finite = np.isfinite(P.reshape(P.shape[0], -1).sum(axis=1) + m.sum(axis=1))
    return finite & (np.diagonal(P, axis1=1, axis2=2) > 0).all(axis=1)
