"""Compiled (Numba) kernels of the bootstrap particle filter's hot loops, and when they apply.

Each kernel is the twin of NumPy code in :mod:`filters.particle.bootstrap` and
:mod:`filters.core.resampling`, which stays the reference; :func:`filters.particle.bootstrap.update`
and :func:`~filters.particle.bootstrap.resample` choose the kernel internally where the layout,
dtype and sizes allow it, and the NumPy path otherwise or under the switch of
:mod:`filters.core.compiled` (``NAVGYM_NUMPY_ONLY=1`` or ``with numpy_only():``).
``tests/filters/particle/test_kernels.py`` holds the two paths equal on the same draws.

* :func:`weigh_pass` (the Bayes correction, Touil & Ghadi 2012, eq. 16; Carvalho et al. 1997,
  eq. 3 and 6) for a component-major cloud (the ``(B, N, n)`` view of a C-contiguous
  ``(B, n, N)`` buffer) whose predictions ``h(x)`` come back component-major too, float32 or
  float64, with a diagonal ``R`` and the Gaussian likelihood: per filter, one pass over the
  particles for the finiteness check and ``z_hat = sum_i w0_i h(x_i)``, one for the centred
  predictions, their spread ``P_zz`` and the quadratic forms, giving the unnormalized
  posterior log-weights and their maximum. The ``exp`` stays NumPy's (its SIMD kernel; Numba
  has no vector ``exp`` without Intel's SVML), then :func:`normalize_pass` forms the
  normalizer, the normalized log and linear weights and the ESS in one more pass. The rare
  paths (a non-finite particle or prediction, every weight vanished) are left to NumPy: the
  kernel reports them and the caller reruns the NumPy code.
* :func:`systematic_pass`: systematic resampling (Carpenter et al. 1999) of a component-major
  cloud, the offspring bounds exactly as :func:`filters.core.resampling.systematic_ancestors`
  forms them (the same operations in the same order, no fast-math: the same ancestors for the
  same weights and uniforms) and the gather along each filter's particle rows.

Rounding: the reductions (``z_hat``, ``P_zz``, sums of weights) are compiled with
reassociation so that they vectorise, as BLAS products reassociate; results agree with the
NumPy path to the particles' rounding, not bit for bit. Because systematic resampling is
discontinuous in the weights, a rounding-level weight difference can move an ancestor across a
systematic point, so resampled clouds of the two paths may differ in a few particles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.layout import is_component_major

__all__ = ["component_major_buffer", "normalize_pass", "systematic_pass", "weigh_pass"]

# no nnan/ninf: non-finite values must propagate to the health checks
_FAST = {"reassoc", "contract", "nsz"}


def component_major_buffer(a: np.ndarray, dtype: np.dtype) -> np.ndarray | None:
    """The C-contiguous ``(B, k, N)`` buffer behind ``a (B, N, k)``, or None if there is none.

    None when ``a`` is not the transposed view of such a buffer or is not of ``dtype``
    (float32 or float64): then the NumPy path runs.
    """
    if a.dtype != dtype or dtype not in (np.float32, np.float64):
        return None
    if is_component_major(a) or (a.shape[1] == 1 and a.transpose(0, 2, 1).flags.c_contiguous):
        return a.transpose(0, 2, 1)
    return None


@njit(cache=True, error_model="numpy", fastmath=_FAST, nogil=True)
def weigh_pass(
    xT, hT, w0, prior, z, inv_var, var, used, const, floor, post, ll, zbar, Pzz, S, nis, mx, ok
):  # pragma: no cover
    """Unnormalized posterior log-weights, ``z_hat`` and ``P_zz`` of every filter ``b``.

    Inputs: particles ``xT (B, n, N)`` and predictions ``hT (B, m, N)`` (same dtype), the
    normalized prior weights ``w0 (B, N)`` and log-weights ``prior (B, N)`` (float64), the
    measurements ``z (B, m)`` (masked entries 0), ``inv_var (B, m)`` the inverse noise
    variances (0 on masked rows), ``const (B,)`` = ``0.5 (log det R + n_meas log 2 pi)``, and
    ``floor``, below which the weights in the particles' precision are set to 0
    (:func:`filters.core.layout.weights_in`).

    ``var (B, m)`` the noise variances and ``used (B, m)`` the 0/1 row weights of the mask.

    Outputs: ``ll (B, N)`` the particle log-likelihoods ``-0.5 sum_j inv_var_j (z_j -
    h_j(x_i))^2 - const`` (not written when ``ll`` has no columns), ``post = prior + ll``,
    ``mx (B,)`` its maximum, ``zbar (B, m)`` float64, ``Pzz (B, m, m)`` in the particles'
    dtype, ``S = P_zz + R`` with masked rows neutralized (unit variance, no cross terms, as
    :func:`filters.core.conditioning.masked_covariance`), the NIS ``v^T S^-1 v`` of the masked
    innovation ``v`` (from the Cholesky factor of ``S``) and ``ok (B,)``: False where a
    particle or ``z_hat`` is not finite, ``S`` is not positive definite or every posterior
    weight vanished (the caller's NumPy path handles those filters; the other outputs of
    such a filter are unspecified).
    """
    B, n, N = xT.shape
    m = hT.shape[1]
    dt = hT.dtype
    wd = np.empty(N, dtype=dt)
    d = np.empty((m, N), dtype=dt)
    quad = np.empty(N, dtype=dt)
    row = np.empty((3, m), dtype=dt)  # z_hat, innovation and inverse variance in the cloud's dtype
    zero = np.zeros(1, dtype=dt)[0]
    L = np.empty((m, m))
    ev = np.empty(m)
    write_ll = ll.shape[1] == N
    for b in range(B):
        xs = 0.0
        for k in range(n):
            xk = xT[b, k]
            acc = 0.0
            for i in range(N):
                acc += xk[i]
            xs += acc
        wb = w0[b]
        for i in range(N):
            wd[i] = wb[i]
            if wd[i] < floor:
                wd[i] = zero
        zfinite = True
        for j in range(m):
            hj = hT[b, j]
            acc = 0.0
            for i in range(N):
                acc += wd[i] * hj[i]
            zbar[b, j] = acc
            zfinite = zfinite and np.isfinite(acc)
        if not (np.isfinite(xs) and zfinite):
            ok[b] = False
            continue
        for i in range(N):
            quad[i] = 0.0
        for j in range(m):
            hj, dj = hT[b, j], d[j]
            row[0, j] = zbar[b, j]
            row[1, j] = z[b, j] - zbar[b, j]  # the innovation z_j - z_hat_j
            row[2, j] = inv_var[b, j]
            zj, rj, ivj = row[0, j], row[1, j], row[2, j]
            for i in range(N):
                c = hj[i] - zj
                dj[i] = c
                e = rj - c
                quad[i] += ivj * (e * e)
        for j in range(m):
            dj = d[j]
            for k in range(j + 1):
                dk = d[k]
                acc32 = zero
                for i in range(N):
                    acc32 += wd[i] * dj[i] * dk[i]
                Pzz[b, j, k] = acc32
                Pzz[b, k, j] = acc32
                s = (np.float64(acc32) + (var[b, j] if j == k else 0.0)) * used[b, j] * used[b, k]
                if j == k:
                    s += 1.0 - used[b, j]
                S[b, j, k] = s
                S[b, k, j] = s
        spd = True
        q = 0.0
        for j in range(m):  # S = L L^T and NIS = |L^-1 v|^2
            for k in range(j + 1):
                acc = S[b, j, k]
                for t in range(k):
                    acc -= L[j, t] * L[k, t]
                if j == k:
                    if not (acc > 0.0 and np.isfinite(acc)):
                        spd = False
                        acc = 1.0
                    L[j, j] = np.sqrt(acc)
                else:
                    L[j, k] = acc / L[k, k]
            acc = (z[b, j] - zbar[b, j]) * used[b, j]
            for t in range(j):
                acc -= L[j, t] * ev[t]
            ev[j] = acc / L[j, j]
            q += ev[j] * ev[j]
        nis[b] = q
        pb, qb = post[b], prior[b]
        cb = const[b]
        top = -np.inf
        for i in range(N):
            li = -0.5 * quad[i] - cb
            if write_ll:
                ll[b, i] = li
            p = qb[i] + li
            pb[i] = p
            top = max(top, p)
        mx[b] = top
        ok[b] = np.isfinite(top) and spd


@njit(cache=True, error_model="numpy", fastmath=_FAST, nogil=True)
def normalize_pass(post, e, mx, log_norm, ess):  # pragma: no cover - compiled
    """``log_norm = mx + log sum e``, ``post -= log_norm``, ``e /= sum e``, ``ess = 1 / sum e^2``.

    ``e = exp(post - mx)`` on entry (Touil & Ghadi 2012, eq. 16 normalized in the log domain),
    one pass per filter.
    """
    B, N = post.shape
    for b in range(B):
        eb, pb = e[b], post[b]
        total = 0.0
        for i in range(N):
            total += eb[i]
        ln = mx[b] + np.log(total)
        log_norm[b] = ln
        inv = 1.0 / total
        acc = 0.0
        for i in range(N):
            pb[i] -= ln
            v = eb[i] * inv
            eb[i] = v
            acc += v * v
        ess[b] = 1.0 / acc


@njit(cache=True, error_model="numpy", nogil=True)
def systematic_pass(w, U, decision, xT, out, ancestors):  # pragma: no cover - compiled
    """Systematic resampling of the filters with ``decision[b]``, gathered into ``out``.

    The bounds ``l_i = clip(floor(N c_i - U) + 1, 0, N)`` with ``c`` the running sum divided by
    the total (as ``np.cumsum`` and the division of :func:`filters.core.resampling._cdf` form
    it; ``l_{N-1} = N``), and ancestor ``a_k = #{i : l_i <= k}`` from a histogram of the
    bounds and its running sum (:func:`filters.core.resampling._ancestors_from_bounds`).
    Filters without ``decision`` keep their particles (copied) and ``a = 0..N-1``.
    """
    B, n, N = xT.shape
    hist = np.empty(N + 1, dtype=np.int64)
    cum = np.empty(N)
    for b in range(B):
        a = ancestors[b]
        if not decision[b]:
            for k in range(N):
                a[k] = k
            for comp in range(n):
                src, dst = xT[b, comp], out[b, comp]
                for k in range(N):
                    dst[k] = src[k]
            continue
        wb = w[b]
        c = 0.0
        for i in range(N):
            c += wb[i]
            cum[i] = c
        total = cum[N - 1]
        hist[:] = 0
        u = U[b]
        for i in range(N - 1):  # l_{N-1} = N is never <= k < N
            t = np.floor(cum[i] / total * N - u) + 1.0
            hist[int(min(max(t, 0.0), float(N)))] += 1
        count = 0
        for k in range(N):
            count += hist[k]
            a[k] = count
        for comp in range(n):
            src, dst = xT[b, comp], out[b, comp]
            for k in range(N):
                dst[k] = src[a[k]]
