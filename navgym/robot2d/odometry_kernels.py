"""Compiled (Numba) twins of the odometry transition's ``f`` and ``F`` for one state per episode.

:func:`transition_pass` and :func:`jacobian_pass` are :meth:`OdometryTransition.f
<navgym.robot2d.models.OdometryTransition.f>` and ``F`` (eq. 77's exact arc, Benzerrouk 2014)
for ``x (B, 3)``, one episode per loop iteration: with ``th = v_c tan(alpha) dt / (2 L)``,
``d = v_c dt sin(th) / th`` and the point L's offset ``[a, b]`` from the rear axle,

    phi+ = phi + 2 th,
    p+ = p + R(phi) [d cos th - 2 a sin^2 th - 2 b sin th cos th,
                     d sin th + 2 a sin th cos th - 2 b sin^2 th],
    dp+/dphi = d [-sin, cos](phi + th) + offset'(phi + 2 th) - offset'(phi).

Why: the NumPy forms are 20-30 passes over ``(B,)`` arrays, which at training's batch sizes cost
their per-call overhead (about 100 us of a 0.55 ms Robot2dRowScale-v3 step at 16 sub-envs); one
compiled pass costs a microsecond or two. Sigma points (``(B, S, 3)``) keep the NumPy form.

:func:`cloud_transition_pass` is ``f`` of a component-major particle cloud ``(B, 3, N)`` (the
Resample task's "structure of arrays", float32 or float64) given ``cos phi`` and ``sin phi`` of
every particle: NumPy's SIMD ``cos`` and ``sin`` compute those (faster than scalar calls in a
loop), and the kernel does the rest, which NumPy spends some ten passes with float64 temporaries
on (about 2 ms of a Robot2dResample-v2 step at 256 x 1000 particles), in one pass, with NumPy's
operations, order and precisions.

``tests/navgym/robot2d/test_noise_kernel.py`` holds the twins equal to rounding.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["cloud_transition_pass", "jacobian_pass", "transition_pass"]


@njit(cache=True, error_model="numpy")
def _half_turn(v_c, tan_alpha, dt, L):  # pragma: no cover - compiled
    th = 0.5 * dt * v_c * tan_alpha / L
    d = v_c * dt * (np.sin(th) / th if th != 0.0 else 1.0)
    return th, d


@njit(cache=True, error_model="numpy")
def transition_pass(x, v_c, tan_alpha, dt, L, a, b, out):  # pragma: no cover - compiled
    """``out (B, 3) = f(x (B, 3))`` with each episode's ``v_c`` and ``tan(alpha)`` ``(B,)``."""
    for i in range(x.shape[0]):
        th, d = _half_turn(v_c[i], tan_alpha[i], dt, L)
        sn, cs = np.sin(th), np.cos(th)
        s2, sc2 = 2.0 * sn * sn, 2.0 * sn * cs
        bx = d * cs - a * s2 - b * sc2
        by = d * sn + a * sc2 - b * s2
        phi = x[i, 2]
        c0, s0 = np.cos(phi), np.sin(phi)
        out[i, 0] = x[i, 0] + c0 * bx - s0 * by
        out[i, 1] = x[i, 1] + s0 * bx + c0 * by
        out[i, 2] = phi + 2.0 * th


@njit(cache=True, error_model="numpy")
def jacobian_pass(x, v_c, tan_alpha, dt, L, a, b, J):  # pragma: no cover - compiled
    """``J (B, 3, 3) = df/dx`` at ``x (B, 3)``: the identity but for ``dp+/dphi``."""
    for i in range(x.shape[0]):
        th, d = _half_turn(v_c[i], tan_alpha[i], dt, L)
        phi = x[i, 2]
        mid = phi + th
        p2 = phi + 2.0 * th
        c2, s2 = np.cos(p2), np.sin(p2)
        c0, s0 = np.cos(phi), np.sin(phi)
        for r in range(3):
            for c in range(3):
                J[i, r, c] = 1.0 if r == c else 0.0
        J[i, 0, 2] = -d * np.sin(mid) + (-a * s2 - b * c2) - (-a * s0 - b * c0)
        J[i, 1, 2] = d * np.cos(mid) + (a * c2 - b * s2) - (a * c0 - b * s0)


@njit(cache=True, error_model="numpy", nogil=True)
def cloud_transition_pass(xT, c0, s0, bx, by, turn, outT):  # pragma: no cover - compiled
    """``outT (B, 3, N) = f(xT (B, 3, N))`` with ``c0, s0 (B, N)`` = cos, sin of ``xT[:, 2]``.

    ``bx, by (B,)`` the body-frame step and ``turn = 2 th (B,)`` (float64); each particle's
    values are computed in float64 from the cloud's precision and stored in it, as NumPy's
    ``x + c0 * bx - s0 * by`` with a float64 ``bx`` computes them.
    """
    B, _, N = xT.shape
    for b in range(B):
        bxb, byb, tb = bx[b], by[b], turn[b]
        x0, x1, x2 = xT[b, 0], xT[b, 1], xT[b, 2]
        o0, o1, o2 = outT[b, 0], outT[b, 1], outT[b, 2]
        cb, sb = c0[b], s0[b]
        for i in range(N):
            c = np.float64(cb[i])
            s = np.float64(sb[i])
            o0[i] = np.float64(x0[i]) + c * bxb - s * byb
            o1[i] = np.float64(x1[i]) + s * bxb + c * byb
            o2[i] = np.float64(x2[i]) + tb
