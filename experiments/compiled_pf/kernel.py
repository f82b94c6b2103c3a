"""A compiled bootstrap PF step for the particle benchmark's problem: what the NumPy contract costs.

``filters/`` is NumPy/SciPy only (DESIGN.md), and on the project's 2-core machines its bootstrap
filter's own NumPy passes exceed the 12.8 ms per step that 20 M particle-steps/s allows at
B x N = 256 x 1000 once it resamples every step (``navgym bench particles``, "filter alone"
rows). This module measures the other side of that trade: the same step, for the same problem
(:class:`benchmarks.particles.PseudorangePF`, float32 particles in a ``(B, n, N)`` buffer),
with the particle loops compiled by Numba. It is a study, used by no environment and by no
library code; ``tests/experiments/test_compiled_pf.py`` holds it equal to
:mod:`filters.particle.bootstrap` on the same draws.

One step (Touil & Ghadi 2012, eq. 15-17; the diagnostics of :class:`filters.core.types.UpdateInfo`):

1. **Predict** ``x_i = F x_i + G e_i`` with the normals ``e`` drawn exactly as the model's
   ``sample_noise`` draws them (:func:`filters.core.normal.standard_normal_block`); ``F`` is
   the model's constant-velocity and clock-drift structure (``p += v dt``, ``b += d dt``),
   written out, ``G`` the model's matrix.
2. **Weigh**, per filter in one compiled pass over its particles (:func:`_predict_weigh`): the
   reduced pseudo-ranges ``h_j(x_i)``, their prior-weighted mean ``z_hat`` and covariance
   ``P_zz`` and each particle's Gaussian quadratic form ``sum_j (z_j - h_j(x_i))^2 / R_jj``.
   The pass also forms the unnormalized posterior log-weights; their maximum and ``exp``
   are NumPy (Numba has no vector ``exp`` without Intel's SVML), the normalization and ESS
   one more compiled pass (:func:`_normalize`), ``S = P_zz + R`` and NIS NumPy on ``(B, 8, 8)``.
3. **Resample** (systematic, every step, or never): the offspring counts exactly as
   :func:`filters.core.resampling.systematic_ancestors` computes them, and the gather along
   each filter's particle rows (:func:`_systematic_gather`).

Reductions use ``fastmath`` reassociation (so they vectorise) and float32 accumulation for
``P_zz`` as the NumPy filter's float32 product does; results agree with the NumPy filter to
float32 rounding, not bit for bit. No masks: the benchmark's 8 satellites are always in view.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from benchmarks.particles import PseudorangePF, reduced_range
from filters.core.linalg import LOG_2PI, spd_inverse
from filters.core.normal import standard_normal_block
from filters.core.resampling import exp_weights, uniform

__all__ = ["CompiledStep", "compiled_step"]

_FAST = {"reassoc", "contract", "nsz"}  # no nnan/ninf: non-finite particles must propagate


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _predict_weigh(
    xT, e, dt, G, m2s, s2, s1, z, log_w, ew0, const, inv_var, xp, zbar, Pzz, post, xsum
):  # pragma: no cover - compiled
    """Steps 1-2 of the module docstring for every filter ``b`` (outputs ``xp`` .. ``xsum``).

    ``ew0 = exp(log_w)`` is normalized here, as the filter's prior weights are:
    ``w0 = ew0 / sum ew0`` and ``log w0 = log_w - log sum ew0``. ``post = log w0 - 0.5 sum_j
    (z_j - h_j)^2 / R_jj - const`` are the unnormalized posterior log-weights (``const = 0.5
    (log det R + m log 2 pi)``); ``xsum[b]`` is the sum of the predicted particles, finite
    exactly when every particle is (the health check).
    """
    B, n, N = xT.shape
    m = m2s.shape[1]
    h = np.empty((m, N), dtype=np.float32)
    w0 = np.empty(N)
    w32 = np.empty(N, dtype=np.float32)
    r = np.empty(m, dtype=np.float32)
    f = np.float32(dt)
    for b in range(B):
        x, y, eb, wb = xT[b], xp[b], e[b], w0
        total = 0.0
        for i in range(N):
            total += ew0[b, i]
        inv_total = 1.0 / total
        for i in range(N):
            w0[i] = ew0[b, i] * inv_total
        log_total = np.log(total)
        xsum[b] = 0.0
        # x <- F x + G e (constant velocity and clock drift), one output row at a time so that
        # every inner loop has a single store stream and vectorises
        for k in range(8):
            g0, g1, g2, g3 = G[k, 0], G[k, 1], G[k, 2], G[k, 3]
            yk, xk = y[k], x[k]
            rate = k + 3 if k < 3 else (7 if k == 6 else -1)
            e0, e1, e2, e3 = eb[0], eb[1], eb[2], eb[3]
            acc = 0.0
            if rate >= 0:
                xr = x[rate]
                for i in range(N):
                    v = (xk[i] + f * xr[i]) + (g0 * e0[i] + g1 * e1[i] + g2 * e2[i] + g3 * e3[i])
                    yk[i] = v
                    acc += v
            else:
                for i in range(N):
                    v = xk[i] + (g0 * e0[i] + g1 * e1[i] + g2 * e2[i] + g3 * e3[i])
                    yk[i] = v
                    acc += v
            xsum[b] += acc
        for j in range(m):  # h_j = |p - s_j| - |s_j| + b (reduced_range)
            sx, sy, sz, a, c = m2s[0, j], m2s[1, j], m2s[2, j], s2[j], s1[j]
            hj = h[j]
            for i in range(N):
                hj[i] = reduced_range(sx, sy, sz, a, c, y[0, i], y[1, i], y[2, i]) + y[6, i]
        for i in range(N):
            w32[i] = wb[i]
        for j in range(m):  # z_hat (float64 sums) and centred predictions
            acc = 0.0
            hj = h[j]
            for i in range(N):
                acc += wb[i] * hj[i]
            zbar[b, j] = acc
            zj = np.float32(acc)
            for i in range(N):
                hj[i] -= zj
            r[j] = np.float32(z[b, j] - acc)  # innovation z - z_hat
        for j in range(m):  # P_zz (float32 sums, as the NumPy filter's float32 product)
            for k in range(j + 1):
                acc32 = np.float32(0.0)
                hj, hk = h[j], h[k]
                for i in range(N):
                    acc32 += w32[i] * hj[i] * hk[i]
                Pzz[b, j, k] = acc32
                Pzz[b, k, j] = acc32
        pb, lb = post[b], log_w[b]  # the Gaussian quadratic form with z - h = (z - z_hat) - centred h
        for i in range(N):
            pb[i] = 0.0
        for j in range(m):
            rj, ivj, hj = r[j], inv_var[j], h[j]
            for i in range(N):
                d = rj - hj[i]
                pb[i] += d * d * ivj
        for i in range(N):
            pb[i] = (lb[i] - log_total) - 0.5 * pb[i] - const


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _normalize(post, ew, log_norm, total, ess):  # pragma: no cover - compiled
    """``post -= log_norm``, ``ew /= total`` and ``ess = 1 / sum ew^2`` in one pass per filter."""
    B, N = post.shape
    for b in range(B):
        pb, eb, ln, inv = post[b], ew[b], log_norm[b], 1.0 / total[b]
        acc = 0.0
        for i in range(N):
            pb[i] -= ln
            v = eb[i] * inv
            eb[i] = v
            acc += v * v
        ess[b] = 1.0 / acc


@njit(cache=True, error_model="numpy")
def _systematic_gather(w, U, xp, out, ancestors):  # pragma: no cover - compiled
    """Systematic resampling of every filter (step 3): counts as in ``systematic_ancestors``.

    The number of points ``(k + U) / N`` at or below the normalized cumulative weight ``c_i``
    is ``l_i = clip(floor(N c_i - U) + 1, 0, N)`` (``l_{N-1} = N``), with ``c`` the running
    sum divided by the total as NumPy's ``cumsum`` forms it; point ``k`` goes to the first
    ``i`` with ``l_i > k``, i.e. ``a_k = #{i : l_i <= k}``: a histogram of the ``l_i`` and its
    running sum, without a data-dependent branch.
    """
    B, n, N = xp.shape
    hist = np.empty(N + 1, dtype=np.int64)
    for b in range(B):
        wb = w[b]
        total = 0.0
        for i in range(N):
            total += wb[i]
        hist[:] = 0
        c = 0.0
        u = U[b]
        for i in range(N - 1):  # l_{N-1} = N is never <= k < N
            c += wb[i]
            t = np.floor(c / total * N - u) + 1.0
            hist[int(min(max(t, 0.0), float(N)))] += 1
        a = ancestors[b]
        count = 0
        for k in range(N):
            count += hist[k]
            a[k] = count
        for comp in range(n):
            src, dst = xp[b, comp], out[b, comp]
            for k in range(N):
                dst[k] = src[a[k]]


class CompiledStep(NamedTuple):
    """One compiled step's outputs (the fields of ``UpdateInfo`` the benchmark step computes)."""

    xT: np.ndarray  # (B, n, N) particles after the step (resampled when asked)
    log_w: np.ndarray  # (B, N) log-weights after the step
    predicted: np.ndarray  # (B, n, N) particles after the prediction
    post_log_w: np.ndarray  # (B, N) posterior log-weights before resampling
    innovation: np.ndarray  # (B, m) z - z_hat
    S: np.ndarray  # (B, m, m) P_zz + R
    nis: np.ndarray  # (B,)
    log_likelihood: np.ndarray  # (B,) log sum_i w0_i p(z | x_i)
    ess: np.ndarray  # (B,) after the Bayes correction
    healthy: np.ndarray  # (B,) finite particles, weights and z_hat, S positive definite
    ancestors: np.ndarray | None  # (B, N) when resampled


