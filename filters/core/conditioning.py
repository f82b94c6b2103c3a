"""The linear-Gaussian conditioning step every Gaussian filter ends with.

Given a predicted state ``N(m, P)``, an innovation ``v = z - z_hat``, its covariance ``S``
and the state-measurement cross covariance ``P_xz``, the update is (seed 001 eq. 60-62)::

    K = P_xz S^-1,   m+ = m + K v,   P+ = P - K S K^T

and the covariance is updated in the expanded Joseph form
``P+ = P - K P_xz^T - P_xz K^T + K S K^T``, which for ``P_xz = P H^T`` and
``S = H P H^T + R`` is *identically* ``(I - K H) P (I - K H)^T + K R K^T`` for any gain K
(Bucy & Joseph 1968): first-order errors in K cancel, as in the factored form, but every product
is n x m x n instead of n x n x n. KF, EKF, iterated EKF, sigma-point and divided-difference
filters only differ in how they compute ``z_hat``, ``S`` and ``P_xz``.

Masked measurement rows (satellites out of view, outages) contribute exactly nothing: their
innovation, their cross covariance column and their cross terms in ``S`` are zeroed and their
diagonal of ``S`` is set to 1, so ``S^-1`` is block diagonal and ``K`` has zero columns there.
The result equals the update with those rows deleted.
"""

from __future__ import annotations

import numpy as np

from filters.core.linalg import LOG_2PI, spd_inverse, symmetrize
from filters.core.types import GaussianState, UpdateInfo


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
    S = S * (w[:, :, None] * w[:, None, :]) + np.eye(S.shape[-1]) * (1.0 - w)[:, None, :]
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
    S_inv, logdet, ok = spd_inverse(S)
    K = P_xz @ S_inv
    S_inv_v = S_inv @ v[:, :, None]
    m_new = m + (P_xz @ S_inv_v)[:, :, 0]
    # Expanded Joseph form: P - K P_xz^T - P_xz K^T + K S K^T = P - K P_xz^T + (K S - P_xz) K^T.
    KT = np.swapaxes(K, -1, -2)
    P_new = symmetrize(P - K @ np.swapaxes(P_xz, -1, -2) + (K @ S - P_xz) @ KT)
    nis = (v * S_inv_v[:, :, 0]).sum(axis=1)
    n_meas = mask.sum(axis=1)
    log_lik = -0.5 * (nis + logdet + n_meas * LOG_2PI)
    healthy = ok & health(m_new, P_new)
    info = UpdateInfo(v, S, nis, log_lik, healthy, n_meas)
    return GaussianState(m_new, P_new), info


def health(m: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Cheap per-filter health: finite mean and covariance, positive covariance diagonal.

    Full positive definiteness of ``P`` is enforced by construction (Joseph form, symmetrization,
    Cholesky-checked ``S``); :func:`filters.core.linalg.is_positive_definite` checks it exactly.
    """
    # A sum is non-finite iff some term is (or it overflows, which is unhealthy too).
    finite = np.isfinite(P.reshape(P.shape[0], -1).sum(axis=1) + m.sum(axis=1))
    return finite & (np.diagonal(P, axis1=1, axis2=2) > 0).all(axis=1)
