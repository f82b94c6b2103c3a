"""Compiled (Numba) kernels around the model calls of the sigma-point filters (UKF, CKF, GHKF).

A sigma-point step is ``points -> model -> moments``: the model's ``f``/``h`` is model code
(vectorised NumPy on all points of all filters at once) and stays outside; the parts around
it are one pass over the batch each, twins of NumPy code that stays the reference
(:func:`filters.sigma_point.sigma_points`, :func:`~filters.sigma_point.moments`,
:func:`~filters.sigma_point.predict_measurement` and :func:`filters.core.conditioning.condition`):

* :func:`points_pass`: ``X_l = m + chol(P) xi_l`` (Benzerrouk 2014, eq. 51), the Cholesky
  factor per filter (Cholesky-Banachiewicz), structural zeros of the unit points skipped;
* :func:`predict_pass`: ``m- = sum wm Y``, ``P- = lambda sum wc (Y - m-)(Y - m-)^T + Q``
  (eq. 52-54, fading eq. 64), exactly symmetric;
* :func:`moments_pass`: ``C = sum wc dZ dZ^T`` and ``P_xz = sum wc dX dZ^T`` (eq. 58-59), the
  :class:`~filters.core.types.MeasurementMoments` of
  :func:`~filters.sigma_point.predict_measurement`, which every moment-based update shares
  (the sigma-point update, its fading and Gaussian-sum forms, the CIF), so they all see the
  same numbers; the conditioning on them (eq. 60-62) is
  :func:`filters.core.conditioning.condition`, with a compiled twin in
  :func:`filters.core.gaussian_kernels.condition`.

Layout: the kernels keep the points **state-major**, ``Xt (n, B, S)`` C-contiguous (each state
component of every point of every filter one contiguous block for the passes). The model gets
them as the NumPy path gives them, a C-contiguous batch-first ``(B, S, n)`` copy: a model's
reductions (a range's sum of squares, a norm) round differently on other memory layouts, and a
strided view made a single filter's pseudo-ranges differ from the same filter's in a batch by one
ulp (GpsInsMixture's CKF). A model that declares itself element-wise
(:class:`~filters.core.models.ElementwiseModel`) gets the state-major points as a ``(B, S, n)``
view instead (no copy; its output, laid out like its input, is state-major already). A model's
output is copied into state-major order where it is not (:func:`state_major`).

:mod:`filters.sigma_point` chooses these kernels (in :func:`~filters.sigma_point.predict` and
:func:`~filters.sigma_point.predict_measurement`) for float64 beliefs of up to
:data:`~filters.core.gaussian_kernels.MAX_STATES` states and :data:`MAX_POINTS` points unless
the switch of :mod:`filters.core.compiled` forces NumPy. A filter whose ``P`` is not
numerically positive definite is reported by :func:`points_pass` and gets the NumPy path's
jittered points (and its unhealthy flag); the other filters keep the kernel's numbers.
``tests/filters/test_sigma_point_kernels.py`` holds the two paths equal.

The weighted sums over the points may be reassociated (``fastmath`` ``reassoc``: vectorised
over the points); each filter's numbers depend on its own inputs only.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.gaussian_kernels import LANES, _pattern, cholesky_lanes

__all__ = ["MAX_POINTS", "moments_pass", "points_pass", "predict_pass", "state_major"]

#: Most sigma points per filter the kernels are chosen for (the unscented rule in 24 states
#: has 49, cubature 48; Gauss-Hermite sets beyond this stay on the NumPy path).
MAX_POINTS = 128

_FAST = {"contract", "nsz"}
_SUMS = {"contract", "nsz", "reassoc"}  # the point sums: vectorised over the points


def state_major(Y: np.ndarray) -> np.ndarray:
    """``Y (B, S, d)`` as a C-contiguous ``(d, B, S)`` array: a view when it is one already."""
    return np.ascontiguousarray(Y.transpose(2, 0, 1), dtype=np.float64)


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def points_pass(m, P, xi, Xt, ok):  # pragma: no cover - compiled
    """``Xt[:, b, l] = m_b + chol(P_b) xi_l`` for every filter (Benzerrouk 2014, eq. 51).

    ``m (B, n)``, ``P (B, n, n)`` symmetric (lower triangle read), unit points ``xi (S, n)``;
    writes ``Xt (n, B, S)`` and ``ok (B,)`` (False: ``P_b`` not positive definite or not
    finite, its points unspecified). The factorizations run
    :data:`~filters.core.gaussian_kernels.LANES` filters side by side
    (:func:`~filters.core.gaussian_kernels.cholesky_lanes`).
    """
    B, n = m.shape
    S = xi.shape[0]
    Pl = np.empty((n, n, LANES))
    L = np.empty((n, n, LANES))
    Linv = np.empty((n, LANES))
    okl = np.empty(LANES, dtype=np.bool_)
    xi3 = xi.reshape((1, S, n))
    idx = np.empty((S, n), dtype=np.int64)
    cnt = np.empty(S, dtype=np.int64)
    _pattern(xi3, idx, cnt)
    # unscented and cubature points have at most one nonzero coordinate: X = m + xi_sc L[:, c]
    single = True
    for s in range(S):
        if cnt[s] > 1:
            single = False
    col = np.zeros(S, dtype=np.int64)
    val = np.zeros(S)
    for s in range(S):
        if cnt[s] == 1:
            col[s] = idx[s, 0]
            val[s] = xi[s, idx[s, 0]]
    for b0 in range(0, B, LANES):
        G = min(LANES, B - b0)
        for l in range(G):
            for i in range(n):
                for j in range(i + 1):
                    Pl[i, j, l] = P[b0 + l, i, j]
        cholesky_lanes(Pl, L, Linv, okl, G)
        for l in range(G):
            b = b0 + l
            ok[b] = okl[l]
            if single:  # a zero point gets m + 0 * L[:, 0] = m, as m + xi L^T does
                for i in range(n):
                    mi = m[b, i]
                    row = Xt[i, b]
                    Li = L[i]
                    for s in range(S):
                        row[s] = mi + val[s] * Li[col[s], l]
                continue
            for i in range(n):
                mi = m[b, i]
                row = Xt[i, b]
                for s in range(S):
                    acc = 0.0
                    for t in range(cnt[s]):
                        c = idx[s, t]
                        acc += xi[s, c] * L[i, c, l]
                    row[s] = mi + acc


@njit(cache=True, error_model="numpy", fastmath=_SUMS)
def predict_pass(Yt, wm, wc, lam, Q, m_out, P_out):  # pragma: no cover - compiled
    """Moments of the propagated points (Benzerrouk 2014, eq. 52-54; fading eq. 64).

    ``Yt (n, B, S)`` state-major points ``f(X)``, weights ``wm, wc (S,)``, ``lam (B,)``,
    ``Q (1 or B, n, n)``; writes ``m_out (B, n)`` and ``P_out (B, n, n)``, exactly symmetric
    (``lam C + (Q + Q^T) / 2``, the lower triangle of the spread mirrored).
    """
    n, B, S = Yt.shape
    d = np.empty((n, S))
    for b in range(B):
        for i in range(n):
            y = Yt[i, b]
            acc = 0.0
            for s in range(S):
                acc += wm[s] * y[s]
            m_out[b, i] = acc
            for s in range(S):
                d[i, s] = y[s] - acc
        lb = lam[b]
        Qb = Q[b if Q.shape[0] > 1 else 0]
        Pb = P_out[b]
        for i in range(n):
            for j in range(i + 1):
                acc = 0.0
                for s in range(S):
                    acc += wc[s] * d[i, s] * d[j, s]
                val = lb * acc + 0.5 * (Qb[i, j] + Qb[j, i])
                Pb[i, j] = val
                Pb[j, i] = val


@njit(cache=True, error_model="numpy", fastmath=_SUMS)
def moments_pass(m, Xt, Zt, zt, wc, C_out, Pxz_out):  # pragma: no cover - compiled
    """Spreads of the predicted measurements (Benzerrouk 2014, eq. 58-59), R excluded.

    Inputs: ``m (B, n)``, the points ``Xt (n, B, S)`` placed on ``N(m, P)``, their
    measurements ``Zt (k, B, S)``, the predicted measurements ``zt (k, B)`` (``sum wm Z``,
    formed by the caller with the NumPy path's own product: large measurements, pseudo-ranges
    of 2e7 m, make ``z_hat`` and the innovation depend on the summation order at 4e-9 m) and
    ``wc (S,)``. Writes ``C_out (B, k, k)``, ``sum wc (Z - z_hat)(Z - z_hat)^T`` (exactly
    symmetric), and ``Pxz_out (B, n, k)``, ``sum wc (X - m)(Z - z_hat)^T``.
    """
    n, B, S = Xt.shape
    k = Zt.shape[0]
    dX = np.empty((n, S))
    dZ = np.empty((k, S))
    for b in range(B):
        for i in range(n):
            x, mi = Xt[i, b], m[b, i]
            for s in range(S):
                dX[i, s] = wc[s] * (x[s] - mi)
        for j in range(k):
            z, zj = Zt[j, b], zt[j, b]
            for s in range(S):
                dZ[j, s] = z[s] - zj
        Pb = Pxz_out[b]
        for i in range(n):
            for j in range(k):
                acc = 0.0
                for s in range(S):
                    acc += dX[i, s] * dZ[j, s]
                Pb[i, j] = acc
        Cb = C_out[b]
        for i in range(k):
            for j in range(i + 1):
                acc = 0.0
                for s in range(S):
                    acc += wc[s] * dZ[i, s] * dZ[j, s]
                Cb[i, j] = acc
                Cb[j, i] = acc
