"""Compiled (Numba) kernels of the linear-Gaussian predict, update and conditioning.

Twins of NumPy code that stays the reference: :func:`sandwich_pass` of
:func:`filters.core.linalg.sandwich` (with the fading factor and ``Q`` of
:func:`filters.kalman.predict`), :func:`update_pass` of :func:`filters.core.conditioning.condition`
on ``S = H P H^T + R``, ``P_xz = P H^T`` (the KF/EKF update of :func:`filters.kalman.update`).
:mod:`filters.kalman` chooses them for float64 beliefs of up to :data:`MAX_STATES` states (the
update for at most :data:`MAX_MEASUREMENTS` and at most ``n`` measurement rows: with more rows
than states, e.g. 12 pseudo-ranges of an 8-state GpsIns filter, the NumPy path's
observed-subspace form, :func:`filters.core.conditioning.condition_observed`, does less work
than the kernel's ``m x m`` algebra) unless the switch of :mod:`filters.core.compiled` forces
NumPy; ``tests/filters/test_gaussian_kernels.py`` holds the two paths equal.

Why: at n = 9, m = 4 the NumPy path is a dozen batched calls on ``(B, 9, 9)`` arrays, each
paying NumPy's per-call and per-matrix overhead (LAPACK's Cholesky is called per matrix);
here one pass over the batch keeps the matrices in L1. :func:`sandwich_pass` and
:func:`update_pass` run :data:`LANES` filters at a time, lane-last (``(n, n, LANES)``
scratch): the factorizations are chains of dependent square roots and divisions, and eight
filters' chains side by side keep the core busy while each waits (the gain is in
``docs/performance.md``, "Figures behind the code").

The update (Benzerrouk 2014, eq. 19-21 in the whitened form of
:mod:`filters.core.conditioning`), per filter: masked rows neutralized (zero innovation and
cross-covariance column, unit variance, no cross terms), ``S = L L^T``
(Cholesky-Banachiewicz), ``L [W^T | e] = [P_xz^T | v]`` by forward substitution,
``m+ = m + W e``, ``P+ = P - W W^T`` (lower triangle formed, then mirrored: exactly
symmetric), ``NIS = |e|^2``, ``log p(z) = -(NIS + 2 sum log L_ii + m_used log 2 pi) / 2``, and
the health flag, in the same pass: finite ``m+`` and ``P+`` positive definite (the pivots of
an ``L D L^T`` elimination all positive and finite, the test LAPACK's ``potrf`` makes,
without its square roots). A filter whose ``S`` has a non-positive or non-finite pivot is
reported (``ok_S`` False) and left to the NumPy path, whose jitter fallback it needs.

:func:`condition` (:func:`condition_pass`, one filter per iteration through
:func:`condition_one`) is the same update from given moments ``(v, S, P_xz)``: the compiled
twin of :func:`filters.core.conditioning.condition`, for the moment-based filters
(sigma-point, divided-difference and their fading and Gaussian-sum forms) once that function
chooses it; the sigma-point kernels of :mod:`filters.core.sigma_point_kernels` use
:func:`cholesky_lanes`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.types import GaussianState, UpdateInfo

__all__ = [
    "LANES",
    "MAX_MEASUREMENTS",
    "MAX_STATES",
    "cholesky_lanes",
    "cholesky_small",
    "condition",
    "condition_one",
    "condition_pass",
    "positive_definite",
    "sandwich_pass",
    "update_pass",
]

#: Largest state dimension and number of measurement rows the kernels are chosen for (their
#: scratch matrices are per call; beyond these sizes BLAS-backed NumPy is as fast).
MAX_STATES = 24
MAX_MEASUREMENTS = 16

_FAST = {"contract", "nsz"}  # FMA contraction; no reassociation (sums in the written order)
_LOG_2PI = float(np.log(2.0 * np.pi))
#: Filters per group of the lane-last passes. The lane loops run to the group's own size, a
#: trip count LLVM cannot fold: with a constant one (8, 16, 32) its loop vectorizer leaves
#: them scalar (a tiny constant trip count allows no runtime alias checks); with an opaque
#: one it vectorizes them (``docs/performance.md``, "Figures behind the code"), and a short
#: last group costs only its own lanes.
LANES = 32


@njit(cache=True, error_model="numpy")
def _pattern(A, idx, cnt):  # pragma: no cover - compiled
    """Column indices ``idx[i, :cnt[i]]`` of each row of ``A (G, r, c)`` nonzero in some member.

    The products skip structural zeros (constant-velocity ``F``, range ``H`` rows that see
    three position states): adding ``0 * x`` changes no finite sum, and ``P`` is finite
    (checked by the step functions).
    """
    G, r, c = A.shape
    nz = np.zeros((r, c), dtype=np.bool_)
    for g in range(G):
        for i in range(r):
            for j in range(c):
                if A[g, i, j] != 0.0:
                    nz[i, j] = True
    for i in range(r):
        t = 0
        for j in range(c):
            if nz[i, j]:
                idx[i, t] = j
                t += 1
        cnt[i] = t


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def sandwich_pass(F, P, lam, Q, out):  # pragma: no cover - compiled
    """``out_b = lam_b F_b P_b F_b^T + Q_b`` (Benzerrouk 2014, eq. 18 and 67-69).

    ``F (1 or B, n, n)``, ``P (B, n, n)`` symmetric, ``lam (B,)``, ``Q (1 or B, n, n)``
    symmetric; a leading axis of 1 is shared by the batch. The lower triangle is formed and
    mirrored (the result is exactly symmetric).

    :data:`LANES` filters at a time: their ``P`` (and ``F``) are copied lane-last into scratch
    ``(n, n, LANES)`` so the products run across filters (structural zeros of ``F``, the union
    over the batch, skipped); a shorter last group runs its own lanes only.
    """
    B, n = P.shape[0], P.shape[1]
    idx = np.empty((n, n), dtype=np.int64)
    cnt = np.empty(n, dtype=np.int64)
    _pattern(F, idx, cnt)
    shared = F.shape[0] == 1
    Pl = np.empty((n, n, LANES))
    Fl = np.empty((n, n, LANES))
    T = np.empty((n, n, LANES))
    O = np.empty((n, n, LANES))
    if shared:
        for i in range(n):
            for j in range(n):
                for l in range(LANES):
                    Fl[i, j, l] = F[0, i, j]
    for b0 in range(0, B, LANES):
        G = min(LANES, B - b0)  # lanes of this group (a trip count LLVM cannot fold)
        for l in range(G):
            bb = b0 + l
            for i in range(n):
                for j in range(n):
                    Pl[i, j, l] = P[bb, i, j]
            if not shared:  # the union pattern's entries only (the products read no others)
                for i in range(n):
                    for t in range(cnt[i]):
                        c = idx[i, t]
                        Fl[i, c, l] = F[bb, i, c]
        for i in range(n):  # T = F P
            for j in range(n):
                for l in range(G):
                    T[i, j, l] = 0.0
                for t in range(cnt[i]):
                    c = idx[i, t]
                    for l in range(G):
                        T[i, j, l] += Fl[i, c, l] * Pl[c, j, l]
        for i in range(n):  # O = T F^T, lower triangle
            for j in range(i + 1):
                for l in range(G):
                    O[i, j, l] = 0.0
                for t in range(cnt[j]):
                    c = idx[j, t]
                    for l in range(G):
                        O[i, j, l] += T[i, c, l] * Fl[j, c, l]
        for l in range(G):
            bb = b0 + l
            lb = lam[bb]
            Qb = Q[bb if Q.shape[0] > 1 else 0]
            ob = out[bb]
            for i in range(n):
                for j in range(i + 1):
                    s = lb * O[i, j, l] + Qb[i, j]
                    ob[i, j] = s
                    ob[j, i] = s


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def positive_definite(A, W):  # pragma: no cover - compiled
    """Whether symmetric ``A (n, n)`` (lower triangle read) is positive definite; ``W (n, n)`` scratch.

    Right-looking ``L D L^T`` elimination (no square roots, independent updates of the trailing
    triangle after each pivot): positive definite iff every pivot ``d_j`` is positive and
    finite. The pivots are those of the Cholesky factorization LAPACK's ``potrf`` tests
    (``d_j = L_jj^2``), up to rounding.
    """
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1):
            W[i, j] = A[i, j]
    for j in range(n):
        d = W[j, j]
        if not (d > 0.0) or not np.isfinite(d):
            return False
        inv = 1.0 / d
        for i in range(j + 1, n):
            f = W[i, j] * inv
            for q in range(j + 1, i + 1):
                W[i, q] -= f * W[q, j]
    return True


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def cholesky_small(A, L):  # pragma: no cover - compiled
    """Lower Cholesky factor of symmetric ``A (k, k)`` into ``L`` (Cholesky-Banachiewicz).

    False on a pivot that is not positive (NaN included), ``L`` then unfinished.
    """
    k = A.shape[0]
    for i in range(k):
        for j in range(k):
            L[i, j] = 0.0
    for i in range(k):
        for j in range(i + 1):
            acc = A[i, j]
            for q in range(j):
                acc -= L[i, q] * L[j, q]
            if i == j:
                if not acc > 0.0:
                    return False
                L[i, i] = np.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
    return True


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def cholesky_lanes(A, L, Linv, ok, G):  # pragma: no cover - compiled
    """Lower Cholesky factors of :data:`LANES` symmetric matrices side by side, ``(n, n, LANES)``.

    Cholesky-Banachiewicz, the lower triangle of ``A`` read; a pivot that is not positive or
    not finite marks the matrix not positive definite, the case the NumPy path's jitter
    fallback (:func:`filters.core.linalg.cholesky`) handles.

    The first ``G`` lanes are factorized. Writes the reciprocal pivots ``Linv (n, LANES)`` and
    ``ok (LANES,)``, False for a lane with a non-positive or non-finite pivot (it continues on
    pivot 1, its factor unspecified). The upper triangle of ``L`` is zeroed.
    """
    n = A.shape[0]
    for l in range(G):
        ok[l] = True
    for i in range(n):
        for j in range(i + 1):
            for l in range(G):
                L[i, j, l] = A[i, j, l]
            for q in range(j):
                for l in range(G):
                    L[i, j, l] -= L[i, q, l] * L[j, q, l]
            if i == j:
                for l in range(G):
                    a = L[i, i, l]
                    if not (a > 0.0) or not np.isfinite(a):
                        ok[l] = False
                        a = 1.0
                    r = np.sqrt(a)
                    L[i, i, l] = r
                    Linv[i, l] = 1.0 / r
            else:
                for l in range(G):
                    L[i, j, l] *= Linv[j, l]
        for j in range(i + 1, n):
            for l in range(G):
                L[i, j, l] = 0.0


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def condition_one(mb, Pb, PHt, Sb, vb, used, out_m, out_P, L, Linv, Wt, e, C):  # pragma: no cover
    """The whitened Kalman update of one filter (module docstring), given its moments.

    ``mb (n,)``, ``Pb (n, n)`` symmetric, ``PHt (n, k)`` the cross covariance and ``Sb (k, k)``
    the innovation covariance (both with masked rows neutralized), ``vb (k,)`` the masked
    innovation, ``used`` the number of used rows; writes ``out_m (n,)`` and ``out_P (n, n)``
    (exactly symmetric). ``L, Linv, Wt, e, C`` are scratch ``(k, k), (k,), (k, n), (k,), (n, n)``.

    Returns:
        ``(ok_S, nis, log_lik, healthy)``; with ``ok_S`` False (``S`` not positive definite or
        not finite) the other outputs are unspecified.
    """
    n, k = PHt.shape
    logdet = 0.0
    for i in range(k):  # S = L L^T
        for j in range(i + 1):
            acc = Sb[i, j]
            for q in range(j):
                acc -= L[i, q] * L[j, q]
            if i == j:
                if not (acc > 0.0) or not np.isfinite(acc):
                    return False, 0.0, 0.0, False
                L[i, i] = np.sqrt(acc)
                Linv[i] = 1.0 / L[i, i]
                logdet += np.log(acc)
            else:
                L[i, j] = acc * Linv[j]
    q2 = 0.0
    for i in range(k):  # L [W^T | e] = [P_xz^T | v]
        inv = Linv[i]
        acc = vb[i]
        for q in range(i):
            acc -= L[i, q] * e[q]
        e[i] = acc * inv
        q2 += e[i] * e[i]
        for j in range(n):
            acc = PHt[j, i]
            for q in range(i):
                acc -= L[i, q] * Wt[q, j]
            Wt[i, j] = acc * inv
    log_lik = -0.5 * (q2 + logdet + used * _LOG_2PI)
    msum = 0.0
    for j in range(n):  # m+ = m + W e
        acc = mb[j]
        for i in range(k):
            acc += Wt[i, j] * e[i]
        out_m[j] = acc
        msum += acc
    for i in range(n):  # P+ = P - W W^T, exactly symmetric
        for j in range(i + 1):
            acc = 0.0
            for q in range(k):
                acc += Wt[q, i] * Wt[q, j]
            s = 0.5 * (Pb[i, j] + Pb[j, i]) - acc
            out_P[i, j] = s
            out_P[j, i] = s
    # health: finite m+ and P+ positive definite
    healthy = np.isfinite(msum) and positive_definite(out_P, C)
    return True, q2, log_lik, healthy


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def update_pass(
    m, P, v, H, R, w, m_new, P_new, v_out, S_out, nis, log_lik, ok_S, healthy
):  # pragma: no cover
    """The KF/EKF update of every filter (module docstring).

    Inputs: ``m (B, n)``, ``P (B, n, n)`` symmetric, innovations ``v (B, k)``, ``H (1 or B, k,
    n)``, ``R (1 or B, k, k)``, row weights ``w (B, k)`` (1 used, 0 masked). Outputs:
    ``m_new``, ``P_new``, the masked innovations ``v_out``, ``S_out (B, k, k)`` (masked rows
    neutralized), ``nis``, ``log_lik``, ``ok_S`` (False: ``S`` not positive definite or not
    finite, the other outputs of that filter unspecified) and ``healthy``.

    :data:`LANES` filters at a time, lane-last (as :func:`sandwich_pass`): the factorizations
    are chains of dependent square roots and divisions, and running eight filters' chains
    side by side keeps the core busy while each waits. A lane whose pivot fails continues on
    pivot 1 with its flag down; a shorter last group runs its own lanes only.
    """
    B, n = m.shape
    k = v.shape[1]
    idx = np.empty((k, n), dtype=np.int64)
    cnt = np.empty(k, dtype=np.int64)
    _pattern(H, idx, cnt)
    shared_H, shared_R = H.shape[0] == 1, R.shape[0] == 1
    Pl = np.empty((n, n, LANES))
    Hl = np.empty((k, n, LANES))
    Rl = np.empty((k, k, LANES))
    X = np.empty((n, k, LANES))  # P_xz = P H^T
    Sl = np.empty((k, k, LANES))
    Ll = np.empty((k, k, LANES))
    Li = np.empty((k, LANES))
    Wt = np.empty((k, n, LANES))
    e = np.empty((k, LANES))
    Cl = np.empty((n, n, LANES))
    wl = np.empty((k, LANES))
    vl = np.empty((k, LANES))
    mo = np.empty((n, LANES))
    okl = np.empty(LANES, dtype=np.bool_)
    pdl = np.empty(LANES, dtype=np.bool_)
    ld = np.empty(LANES)
    q2 = np.empty(LANES)
    used = np.empty(LANES)
    if shared_H:
        for i in range(k):
            for c in range(n):
                for l in range(LANES):
                    Hl[i, c, l] = H[0, i, c]
    if shared_R:
        for i in range(k):
            for j in range(k):
                for l in range(LANES):
                    Rl[i, j, l] = R[0, i, j]
    for b0 in range(0, B, LANES):
        G = min(LANES, B - b0)  # lanes of this group (a trip count LLVM cannot fold)
        for l in range(G):  # gather, lane-last
            bb = b0 + l
            for i in range(n):
                for j in range(n):
                    Pl[i, j, l] = P[bb, i, j]
            u = 0.0
            for i in range(k):
                wl[i, l] = w[bb, i]
                vl[i, l] = v[bb, i] * w[bb, i]
                u += 1.0 if w[bb, i] != 0.0 else 0.0
            used[l] = u
            if not shared_H:  # the union pattern's entries only (the products read no others)
                for i in range(k):
                    for t in range(cnt[i]):
                        c = idx[i, t]
                        Hl[i, c, l] = H[bb, i, c]
            if not shared_R:
                for i in range(k):
                    for j in range(k):
                        Rl[i, j, l] = R[bb, i, j]
        for i in range(n):  # P_xz = P H^T, masked columns zeroed
            for j in range(k):
                for l in range(G):
                    X[i, j, l] = 0.0
                for t in range(cnt[j]):
                    c = idx[j, t]
                    for l in range(G):
                        X[i, j, l] += Pl[i, c, l] * Hl[j, c, l]
                for l in range(G):
                    X[i, j, l] *= wl[j, l]
        for i in range(k):  # S = H P H^T + R, masked rows and columns neutralized (lower)
            for j in range(i + 1):
                for l in range(G):
                    Sl[i, j, l] = 0.0
                for t in range(cnt[i]):
                    c = idx[i, t]
                    for l in range(G):
                        Sl[i, j, l] += Hl[i, c, l] * X[c, j, l]
                for l in range(G):
                    # X's column j carries w_j; H's row i is weighed here
                    s = (Sl[i, j, l] + Rl[i, j, l] * wl[j, l]) * wl[i, l]
                    if i == j:
                        s += 1.0 - wl[i, l]
                    Sl[i, j, l] = s
        cholesky_lanes(Sl, Ll, Li, okl, G)  # S = L L^T (a failed lane continues on pivot 1)
        for l in range(G):
            ld[l] = 0.0
            q2[l] = 0.0
        for i in range(k):  # log det S = 2 sum log L_ii
            for l in range(G):
                ld[l] += 2.0 * np.log(Ll[i, i, l])
        for i in range(k):  # L [W^T | e] = [P_xz^T | v]
            for l in range(G):
                e[i, l] = vl[i, l]
            for q in range(i):
                for l in range(G):
                    e[i, l] -= Ll[i, q, l] * e[q, l]
            for l in range(G):
                e[i, l] *= Li[i, l]
                q2[l] += e[i, l] * e[i, l]
            for j in range(n):
                for l in range(G):
                    Wt[i, j, l] = X[j, i, l]
                for q in range(i):
                    for l in range(G):
                        Wt[i, j, l] -= Ll[i, q, l] * Wt[q, j, l]
                for l in range(G):
                    Wt[i, j, l] *= Li[i, l]
        for j in range(n):  # m+ = m + W e (the prior mean added in the scatter below)
            for l in range(G):
                mo[j, l] = 0.0
            for i in range(k):
                for l in range(G):
                    mo[j, l] += Wt[i, j, l] * e[i, l]
        for i in range(n):  # P+ = P - W W^T, lower triangle (Cl, the health check's workspace)
            for j in range(i + 1):
                for l in range(G):
                    Cl[i, j, l] = 0.0
                for q in range(k):
                    for l in range(G):
                        Cl[i, j, l] += Wt[q, i, l] * Wt[q, j, l]
                for l in range(G):
                    Cl[i, j, l] = 0.5 * (Pl[i, j, l] + Pl[j, i, l]) - Cl[i, j, l]
        for l in range(G):  # scatter P+ before the health check works on Cl
            bb = b0 + l
            ob = P_new[bb]
            for i in range(n):
                for j in range(i + 1):
                    s = Cl[i, j, l]
                    ob[i, j] = s
                    ob[j, i] = s
        for l in range(G):
            pdl[l] = True
        for j in range(n):  # health: P+ positive definite (L D L^T pivots positive, finite)
            for l in range(G):
                d = Cl[j, j, l]
                if not (d > 0.0) or not np.isfinite(d):
                    pdl[l] = False
                    d = 1.0
                ld_inv = 1.0 / d
                for i in range(j + 1, n):
                    f = Cl[i, j, l] * ld_inv
                    for q in range(j + 1, i + 1):
                        Cl[i, q, l] -= f * Cl[q, j, l]
        for l in range(G):  # scatter
            bb = b0 + l
            msum = 0.0
            for j in range(n):
                s = m[bb, j] + mo[j, l]
                m_new[bb, j] = s
                msum += s
            Sb = S_out[bb]
            for i in range(k):
                v_out[bb, i] = vl[i, l]
                for j in range(i + 1):
                    s = Sl[i, j, l]
                    Sb[i, j] = s
                    Sb[j, i] = s
            ok_S[bb] = okl[l]
            nis[bb] = q2[l]
            log_lik[bb] = -0.5 * (q2[l] + ld[l] + used[l] * _LOG_2PI)
            healthy[bb] = okl[l] and pdl[l] and np.isfinite(msum)


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def condition_pass(
    m, P, v, S, P_xz, w, m_new, P_new, v_out, S_out, nis, log_lik, ok_S, healthy
):  # pragma: no cover
    """:func:`filters.core.conditioning.condition` of every filter (module docstring).

    Inputs: ``m (B, n)``, ``P (B, n, n)`` symmetric, innovations ``v (B, k)``, innovation
    covariances ``S (B, k, k)`` (lower triangle factorized), cross covariances
    ``P_xz (B, n, k)``, row weights ``w (B, k)`` (1 used, 0 masked). Outputs as
    :func:`update_pass`; ``S_out`` is ``S`` with masked rows and columns neutralized.
    """
    B, n = m.shape
    k = v.shape[1]
    PHt = np.empty((n, k))
    L = np.empty((k, k))
    Linv = np.empty(k)
    Wt = np.empty((k, n))
    e = np.empty(k)
    C = np.empty((n, n))
    for b in range(B):
        wb = w[b]
        Sb = S_out[b]
        used = 0
        for i in range(k):
            used += 1 if wb[i] != 0.0 else 0
            v_out[b, i] = v[b, i] * wb[i]
            for j in range(k):
                s = S[b, i, j] * (wb[i] * wb[j])
                if i == j:
                    s += 1.0 - wb[i]
                Sb[i, j] = s
        for i in range(n):
            for j in range(k):
                PHt[i, j] = P_xz[b, i, j] * wb[j]
        ok, q2, ll, good = condition_one(
            m[b], P[b], PHt, Sb, v_out[b], used, m_new[b], P_new[b], L, Linv, Wt, e, C
        )
        ok_S[b] = ok
        nis[b] = q2
        log_lik[b] = ll
        healthy[b] = good


def condition(
    m: np.ndarray, P: np.ndarray, v: np.ndarray, S: np.ndarray, P_xz: np.ndarray, mask: np.ndarray
) -> tuple[GaussianState, UpdateInfo] | None:
    """:func:`filters.core.conditioning.condition` by :func:`condition_pass`, or None.

    The compiled twin of the conditioning every moment-based update ends with (sigma-point,
    divided-difference, their fading and Gaussian-sum forms), for a caller that has chosen
    the compiled path (:func:`filters.core.compiled.compiled_enabled`). None (the caller runs
    the NumPy path) where the sizes exceed :data:`MAX_STATES` or :data:`MAX_MEASUREMENTS`,
    ``P`` is not float64, or some filter's ``S`` is not positive definite or not finite (the
    NumPy path's jitter fallback handles it). The results equal the NumPy path's to rounding.
    """
    B, n = m.shape
    k = v.shape[1]
    if P.dtype != np.float64 or not (0 < n <= MAX_STATES and 0 < k <= MAX_MEASUREMENTS):
        return None
    m_new, P_new = np.empty((B, n)), np.empty((B, n, n))
    v_out, S_out = np.empty((B, k)), np.empty((B, k, k))
    nis, log_lik = np.empty(B), np.empty(B)
    ok_S, healthy = np.empty(B, dtype=bool), np.empty(B, dtype=bool)
    f64 = np.float64
    condition_pass(
        np.ascontiguousarray(m, dtype=f64), np.ascontiguousarray(P), np.ascontiguousarray(v, dtype=f64),
        np.ascontiguousarray(S, dtype=f64), np.ascontiguousarray(P_xz, dtype=f64), mask.astype(f64),
        m_new, P_new, v_out, S_out, nis, log_lik, ok_S, healthy,
    )  # fmt: skip
    if not ok_S.all():
        return None
    info = UpdateInfo(v_out, S_out, nis, log_lik, healthy, mask.sum(axis=1))
    return GaussianState(m_new, P_new), info
