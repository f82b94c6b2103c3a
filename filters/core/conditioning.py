"""The linear-Gaussian conditioning step every Gaussian filter ends with.

Given a predicted state ``N(m, P)``, an innovation ``v = z - z_hat``, its covariance ``S``
and the state-measurement cross covariance ``P_xz``, the update is (Benzerrouk 2014, eq. 60-62)::

    K = P_xz S^-1,   m+ = m + K v,   P+ = P - K S K^T

computed in whitened (Cholesky) form: with ``S = L L^T``, ``W = P_xz L^-T`` and ``e = L^-1 v``
(one batched forward substitution), ``m+ = m + W e``, ``P+ = P - W W^T``, ``NIS = |e|^2`` and
``log det S = 2 sum log diag L``. ``S^-1`` is never formed. For the optimal gain ``K = W L^-1``
every term of the expanded Joseph form ``P - K P_xz^T - P_xz K^T + K S K^T`` equals ``W W^T``, so
the two agree in exact arithmetic; numerically ``P - W W^T`` is the standard form, exactly
symmetric after :func:`~filters.core.linalg.symmetrize` but, unlike the Joseph form
``(I - K H) P (I - K H)^T + K R K^T`` (:func:`~filters.core.linalg.joseph_update`, which needs
``H`` and ``R`` apart), not positive semi-definite by construction: with a dynamic range of
about 1e12 between ``P`` and ``R`` (a 1e10 prior variance against 1e-6 noise) rounding can leave
it indefinite, which the health flag reports (:func:`health`).
KF, EKF, iterated EKF, sigma-point and divided-difference filters only differ in how they compute
``z_hat``, ``S`` and ``P_xz``.

Masked measurement rows (satellites out of view, outages) contribute exactly nothing: their
innovation, their cross covariance column and their cross terms in ``S`` are zeroed and their
diagonal of ``S`` is set to 1, so ``S^-1`` is block diagonal and ``K`` has zero columns there.
The result equals the update with those rows deleted.

:func:`condition_observed` is the same update for measurements with diagonal noise that depend
on at most three states (:func:`observed_states`), computed with 3 x 3 algebra; the EKF update
chooses it where it applies.
"""

from __future__ import annotations

import numpy as np

from filters.core import gaussian_kernels
from filters.core.compiled import compiled_enabled
from filters.core.linalg import (
    LOG_2PI,
    chol_logdet,
    cholesky,
    cholesky_unrolled,
    gram,
    is_positive_definite,
    solve_lower,
    solve_lower_rows,
    symmetrize,
)
from filters.core.types import GaussianState, MeasurementMoments, UpdateInfo


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
    """Kalman update from first and second moments (Benzerrouk 2014, eq. 19-21, 60-62).

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

    The compiled twin :func:`filters.core.gaussian_kernels.condition` runs where it applies
    (float64, sizes in its range, a positive-definite ``S``); this NumPy body otherwise and under
    :func:`filters.core.compiled.numpy_only` (tests hold the two equal).
    """
    if compiled_enabled():
        out = gaussian_kernels.condition(m, P, v, S, P_xz, mask)
        if out is not None:
            return out
    v, S, P_xz = mask_moments(v, S, P_xz, mask)
    chol_S, ok = cholesky(S)  # jitter fallback; ok = False marks a non-positive-definite S
    n = m.shape[1]
    # Whitening by the Cholesky factor L of S: L [W^T | e] = [P_xz^T | v].
    X = solve_lower(chol_S, np.concatenate([np.swapaxes(P_xz, -1, -2), v[:, :, None]], axis=2))
    Wt, e = X[:, :, :n], X[:, :, n]
    m_new = m + (e[:, None, :] @ Wt)[:, 0, :]
    P_new = symmetrize(P - gram(np.swapaxes(Wt, -1, -2)))  # P - W W^T
    nis = (e * e).sum(axis=1)
    logdet = chol_logdet(chol_S)
    n_meas = mask.sum(axis=1)
    log_lik = -0.5 * (nis + logdet + n_meas * LOG_2PI)
    healthy = ok & health(m_new, P_new)
    info = UpdateInfo(v, S, nis, log_lik, healthy, n_meas)
    return GaussianState(m_new, P_new), info


def condition_moments(
    m: np.ndarray, P: np.ndarray, mom: MeasurementMoments, R: np.ndarray, mask: np.ndarray
) -> tuple[GaussianState, UpdateInfo]:
    """:func:`condition` on a filter's measurement prediction: ``S = C + R`` (Benzerrouk 2014, eq. 58, 60-62).

    The update of every moment-based filter (sigma-point, divided-difference, their fading and
    Gaussian-sum forms); the health flag also carries ``mom.ok`` (the prior's factorization).
    """
    post, info = condition(m, P, mom.v, mom.C + R, mom.P_xz, mask)
    return post, info._replace(healthy=info.healthy & mom.ok)


