"""Batched small-matrix linear algebra shared by every filter.

NumPy's ``linalg`` routines are batched over leading axes but raise for the whole batch when a
single matrix fails; the helpers here keep the fast batched call on the common path and isolate
the failing members (jitter, health flags) only when it raises.
"""

from __future__ import annotations

import numpy as np

#: Relative jitter added to the diagonal of a matrix whose Cholesky factorization failed.
DEFAULT_JITTER = 1e-9
LOG_2PI = float(np.log(2.0 * np.pi))
#: Largest row count for which :func:`gram` multiplies by a copy of ``A^T`` (gemm, not syrk).
GRAM_GEMM_MAX_ROWS = 12


def symmetrize(P: np.ndarray) -> np.ndarray:
    """Return ``(P + P^T) / 2`` over the last two axes."""
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def sandwich(F: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``F P F^T`` for ``P (B, n, n)`` symmetric and ``F (r, n)`` shared or ``(B, r, n)``.

    A shared ``F`` goes through two large GEMMs on the stacked rows (``(B n, n) @ (n, r)``),
    about 1.5x faster than NumPy's per-matrix loop for small n; ``P`` must be symmetric
    (``(F P) = (P F^T)^T``). The result is symmetric up to rounding.
    """
    B, n = P.shape[0], P.shape[-1]
    if F.ndim == 2:
        r = F.shape[0]
        PFt = (P.reshape(B * n, n) @ F.T).reshape(B, n, r)
        FP = np.ascontiguousarray(np.swapaxes(PFt, -1, -2))
        return (FP.reshape(B * r, n) @ F.T).reshape(B, r, r)
    return (F @ P) @ np.swapaxes(F, -1, -2)


def cross(P: np.ndarray, H: np.ndarray) -> np.ndarray:
    """``P H^T`` for ``P (B, n, n)`` and ``H (m, n)`` shared (one GEMM) or ``(B, m, n)``."""
    if H.ndim == 2:
        B, n = P.shape[0], P.shape[-1]
        return (P.reshape(B * n, n) @ H.T).reshape(B, n, H.shape[0])
    return P @ np.swapaxes(H, -1, -2)


def gram(A: np.ndarray) -> np.ndarray:
    """``A A^T`` for stacked ``A (..., r, k)``, symmetric up to rounding.

    NumPy sends ``A @ swapaxes(A)`` (both operands one buffer) to BLAS ``syrk`` one small matrix
    at a time, slower than ``gemm`` on a contiguous copy of ``A^T`` for r <= 12
    (:data:`GRAM_GEMM_MAX_ROWS`; ``docs/performance.md``, "Gaussian filters"); larger matrices
    keep ``syrk``.
    """
    At = np.swapaxes(A, -1, -2)
    return A @ (np.ascontiguousarray(At) if A.shape[-2] <= GRAM_GEMM_MAX_ROWS else At)


def is_finite(x: np.ndarray) -> np.ndarray:
    """Whether every entry beyond the batch axis is finite, shape ``(B,)``."""
    return np.isfinite(x.reshape(x.shape[0], -1)).all(axis=1)


def cholesky(P: np.ndarray, jitter: float = DEFAULT_JITTER, tries: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Lower Cholesky factors of a batch of symmetric matrices, with jitter fallback.

    Fast path: one batched ``np.linalg.cholesky``. If it raises (a member is not positive
    definite), every member is tested on its own by :func:`cholesky_unrolled` (element-wise
    over the batch), so a member's factor and flag never depend on the rest of the batch: the
    members it factorizes get the fast path's factor (LAPACK again on those members alone, bit
    for bit what they get in a batch without the failing member; :func:`cholesky_unrolled`'s
    where LAPACK still refuses one), ``ok`` True, and only the members it cannot
    factorize are shifted by ``(jitter * s * 10**k - min(lambda_min, 0)) I`` (``s`` the spectral
    radius, ``lambda_min`` the smallest eigenvalue), escalating ``k`` over
    ``tries`` batched attempts. Non-finite members get the identity.

    Args:
        P: symmetric matrices, shape ``(..., n, n)``.
        jitter: first relative jitter.
        tries: number of escalating jitter attempts.

    Returns:
        ``(chol_P, ok)``: factors ``(..., n, n)`` and ``ok`` ``(...,)``, False where the matrix
        was not finite or needed a shift to be factorized.

    """
    try:
        return np.linalg.cholesky(P), np.ones(P.shape[:-2], dtype=bool)
    except np.linalg.LinAlgError:
        pass
    A, finite = _members(P)
    L, ok = cholesky_unrolled(A)
    ok &= finite
    good = np.flatnonzero(ok)
    if good.size:
        L_good, done = _per_member(np.linalg.cholesky, _raw_members(P)[good])
        L[good[done]] = L_good[done]
    bad = np.flatnonzero(~ok & finite)
    if bad.size:
        L[bad] = _shifted_cholesky(A[bad], jitter, tries)
    return L.reshape(P.shape), ok.reshape(P.shape[:-2])


def _members(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``P (..., n, n)`` as ``(M, n, n)`` members, symmetrized, non-finite ones replaced by ``I``.

    The common start of the per-member fallbacks (:func:`cholesky`, :func:`spd_inverse`,
    :func:`is_positive_definite`); also returns ``finite (M,)``.
    """
    n = P.shape[-1]
    A = np.ascontiguousarray(np.broadcast_to(P, P.shape)).reshape(-1, n, n)
    finite = np.isfinite(A).all(axis=(1, 2))
    return symmetrize(np.where(finite[:, None, None], A, np.eye(n))), finite


def _raw_members(P: np.ndarray) -> np.ndarray:
    """``P (..., n, n)`` as ``(M, n, n)`` members, as given (what the batched LAPACK path reads)."""
    n = P.shape[-1]
    return np.ascontiguousarray(np.broadcast_to(P, P.shape)).reshape(-1, n, n)


def _per_member(routine, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A batched LAPACK ``routine`` (``np.linalg.cholesky``, ``np.linalg.inv``) of members ``X (k, n, n)``.

    NumPy runs it matrix by matrix, so a member's result is the same in any batch: one batched
    call, and when it raises, member by member. Returns the results (zeros where it raised)
    and ``(k,)`` whether it succeeded.
    """
    try:
        return routine(X), np.ones(X.shape[0], dtype=bool)
    except np.linalg.LinAlgError:
        pass
    out = np.zeros_like(X)
    done = np.ones(X.shape[0], dtype=bool)
    for i in range(X.shape[0]):
        try:
            out[i] = routine(X[i])
        except np.linalg.LinAlgError:
            done[i] = False
    return out, done


def _shifted_cholesky(A: np.ndarray, jitter: float, tries: int) -> np.ndarray:
    """Factors of ``A + shift I`` for members ``A (k, n, n)`` that are not positive definite."""
    n = A.shape[-1]
    eye = np.eye(n)
    lam = np.linalg.eigvalsh(A)
    lam_min = lam[:, 0]
    scale = np.maximum(np.abs(lam).max(axis=-1), 1e-300)
    for k in range(tries):
        shift = jitter * scale * 10.0**k - np.minimum(lam_min, 0.0)
        L, ok = cholesky_unrolled(A + shift[:, None, None] * eye)
        if ok.all():
            return L
    return np.broadcast_to(eye, A.shape).copy()  # last resort: the identity


def solve_lower(L: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve ``L X = rhs`` for lower-triangular ``L (B, m, m)`` and ``rhs (B, m, k)``.

    Forward substitution vectorized over the batch, looping over the m rows (NumPy has no
    batched triangular solve; ``np.linalg.solve`` would LU-factorize every matrix again). For the
    small m of navigation filters this is several times cheaper than ``np.linalg.inv``.
    """
    m = L.shape[-1]
    X = np.empty(np.broadcast_shapes(rhs.shape), dtype=np.result_type(L, rhs))
    d = np.diagonal(L, axis1=-2, axis2=-1)
    for i in range(m):
        r = rhs[:, i, :]
        if i:
            r = r - (L[:, i : i + 1, :i] @ X[:, :i, :])[:, 0, :]
        X[:, i, :] = r / d[:, i, None]
    return X


def chol_logdet(chol_S: np.ndarray) -> np.ndarray:
    """``log det S`` from its lower Cholesky factor: ``2 sum log diag L``."""
    return 2.0 * np.log(np.diagonal(chol_S, axis1=-2, axis2=-1)).sum(axis=-1)


def spd_inverse(S: np.ndarray, rcond: float = 1e-13) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse and log-determinant of a batch of symmetric positive-definite matrices.

    The Cholesky factorization doubles as the positive-definiteness check: one batched
    ``np.linalg.cholesky`` and ``np.linalg.inv`` on the common path. When it raises, each member
    is tested on its own (:func:`cholesky_unrolled`), so a member's result never depends on
    the rest of the batch: the members that factorize are inverted and their log-determinant
    taken as on the common path (the same LAPACK calls on those members alone: bit for bit); the
    others (not positive definite, not finite, or singular to working precision although their
    pivots passed by rounding) are flagged ``ok = False`` and inverted from
    their eigen-decomposition with the eigenvalues floored at ``rcond`` times the largest, so the
    batch never raises and never returns NaN for finite input.

    Args:
        S: shape ``(B, m, m)``.
        rcond: relative eigenvalue floor of the fallback.

    Returns:
        ``(S_inv, logdet, ok)`` with shapes ``(B, m, m)``, ``(B,)``, ``(B,)``.
    """
    try:
        chol_S = np.linalg.cholesky(S)
        ok = np.ones(S.shape[:-2], dtype=bool)
        S_inv = np.linalg.inv(S)
        return S_inv, chol_logdet(chol_S), ok
    except np.linalg.LinAlgError:
        pass
    lead, m = S.shape[:-2], S.shape[-1]
    A, finite = _members(S)  # any leading axes
    L, ok = cholesky_unrolled(A)
    ok &= finite
    S_inv = np.empty_like(A)
    logdet = np.empty(A.shape[0])
    good = np.flatnonzero(ok)
    if good.size:
        raw = _raw_members(S)[good]
        # A member can pass the element-wise pivots by rounding and still be singular to working
        # precision (a rank-one spread of 1e18 beside a noise of 1e2 m^2): LAPACK refuses it.
        S_inv_good, inverted = _per_member(np.linalg.inv, raw)
        L_good, factored = _per_member(np.linalg.cholesky, raw)
        logdet_good = chol_logdet(L[good])
        logdet_good[factored] = chol_logdet(L_good[factored])
        ok[good[~inverted]] = False
        S_inv[good[inverted]] = S_inv_good[inverted]
        logdet[good[inverted]] = logdet_good[inverted]
    bad = np.flatnonzero(~ok)
    lam, V = np.linalg.eigh(A[bad])
    top = np.maximum(np.abs(lam).max(axis=-1, keepdims=True), 1e-300)
    lam = np.maximum(lam, rcond * top)
    S_inv[bad] = (V / lam[..., None, :]) @ np.swapaxes(V, -1, -2)
    logdet[bad] = np.log(lam).sum(axis=-1)
    return S_inv.reshape(*lead, m, m), logdet.reshape(lead), ok.reshape(lead)


def joseph_update(P: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Joseph-form covariance update ``(I - K H) P (I - K H)^T + K R K^T``.

    Positive semi-definite by construction for any gain K (Bucy & Joseph 1968; Simon,
    *Optimal State Estimation*, eq. 5.19).

    Args:
        P: prior covariances ``(B, n, n)``.
        K: gains ``(B, n, m)``.
        H: observation matrices ``(B, m, n)`` or ``(m, n)``.
        R: measurement covariances ``(B, m, m)`` or ``(m, m)``.

    """
    A = np.eye(P.shape[-1]) - K @ H
    KT = np.swapaxes(K, -1, -2)
    return symmetrize(A @ P @ np.swapaxes(A, -1, -2) + K @ R @ KT)


def is_positive_definite(P: np.ndarray) -> np.ndarray:
    """Per-member positive definiteness of ``(B, n, n)`` symmetric matrices, shape ``(B,)``.

    Whether the Cholesky factorization succeeds: one batched ``np.linalg.cholesky``, and when it
    raises, :func:`cholesky_unrolled` member by member (element-wise over the batch). Non-finite
    members are not positive definite.
    """
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        A, finite = _members(P)
        return (finite & cholesky_unrolled(A)[1]).reshape(P.shape[:-2])
    return np.isfinite(P).all(axis=(-1, -2))  # LAPACK may pass NaN through without raising


def trace_of_spd_inverse(A: np.ndarray) -> np.ndarray:
    """``tr A^-1`` for small SPD ``A (B, n, n)`` by an element-wise Cholesky over the batch.

    ``L`` by :func:`cholesky_unrolled`, then ``Y = L^-1`` by forward substitution
    (:func:`solve_lower_rows` of the identity), ``tr A^-1 = sum Y_ij^2``; NaN where a pivot is
    not positive (not positive definite). For n <= 4 (GDOP) this is several times cheaper than
    ``np.linalg.inv``, whose per-matrix LAPACK call dominates.
    """
    n = A.shape[-1]
    L, ok = cholesky_unrolled(A)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        Y = solve_lower_rows(L, np.broadcast_to(np.eye(n), A.shape))  # Y[:, j, i] = (L^-1)_ij
        total = np.zeros(A.shape[0])
        for j in range(n):
            for i in range(j, n):
                total += Y[:, j, i] * Y[:, j, i]
    return np.where(ok, total, np.nan)


def cholesky_unrolled(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower Cholesky factors of symmetric ``A (B, k, k)``, per member, element-wise over the batch.

    Cholesky-Banachiewicz over the ``k (k + 1) / 2`` entries, each a pass over the batch: for
    k <= 4 several times cheaper than ``np.linalg.cholesky``, whose per-matrix LAPACK call
    dominates (the observed-subspace update), and, because it never raises, the per-member
    factorization of the fallbacks of :func:`cholesky`, :func:`spd_inverse` and
    :func:`is_positive_definite` (as fast as a column-oriented form up to k = 15).

    Returns:
        ``(L, ok)``: ``L (B, k, k)`` (upper triangle zero) and ``ok (B,)``, False where a pivot
        was not positive (not positive definite, or not finite); such members get pivot 1 and
        must not be used.
    """
    k = A.shape[-1]
    L = np.zeros_like(A)
    good = []
    with np.errstate(over="ignore", invalid="ignore"):  # only in members flagged not ok
        for i in range(k):
            for j in range(i + 1):
                acc = A[:, i, j] if j == 0 else A[:, i, j] - L[:, i, 0] * L[:, j, 0]
                for q in range(1, j):
                    acc -= L[:, i, q] * L[:, j, q]
                if i == j:
                    good.append(acc > 0)  # False for NaN too
                    np.sqrt(np.where(good[-1], acc, 1.0), out=L[:, i, i])
                else:
                    np.divide(acc, L[:, j, j], out=L[:, i, j])
    return L, np.logical_and.reduce(good)


def solve_lower_rows(L: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``X L^-T`` for small lower-triangular ``L (B, k, k)`` and ``X (B, r, k)``.

    Row by row ``Y L^T = X`` is the forward substitution ``L y_i = x_i``, unrolled over the k
    columns (passes over ``(B, r)`` arrays; see :func:`cholesky_unrolled`).
    """
    k = L.shape[-1]
    Y = np.empty(np.broadcast_shapes(X.shape), dtype=np.result_type(L, X))
    for i in range(k):
        acc = X[:, :, i] if i == 0 else X[:, :, i] - Y[:, :, 0] * L[:, i, 0, None]
        for q in range(1, i):
            acc -= Y[:, :, q] * L[:, i, q, None]
        np.divide(acc, L[:, i, i, None], out=Y[:, :, i])
    return Y
