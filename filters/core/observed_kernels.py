"""Compiled (Numba) twin of the observed-subspace Kalman update.

:func:`observed_pass` is :func:`filters.core.conditioning.condition_observed` for one noise
diagonal per filter, one filter per loop iteration: measurements with diagonal noise
``R = diag(r)`` that depend on ``k <= 3`` states ``o`` (pseudo-ranges of an error-state INS: the
two horizontal position errors and the clock bias, ``k = 3`` for ``m = 12`` rows). With
``W = diag(w / r)`` (``w`` 1 for a used row, 0 for a masked one), ``P_oo = L L^T``,
``G_x = P_xo L^-T`` and ``H_s = H_o L`` (information form, Simon, *Optimal State Estimation*,
2006, §6.2)::

    M = I + H_s^T W H_s = G G^T,   V = G_x G^-T,   y = G^-1 H_s^T W v
    m+ = m + V y,   P+ = (P - G_x G_x^T) + V V^T
    NIS = v^T W v - |y|^2,   log det S = sum log r_i + 2 sum log diag G   (used rows i)

and ``S = H_s H_s^T + diag(r)`` with masked rows and columns neutralized (unit diagonal).

Why: the NumPy form is about thirty batched passes over ``(B, m, k)`` arrays, which at the
batch sizes of training (1-64 filters) cost their per-call overhead, about 280 us per update at
B = 1 on GpsIns; here one pass keeps a filter's matrices in registers and L1. The results
equal the NumPy path's to rounding (``tests/filters/core/test_observed_kernels.py``).
:func:`filters.kalman.update` chooses it where the compiled path is on, the beliefs are float64
of at most :data:`~filters.core.gaussian_kernels.MAX_STATES` states and the noise is one
diagonal per filter (a Gaussian-sum bank stays on the NumPy path).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.gaussian_kernels import cholesky_small, positive_definite
from filters.core.types import GaussianState, UpdateInfo

__all__ = ["observed_pass", "observed_update"]

_FAST = {"contract", "nsz"}  # FMA contraction; no reassociation (sums in the written order)
_LOG_2PI = float(np.log(2.0 * np.pi))


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def observed_pass(
    m, P, v, H, r, w, obs, m_new, P_new, v_out, S_out, nis, log_lik, ok, healthy
):  # pragma: no cover - compiled
    """The observed-subspace update of every filter (module docstring).

    Inputs: ``m (B, n)``, ``P (B, n, n)`` symmetric, innovations ``v (B, mdim)``, Jacobians
    ``H (1 or B, mdim, n)``, noise diagonals ``r (1 or B, mdim)``, row weights ``w (B, mdim)``
    (1 used, 0 masked), the observed state indices ``obs (k,)``. Outputs: the posterior
    ``m_new``, ``P_new`` (exactly symmetric), the masked innovations ``v_out``, ``S_out``,
    ``nis``, ``log_lik``, ``ok`` (False where a used row has ``r <= 0`` or ``P_oo`` is not
    positive definite: the caller then runs the NumPy path for the whole batch) and
    ``healthy`` (finite ``m+``, ``P+`` positive definite, ``M`` factorized).
    """
    B, n = m.shape
    mdim = v.shape[1]
    k = obs.shape[0]
    Poo = np.empty((k, k))
    L = np.empty((k, k))
    Hs = np.empty((mdim, k))
    Gx = np.empty((n, k))
    M = np.empty((k, k))
    G = np.empty((k, k))
    V = np.empty((n, k))
    hw = np.empty(k)
    y = np.empty(k)
    wr = np.empty(mdim)
    A = np.empty((n, n))
    Wk = np.empty((n, n))
    for b in range(B):
        Hb = H[b if H.shape[0] > 1 else 0]
        rb = r[b if r.shape[0] > 1 else 0]
        wb = w[b]
        good = True
        used = 0
        logdet = 0.0
        vwv = 0.0
        for i in range(mdim):
            if wb[i] != 0.0:
                used += 1
                if not rb[i] > 0.0:
                    good = False
                wr[i] = wb[i] / rb[i]
                logdet += np.log(rb[i])
            else:
                wr[i] = 0.0
            vi = v[b, i] * wb[i]
            v_out[b, i] = vi
            vwv += vi * vi * wr[i]
        for i in range(k):
            for j in range(k):
                Poo[i, j] = P[b, obs[i], obs[j]]
        if not good or not cholesky_small(Poo, L):
            ok[b] = False
            healthy[b] = False
            continue
        ok[b] = True
        for i in range(mdim):  # H_s = H_o L (masked rows zero)
            for j in range(k):
                s = 0.0
                if wb[i] != 0.0:
                    for q in range(j, k):
                        s += Hb[i, obs[q]] * L[q, j]
                Hs[i, j] = s
        for a in range(n):  # G_x = P_xo L^-T (forward substitution per row)
            for j in range(k):
                s = P[b, a, obs[j]]
                for q in range(j):
                    s -= L[j, q] * Gx[a, q]
                Gx[a, j] = s / L[j, j]
        for i in range(k):  # M = I + H_s^T W H_s, hw = H_s^T W v
            s = 0.0
            for a in range(mdim):
                s += Hs[a, i] * wr[a] * v_out[b, a]
            hw[i] = s
            for j in range(i + 1):
                s = 0.0
                for a in range(mdim):
                    s += Hs[a, i] * wr[a] * Hs[a, j]
                if i == j:
                    s += 1.0
                M[i, j] = s
                M[j, i] = s
        ok_M = cholesky_small(M, G)
        if not ok_M:  # only a non-finite M: flagged unhealthy, pivots 1 to finish the pass
            for i in range(k):
                for j in range(k):
                    G[i, j] = 1.0 if i == j else 0.0
        y2 = 0.0
        for i in range(k):  # y = G^-1 hw, V = G_x G^-T
            s = hw[i]
            for q in range(i):
                s -= G[i, q] * y[q]
            y[i] = s / G[i, i]
            y2 += y[i] * y[i]
            logdet += 2.0 * np.log(G[i, i])
        for a in range(n):
            for j in range(k):
                s = Gx[a, j]
                for q in range(j):
                    s -= G[j, q] * V[a, q]
                V[a, j] = s / G[j, j]
        msum = 0.0
        for a in range(n):
            s = 0.0
            for j in range(k):
                s += V[a, j] * y[j]
            s += m[b, a]
            m_new[b, a] = s
            msum += s
        for i in range(n):  # P+ = sym(P - G_x G_x^T + V V^T), lower triangle then mirrored
            for j in range(i + 1):
                s = 0.0
                for q in range(k):
                    s += Gx[i, q] * Gx[j, q] - V[i, q] * V[j, q]
                val = 0.5 * (P[b, i, j] + P[b, j, i]) - s
                A[i, j] = val
                P_new[b, i, j] = val
                P_new[b, j, i] = val
        Sb = S_out[b]
        for i in range(mdim):  # S = H_s H_s^T + R, masked rows and columns neutralized
            for j in range(i + 1):
                s = 0.0
                for q in range(k):
                    s += Hs[i, q] * Hs[j, q]
                if i == j:
                    s += rb[i] if wb[i] != 0.0 else 1.0
                Sb[i, j] = s
                Sb[j, i] = s
        quad = vwv - y2
        nis[b] = quad if quad > 0.0 else 0.0
        log_lik[b] = -0.5 * (nis[b] + logdet + used * _LOG_2PI)
        healthy[b] = ok_M and np.isfinite(msum) and positive_definite(A, Wk)


def observed_update(
    m: np.ndarray,
    P: np.ndarray,
    v: np.ndarray,
    H: np.ndarray,
    r: np.ndarray,
    mask: np.ndarray,
    observed: np.ndarray,
) -> tuple[GaussianState, UpdateInfo] | None:
    """:func:`filters.core.conditioning.condition_observed` by :func:`observed_pass`, or None.

    ``H`` is ``(m, n)`` or ``(B, m, n)``, ``r`` the noise diagonal ``(m,)`` or ``(B, m)`` (not a
    bank), ``observed`` the k states. None (the caller runs the NumPy path, which judges these
    filters as before) where some used row has ``r <= 0`` or some ``P_oo`` is not positive
    definite.
    """
    B, n = m.shape
    mdim = v.shape[1]
    f64 = np.float64
    m_new, P_new = np.empty((B, n)), np.empty((B, n, n))
    v_out, S_out = np.empty((B, mdim)), np.empty((B, mdim, mdim))
    nis, log_lik = np.empty(B), np.empty(B)
    ok, healthy = np.empty(B, dtype=bool), np.empty(B, dtype=bool)
    observed_pass(
        np.ascontiguousarray(m, dtype=f64), np.ascontiguousarray(P, dtype=f64),
        np.ascontiguousarray(v, dtype=f64),
        np.ascontiguousarray(H[None] if H.ndim == 2 else H, dtype=f64),
        np.ascontiguousarray(r[None] if r.ndim == 1 else r, dtype=f64),
        mask.astype(f64), np.ascontiguousarray(observed, dtype=np.int64),
        m_new, P_new, v_out, S_out, nis, log_lik, ok, healthy,
    )  # fmt: skip
    if not ok.all():
        return None
    info = UpdateInfo(v_out, S_out, nis, log_lik, healthy, mask.sum(axis=1))
    return GaussianState(m_new, P_new), info