def condition_bank(
    m: np.ndarray, P: np.ndarray, mom: MeasurementMoments, R_components: np.ndarray, mask: np.ndarray
) -> tuple[GaussianState, UpdateInfo]:
    """:func:`condition_moments` of each prior under K noise covariances (Benzerrouk 2014, eq. 72).

    ``S_j = C + R_j`` for ``R_components (B, K, m, m)``: the measurement prediction ``mom`` of
    the ``B`` priors is formed once, and only the K conditionings are stacked, as a ``(B*K)``
    batch ordered filter-major (component j of filter b at ``b*K + j``); each component's
    numbers are those of :func:`condition_moments` with ``R = R_j``.
    """
    B, K, mdim = R_components.shape[:3]

    def rep(a: np.ndarray) -> np.ndarray:
        return np.repeat(a, K, axis=0)

    return condition_moments(
        rep(m),
        rep(P),
        MeasurementMoments(*(rep(a) for a in mom)),
        R_components.reshape(B * K, mdim, mdim),
        rep(mask),
    )


def health(m: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Per-filter health: "finite and positive definite" (``docs/architecture.md``, "filters").

    Finite mean and covariance, and a covariance that is positive definite (its Cholesky
    factorization succeeds, :func:`~filters.core.linalg.is_positive_definite`; one batched
    LAPACK call on the common path).
    """
    # is_positive_definite flags non-finite covariances; a sum is non-finite iff some term is
    return np.isfinite(m.sum(axis=1)) & is_positive_definite(P)


#: Most observed states for :func:`condition_observed` (its k x k algebra is unrolled).
MAX_OBSERVED_STATES = 3


def diagonal_noise(R: np.ndarray) -> np.ndarray | None:
    """The diagonal of ``R (m, m)`` or ``(B, m, m)`` when ``R`` is diagonal, else None.

    ``R`` has as many non-zero entries as its diagonal plus its off-diagonal part, so it is
    diagonal exactly when the two counts agree (zero variances included). Used for measurement
    noise (:func:`filters.kalman.update`) and process noise (particle filters).
    """
    r = np.diagonal(R, axis1=-2, axis2=-1)
    return r if np.count_nonzero(R) == np.count_nonzero(r) else None


def observed_states(H: np.ndarray) -> np.ndarray:
    """Indices of the states the measurements depend on (non-zero columns of ``H``).

    The columns of ``H (..., m, n)`` that are non-zero for some row of some filter, found
    from the column sums of ``H_ij^2`` (one pass; NaN and inf count as non-zero). An
    entry below ~1e-162 in magnitude squares to 0: a column of only such entries is treated as
    unobserved, dropping a term of relative size 1e-324 from ``S``.
    """
    flat = H.reshape(-1, H.shape[-1])
    return np.flatnonzero(np.einsum("ij,ij->j", flat, flat) != 0.0)


def condition_observed(
    m: np.ndarray,
    P: np.ndarray,
    v: np.ndarray,
    H: np.ndarray,
    r: np.ndarray,
    mask: np.ndarray,
    observed: np.ndarray,
) -> tuple[GaussianState, UpdateInfo] | None:
    """Kalman update when the measurements depend on k <= 3 states and their noise is diagonal.

    The posterior of :func:`condition` with ``S = H P H^T + R``, ``P_xz = P H^T``, from k x k
    instead of m x m algebra (pseudo-ranges of an error-state INS depend on the two horizontal
    position errors and the clock bias only: k = 3 for m = 12 rows). With ``o`` the observed
    states, ``H = H_o E_o^T``, ``R = diag(r)``, ``W = diag(mask / r)``, the prior block
    ``P_oo = L L^T``, ``G_x = P_xo L^-T`` and ``H_s = H_o L`` (information form, Simon,
    *Optimal State Estimation*, 2006, §6.2, with the matrix inversion and determinant lemmas)::

        M = I + H_s^T W H_s = G G^T,   V = G_x G^-T,   y = G^-1 H_s^T W v
        m+ = m + V y,   P+ = (P - G_x G_x^T) + V V^T
        NIS = v^T W v - |y|^2,   log det S = sum log r_i + 2 sum log diag G   (used rows i)

    ``P - G_x G_x^T`` is the prior conditioned on the observed states (a Schur complement) and
    ``V V^T`` what the measurements leave of their uncertainty, so ``P+`` is a difference of
    the same kind as the whitened form of :func:`condition` (and agrees with it to
    rounding, also from a prior of 3e5 m clock uncertainty). ``M >= I`` is always factorizable.
    Masked rows have weight 0 and contribute exactly nothing; ``S`` is masked as in
    :func:`mask_moments`.

    A bank of K noise diagonals ``r (B, K, m)`` gives the K updates of each prior, one per
    noise component, as a ``(B*K)`` batch ordered filter-major (the Gaussian-sum EKF, Benzerrouk
    2014, eq. 72): ``L``, ``G_x``, ``H_s`` and ``H_s H_s^T`` depend on the prior only and are
    formed once per filter; each component's numbers are those of the update with ``r = r[:, j]``.

    Args:
        m: predicted means ``(B, n)``.
        P: predicted covariances ``(B, n, n)``.
        v: innovations ``(B, m)``.
        H: observation Jacobians ``(B, m, n)``, zero outside the columns ``observed``.
        r: the diagonal of R, ``(m,)`` or ``(B, m)``; or a bank ``(B, K, m)``.
        mask: ``(B, m)`` booleans; False rows are ignored exactly.
        observed: the k state indices (:func:`observed_states`).

    Returns:
        The filtered state and the :class:`UpdateInfo` (``(B*K)`` batches for a bank), or None
        when some ``P_oo`` is not numerically positive definite or some used row has zero
        noise variance (``W = diag(mask / r)`` needs ``r > 0``): the caller then uses
        :func:`condition`, whose health flag judges ``S`` as before.
    """
    bank = r.ndim == 3
    if not (np.where(mask[:, None, :] if bank else mask, r, 1.0) > 0).all():
        return None
    L, ok = cholesky_unrolled(P[:, observed[:, None], observed])
    if not ok.all():
        return None
    k = observed.size
    w = mask.astype(np.float64)
    v = v * w
    Ho = H[:, :, observed] * w[:, :, None]  # masked rows zero (exactly: weights are 0 or 1)
    # H_o L (L lower triangular), in C order whatever the strides the fancy index gave H_o:
    # matmul's rounding depends on the operands' layout, and a bank must multiply the same
    # layouts as its stacked updates to give their numbers bit for bit
    Hs = np.zeros(Ho.shape)
    for j in range(k):
        for i in range(j, k):
            Hs[:, :, j] += Ho[:, :, i] * L[:, i, j, None]
    Gx = solve_lower_rows(L, P[:, :, observed])
    HsHs = gram(Hs)
    if bank:  # the prior's terms, once per filter, repeated for its K components
        K = r.shape[1]
        m, P, v, w, mask, Hs, Gx, HsHs = (np.repeat(a, K, axis=0) for a in (m, P, v, w, mask, Hs, Gx, HsHs))
        r = r.reshape(-1, r.shape[-1])
    wr = w / r
    WHs = Hs * wr[:, :, None]
    M = np.swapaxes(Hs, -1, -2) @ WHs
    np.einsum("...ii->...i", M)[...] += 1.0
    G, ok_M = cholesky_unrolled(M)  # M >= I: only a non-finite M fails, flagged unhealthy below
    n = m.shape[1]
    # V = G_x G^-T and y = G^-1 H_s^T W v in one solve: rows [G_x ; (H_s^T W v)^T]
    Vy = solve_lower_rows(G, np.concatenate([Gx, v[:, None, :] @ WHs], axis=1))
    V, y = Vy[:, :n], Vy[:, n]
    U = np.concatenate([Gx, V], axis=2)  # [G_x | V]
    m_new = m + (V @ y[:, :, None])[:, :, 0]
    signs = np.repeat([1.0, -1.0], k)  # G_x G_x^T - V V^T as one product
    P_new = symmetrize(P - (U * signs) @ np.swapaxes(U, -1, -2))
    S = HsHs
    np.einsum("...ii->...i", S)[...] += np.where(mask, r, 1.0)
    nis = np.maximum((v * v * wr).sum(axis=1) - (y * y).sum(axis=1), 0.0)
    logdet = np.log(np.where(mask, r, 1.0)).sum(axis=1) + chol_logdet(G)
    n_meas = mask.sum(axis=1)
    log_lik = -0.5 * (nis + logdet + n_meas * LOG_2PI)
    healthy = ok_M & health(m_new, P_new)
    return GaussianState(m_new, P_new), UpdateInfo(v, S, nis, log_lik, healthy, n_meas)