def compiled_step(
    xT: np.ndarray,
    log_w: np.ndarray,
    z: np.ndarray,
    model: PseudorangePF,
    rng: np.random.Generator,
    resample: bool,
) -> CompiledStep:
    """Bootstrap predict + update (+ systematic resampling of every filter) for ``model``.

    Args:
        xT: float32 particles as a C-contiguous ``(B, 8, N)`` buffer.
        log_w: normalized log-weights ``(B, N)``.
        z: reduced pseudo-ranges ``(B, 8)``.
        model: the benchmark's float32 ``PseudorangePF`` (its ``F``, ``G``, satellites, ``R``).
        rng: one Generator; draws the normals as ``model.sample_noise`` does, then (when
            resampling) one uniform per filter as the filter's systematic resampling does.
        resample: systematic resampling of every filter after the update.

    Returns:
        :class:`CompiledStep`.
    """
    if model.dtype != np.float32 or xT.dtype != np.float32 or not xT.flags.c_contiguous:
        raise ValueError("compiled_step needs a float32 model and a C-contiguous float32 (B, 8, N) buffer")
    B, n, N = xT.shape
    if n != 8 or log_w.shape != (B, N) or z.shape != (B, 8):
        shapes = f"{xT.shape}, {log_w.shape}, {z.shape}"
        raise ValueError(f"expected xT (B, 8, N), log_w (B, N), z (B, 8); got {shapes}")
    e = standard_normal_block(rng, (B, 4, N), np.float32)[0]
    ew0 = exp_weights(np.asarray(log_w, dtype=np.float64))  # normalized in the kernel
    var = np.diag(model.R)
    const = 0.5 * (np.log(var).sum() + 8 * LOG_2PI)
    xp = np.empty_like(xT)
    zbar, Pzz, post = np.empty((B, 8)), np.empty((B, 8, 8), dtype=np.float32), np.empty((B, N))
    xsum = np.empty(B)
    m2s, sats_sq, sat_range = model.range_coefficients
    inv_var = (1.0 / var).astype(np.float32)
    _predict_weigh(
        xT, e, model.dt, model.G, m2s, sats_sq, sat_range, z, log_w, ew0, const, inv_var,
        xp, zbar, Pzz, post, xsum,
    )  # fmt: skip
    mx = post.max(axis=1)
    ew = post - mx[:, None]
    exp_weights(ew, out=ew)
    total = ew.sum(axis=1)
    log_norm = mx + np.log(total)
    ess = np.empty(B)
    _normalize(post, ew, log_norm, total, ess)
    v = z - zbar
    S = Pzz.astype(np.float64) + model.R
    S_inv, _, ok = spd_inverse(S)
    nis = np.einsum("bi,bij,bj->b", v, S_inv, v)
    healthy = np.isfinite(xsum) & np.isfinite(log_norm) & np.isfinite(zbar).all(axis=1) & ok
    if not resample:
        return CompiledStep(xp, post, xp, post, v, S, nis, log_norm, ess, healthy, None)
    U = uniform(rng, B, (1,))[:, 0]  # U on (0, 1], as the filter's systematic resampling draws it
    out = np.empty_like(xp)
    ancestors = np.empty((B, N), dtype=np.int64)
    _systematic_gather(ew, U, xp, out, ancestors)
    log_w_new = np.full((B, N), -np.log(N))
    return CompiledStep(out, log_w_new, xp, post, v, S, nis, log_norm, ess, healthy, ancestors)
