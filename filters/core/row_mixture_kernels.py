"""Compiled (Numba) kernel of one row of the per-row mixture update (:mod:`filters.row_mixture`).

Row ``i`` of the sequential update, for every filter of the batch, given the row's measurement
prediction (the base filter's, R excluded): the innovation ``v``, the predicted variance
``c = C_ii`` and the cross covariance ``p = P_xz[:, i]``. The two noise components share them
and differ only in the row's variance, ``r_0 = R_ii`` (nominal) and ``r_1 = ratio_i R_ii``
(outlier) (Benzerrouk 2014, eq. 71-72)::

    S_j = c + r_j,   W_j = p / sqrt(S_j),   e_j = v / sqrt(S_j)
    m_j = m + W_j e_j,   P_j = P - W_j W_j^T
    log gamma_j = -1/2 (e_j^2 + log S_j + log 2 pi)
    log alpha_j = log pi_j + log gamma_j - log sum_k pi_k gamma_k           (eq. 74)
    m+ = sum_j alpha_j m_j,   P+ = sum_j alpha_j [P_j + (m_j - m+)(m_j - m+)^T]   (eq. 75-76)

The NumPy path (:func:`filters.gaussian_sum.update_checked` through the base filter's bank)
conditions each component on the whole ``m``-row measurement with every row but ``i``
neutralized: an ``m x m`` Cholesky of a matrix that is the identity but for one entry, whose
only non-trivial pivot is ``sqrt(S_j)``. A scalar row needs none of it; the kernel forms the
same quantities in the same order (the whitened forms of
:func:`filters.core.gaussian_kernels.condition_one`), so the numbers agree to rounding
(``tests/filters/test_row_mixture.py`` holds the two paths together).

A filter the kernel does not take is flagged (``ok`` False) and the caller runs the NumPy
path's row update for the batch: a non-positive or non-finite ``S_j``, an unhealthy component
(``m_j`` not finite or ``P_j`` not positive definite, which that path gives weight 0), or no
usable component.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.gaussian_kernels import _FAST, _LOG_2PI, positive_definite

__all__ = ["row_pass"]


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def row_pass(
    m, P, v, c, p, r, ratio, log_pi, used, m_out, P_out, s_out, ll_out, alpha_out, ok
):  # pragma: no cover - compiled
    """Row ``i``'s two-component update of every filter (module docstring for the equations).

    Inputs: ``m (B, n)``, ``P (B, n, n)`` symmetric, the row's innovation ``v (B,)``, predicted
    variance ``c (B,)`` and cross covariance ``p (B, n)``, nominal variance ``r (B,)``, the
    outlier ``ratio`` (scalar), prior log-weights ``log_pi (B, 2)`` (nominal, outlier) and
    ``used (B,)`` (the filter has row ``i``). Writes, for used filters: the moment-matched
    ``m_out (B, n)``, ``P_out (B, n, n)`` (exactly symmetric), the mixture's predictive variance
    with the prior weights ``s_out (B,)``, the log-evidence ``ll_out (B,)``, the outlier
    component's posterior weight ``alpha_out (B,)``; unused filters keep ``m``, ``P`` (copied)
    and get ``s = 1``, ``ll = 0``, ``alpha = exp(log_pi_1)``. ``ok (B,)`` False marks a filter
    the kernel did not take (module docstring); its outputs are unspecified.
    """
    B, n = m.shape
    mj = np.empty((2, n))
    Pj = np.empty((2, n, n))
    W = np.empty(n)
    scratch = np.empty((n, n))
    joint = np.empty(2)
    S = np.empty(2)
    for b in range(B):
        mb, Pb = m[b], P[b]
        ok[b] = True
        if not used[b]:
            for i in range(n):
                m_out[b, i] = mb[i]
                for j in range(n):
                    P_out[b, i, j] = Pb[i, j]
            s_out[b] = 1.0
            ll_out[b] = 0.0
            alpha_out[b] = np.exp(log_pi[b, 1])
            continue
        vb = v[b]
        good = np.isfinite(vb)
        for k in range(2):
            Sk = c[b] + (r[b] if k == 0 else r[b] * ratio)
            S[k] = Sk
            if not (Sk > 0.0) or not np.isfinite(Sk):
                good = False
                break
            L = np.sqrt(Sk)
            inv = 1.0 / L
            e = vb * inv
            msum = 0.0
            for i in range(n):
                W[i] = p[b, i] * inv
                mk = mb[i] + W[i] * e
                mj[k, i] = mk
                msum += mk
            for i in range(n):
                for j in range(i + 1):
                    s = 0.5 * (Pb[i, j] + Pb[j, i]) - W[i] * W[j]
                    Pj[k, i, j] = s
                    Pj[k, j, i] = s
            if not np.isfinite(msum) or not positive_definite(Pj[k], scratch):
                good = False
                break
            joint[k] = log_pi[b, k] + (-0.5 * (e * e + np.log(Sk) + _LOG_2PI))
        if not good:
            ok[b] = False
            continue
        mx = max(joint[0], joint[1])
        if not np.isfinite(mx):
            ok[b] = False
            continue
        total = mx + np.log(np.exp(joint[0] - mx) + np.exp(joint[1] - mx))
        w0 = np.exp(joint[0] - total)
        w1 = np.exp(joint[1] - total)
        for i in range(n):
            m_out[b, i] = w0 * mj[0, i] + w1 * mj[1, i]
        for i in range(n):
            d0i = mj[0, i] - m_out[b, i]
            d1i = mj[1, i] - m_out[b, i]
            for j in range(i + 1):
                d0j = mj[0, j] - m_out[b, j]
                d1j = mj[1, j] - m_out[b, j]
                s = (w0 * Pj[0, i, j] + w1 * Pj[1, i, j]) + (d0i * w0 * d0j + d1i * w1 * d1j)
                P_out[b, i, j] = s
                P_out[b, j, i] = s
        s_out[b] = np.exp(log_pi[b, 0]) * S[0] + np.exp(log_pi[b, 1]) * S[1]
        ll_out[b] = total
        alpha_out[b] = w1
