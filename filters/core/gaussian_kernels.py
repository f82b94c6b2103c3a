"""Compiled (Numba) kernels of the linear-Gaussian predict and update, one filter per iteration.

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
here one loop over the batch keeps each filter's matrices in registers and L1.

The update (Benzerrouk 2014, eq. 19-21 in the whitened form of
:mod:`filters.core.conditioning`), per filter: masked rows neutralized (zero innovation and
cross-covariance column, unit variance, no cross terms), ``S = L L^T`` (Cholesky-Banachiewicz),
``L [W^T | e] = [P_xz^T | v]`` by forward substitution, ``m+ = m + W e``, ``P+ = P - W W^T``
(lower triangle formed, then mirrored: exactly symmetric), ``NIS = |e|^2``,
``log p(z) = -(NIS + 2 sum log L_ii + m_used log 2 pi) / 2``, and the health flag: finite
``m+`` and a Cholesky factorization of ``P+`` whose pivots are all positive and finite (the
test LAPACK's ``potrf`` makes). A filter whose ``S`` has a non-positive or non-finite pivot is
reported (``ok_S`` False) and left to the NumPy path, whose jitter fallback it needs.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["MAX_MEASUREMENTS", "MAX_STATES", "sandwich_pass", "update_pass"]

#: Largest state dimension and number of measurement rows the kernels are chosen for (their
#: scratch matrices are per call; beyond these sizes BLAS-backed NumPy is as fast).
MAX_STATES = 24
MAX_MEASUREMENTS = 16

_FAST = {"contract", "nsz"}  # FMA contraction; no reassociation (sums in the written order)


@njit(cache=True, error_model="numpy", inline="always")
def _row_nonzeros(A, idx, cnt):  # pragma: no cover - compiled
    """Column indices ``idx[i, :cnt[i]]`` of the nonzero entries of each row of ``A``.

    The products below skip structural zeros (constant-velocity ``F``, range ``H`` rows that
    see three position states): adding ``0 * x`` changes no finite sum, and ``P`` is finite
    (checked by the step functions).
    """
    for i in range(A.shape[0]):
        c = 0
        for j in range(A.shape[1]):
            if A[i, j] != 0.0:
                idx[i, c] = j
                c += 1
        cnt[i] = c


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def sandwich_pass(F, P, lam, Q, out):  # pragma: no cover - compiled
    """``out_b = lam_b F_b P_b F_b^T + Q_b`` (Benzerrouk 2014, eq. 18 and 67-69).

    ``F (1 or B, n, n)``, ``P (B, n, n)`` symmetric, ``lam (B,)``, ``Q (1 or B, n, n)``
    symmetric; a leading axis of 1 is shared by the batch. The lower triangle is formed and
    mirrored (the result is exactly symmetric).
    """
    B, n = P.shape[0], P.shape[1]
    T = np.empty((n, n))
    idx = np.empty((n, n), dtype=np.int64)
    cnt = np.empty(n, dtype=np.int64)
    shared = F.shape[0] == 1
    if shared:
        _row_nonzeros(F[0], idx, cnt)
    for b in range(B):
        Fb = F[0 if shared else b]
        if not shared:
            _row_nonzeros(Fb, idx, cnt)
        Qb = Q[b if Q.shape[0] > 1 else 0]
        Pb = P[b]
        for i in range(n):  # T = F P (row i of F: its nonzeros)
            for j in range(n):
                acc = 0.0
                for t in range(cnt[i]):
                    c = idx[i, t]
                    acc += Fb[i, c] * Pb[c, j]
                T[i, j] = acc
        lb = lam[b]
        ob = out[b]
        for i in range(n):  # out = lam T F^T + Q, lower triangle mirrored
            for j in range(i + 1):
                acc = 0.0
                for t in range(cnt[j]):
                    c = idx[j, t]
                    acc += T[i, c] * Fb[j, c]
                s = lb * acc + Qb[i, j]
                ob[i, j] = s
                ob[j, i] = s


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def update_pass(m, P, v, H, R, w, m_new, P_new, v_out, S_out, nis, log_lik, ok_S, healthy):  # noqa: E501  # pragma: no cover
    """The KF/EKF update of every filter (module docstring).

    Inputs: ``m (B, n)``, ``P (B, n, n)`` symmetric, innovations ``v (B, k)``, ``H (1 or B, k,
    n)``, ``R (1 or B, k, k)``, row weights ``w (B, k)`` (1 used, 0 masked). Outputs:
    ``m_new``, ``P_new``, the masked innovations ``v_out``, ``S_out (B, k, k)`` (masked rows
    neutralized), ``nis``, ``log_lik``, ``ok_S`` (False: ``S`` not positive definite or not
    finite, the other outputs of that filter unspecified) and ``healthy``.
    """
    B, n = m.shape
    k = v.shape[1]
    PHt = np.empty((n, k))
    L = np.empty((k, k))
    Linv = np.empty(k)
    Cinv = np.empty(n)
    Wt = np.empty((k, n))
    e = np.empty(k)
    C = np.empty((n, n))
    idx = np.empty((k, n), dtype=np.int64)
    cnt = np.empty(k, dtype=np.int64)
    log_2pi = np.log(2.0 * np.pi)
    shared = H.shape[0] == 1
    if shared:
        _row_nonzeros(H[0], idx, cnt)
    for b in range(B):
        Hb = H[0 if shared else b]
        if not shared:
            _row_nonzeros(Hb, idx, cnt)
        Rb = R[b if R.shape[0] > 1 else 0]
        Pb, wb = P[b], w[b]
        for i in range(n):  # P_xz = P H^T, masked columns zeroed
            for j in range(k):
                acc = 0.0
                for t in range(cnt[j]):
                    c = idx[j, t]
                    acc += Pb[i, c] * Hb[j, c]
                PHt[i, j] = acc * wb[j]
        Sb = S_out[b]
        used = 0
        for i in range(k):  # S = H P H^T + R, masked rows and columns neutralized
            used += 1 if wb[i] != 0.0 else 0
            for j in range(i + 1):
                acc = 0.0
                for t in range(cnt[i]):
                    c = idx[i, t]
                    acc += Hb[i, c] * PHt[c, j]
                # PHt's column j carries w_j; H's row i is weighed here
                s = (acc + Rb[i, j] * wb[j]) * wb[i]
                if i == j:
                    s += 1.0 - wb[i]
                Sb[i, j] = s
                Sb[j, i] = s
            v_out[b, i] = v[b, i] * wb[i]
        good = True
        logdet = 0.0
        for i in range(k):  # S = L L^T
            for j in range(i + 1):
                acc = Sb[i, j]
                for l in range(j):  # noqa: E741
                    acc -= L[i, l] * L[j, l]
                if i == j:
                    if not (acc > 0.0) or not np.isfinite(acc):
                        good = False
                        acc = 1.0
                    L[i, i] = np.sqrt(acc)
                    Linv[i] = 1.0 / L[i, i]
                    logdet += np.log(acc)
                else:
                    L[i, j] = acc * Linv[j]
        ok_S[b] = good
        if not good:
            healthy[b] = False
            continue
        q = 0.0
        for i in range(k):  # L [W^T | e] = [P_xz^T | v]
            inv = Linv[i]
            acc = v_out[b, i]
            for l in range(i):  # noqa: E741
                acc -= L[i, l] * e[l]
            e[i] = acc * inv
            q += e[i] * e[i]
            for j in range(n):
                acc = PHt[j, i]
                for l in range(i):  # noqa: E741
                    acc -= L[i, l] * Wt[l, j]
                Wt[i, j] = acc * inv
        nis[b] = q
        log_lik[b] = -0.5 * (q + logdet + used * log_2pi)
        mb, out_m, out_P = m[b], m_new[b], P_new[b]
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
                for l in range(k):  # noqa: E741
                    acc += Wt[l, i] * Wt[l, j]
                s = 0.5 * (Pb[i, j] + Pb[j, i]) - acc
                out_P[i, j] = s
                out_P[j, i] = s
        pd = np.isfinite(msum)
        for i in range(n):  # health: P+ positive definite (Cholesky pivots > 0, finite)
            if not pd:
                break
            for j in range(i + 1):
                acc = out_P[i, j]
                for l in range(j):  # noqa: E741
                    acc -= C[i, l] * C[j, l]
                if i == j:
                    if not (acc > 0.0) or not np.isfinite(acc):
                        pd = False
                        break
                    C[i, i] = np.sqrt(acc)
                    Cinv[i] = 1.0 / C[i, i]
                else:
                    C[i, j] = acc * Cinv[j]
        healthy[b] = pd
