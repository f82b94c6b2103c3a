"""Compiled (Numba) twin of the strapdown transition's ``f`` and ``F`` for one state per episode.

:func:`strapdown_pass` is :meth:`StrapdownTransition.f
<navgym.quadrotor.models.StrapdownTransition.f>` and ``F`` (the preintegrated IMU step and its
exact Jacobian, :mod:`navgym.quadrotor.models`' docstring) for ``x (B, 15)``, one episode per
loop iteration, in the operations and order of the NumPy forms (which stay the reference):

* ``[dv^b, dp^b] = d6 + J6 [b_a, b_g]``, ``C0 = C(e0)``, ``[dv_t, dp_t] = E_h C0 [dv^b, dp^b]``;
* ``v1 = v0 + a T + dv_t``, ``p1 = p0 + v0 T + a T^2 / 2 + dp_t`` with
  ``a = Gamma (p0 + v0 T / 2) + g - 2 Omega x v0``;
* ``A = C0 dR Exp(u)`` to second order (``u = -Phi b_g``), ``C1 = E A``, ``e1`` the Euler
  angles of ``C1`` (roll and yaw unwrapped near ``e0``);
* ``F`` as :meth:`~navgym.quadrotor.models.StrapdownTransition.F` writes it.

Why: the NumPy forms are about a hundred small passes over component-first ``(3, B)`` arrays,
which at training's batch sizes cost their per-call overhead (about 300 us of a 0.86 ms
QuadrotorNoiseScale-v2 step at 16 sub-envs); one compiled pass costs a few microseconds. Sigma
points ``(B, S, 15)`` keep the NumPy forms. ``tests/navgym/quadrotor/test_strapdown_kernel.py``
holds the twins equal to rounding.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["strapdown_pass"]

_TWO_PI = 2.0 * np.pi


@njit(cache=True, error_model="numpy")
def _wrap(a):  # pragma: no cover - compiled
    """``mod(a + pi, 2 pi) - pi`` (NumPy's floor modulo)."""
    r = np.mod(a + np.pi, _TWO_PI)
    return r - np.pi


@njit(cache=True, error_model="numpy")
def _cross(a0, a1, a2, b0, b1, b2):  # pragma: no cover - compiled
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True, error_model="numpy")
def _euler_rate(e1, e2, inverse, N):  # pragma: no cover - compiled
    """``N(e)`` or its inverse (pitch ``e1``, yaw ``e2``), as ``_euler_rate_soa``."""
    sp, cp = np.sin(e1), np.cos(e1)
    if abs(cp) < 1e-6:
        cp = np.copysign(1e-6, cp)
    sy, cy = np.sin(e2), np.cos(e2)
    for i in range(3):
        for j in range(3):
            N[i, j] = 0.0
    N[1, 1] = cy
    N[2, 2] = 1.0
    if not inverse:
        N[0, 0] = cy * cp
        N[0, 1] = -sy
        N[1, 0] = sy * cp
        N[2, 0] = -sp
    else:
        N[0, 0] = cy / cp
        N[0, 1] = sy / cp
        N[1, 0] = -sy
        tp = sp / cp
        N[2, 0] = cy * tp
        N[2, 1] = sy * tp


@njit(cache=True, error_model="numpy")
def strapdown_pass(
    x, dR, phi, d6, J6, gravity, gradient, earth_rate, pv_c, pv_G, pv_W, T, out, F
):  # pragma: no cover - compiled  # fmt: skip
    """``out (B, 15) = f(x)`` and ``F (B, 15, 15) = df/dx`` at ``x (B, 15)`` (module docstring).

    ``pv_c (6, 6)``, ``pv_G``, ``pv_W (3, 36)`` are the (p, v) block's constant part and its
    gradient and Earth-rate bases (``_pv_basis``).
    """
    B = x.shape[0]
    C0 = np.empty((3, 3))
    A = np.empty((3, 3))
    m1 = np.empty((3, 3))
    N0 = np.empty((3, 3))
    N1i = np.empty((3, 3))
    wN0 = np.empty((3, 3))
    M3 = np.empty((3, 3))
    inc = np.empty(6)
    y = np.empty((3, 2))
    for b in range(B):
        xb = x[b]
        for r in range(6):  # [dv^b, dp^b] = (J6 * x[9:15]).sum(-1) + d6
            s = 0.0
            for c in range(6):
                s += J6[b, r, c] * xb[9 + c]
            inc[r] = s + d6[b, r]
        sr, cr = np.sin(xb[6]), np.cos(xb[6])
        sp, cp = np.sin(xb[7]), np.cos(xb[7])
        sy, cy = np.sin(xb[8]), np.cos(xb[8])
        srsp, crsp = sr * sp, cr * sp
        C0[0, 0] = cp * cy
        C0[1, 0] = cp * sy
        C0[2, 0] = -sp
        C0[0, 1] = srsp * cy - cr * sy
        C0[1, 1] = srsp * sy + cr * cy
        C0[2, 1] = sr * cp
        C0[0, 2] = crsp * cy + sr * sy
        C0[1, 2] = crsp * sy - sr * cy
        C0[2, 2] = cr * cp
        om0, om1, om2 = earth_rate[b, 0], earth_rate[b, 1], earth_rate[b, 2]
        w0, w1, w2 = 0.5 * T * om0, 0.5 * T * om1, 0.5 * T * om2
        for j in range(2):  # y = C0 [dv^b, dp^b]; y -= w_h x y
            for i in range(3):
                y[i, j] = C0[i, 0] * inc[3 * j] + C0[i, 1] * inc[3 * j + 1] + C0[i, 2] * inc[3 * j + 2]
            c0, c1, c2 = _cross(w0, w1, w2, y[0, j], y[1, j], y[2, j])
            y[0, j] -= c0
            y[1, j] -= c1
            y[2, j] -= c2
        k0, k1, k2 = _cross(om0, om1, om2, xb[3], xb[4], xb[5])
        for i in range(3):
            acc = xb[i] + (0.5 * T) * xb[3 + i]
            acc *= gradient[b, i]
            acc += gravity[b, i]
            acc -= 2.0 * (k0 if i == 0 else (k1 if i == 1 else k2))
            v1 = acc * T
            v1 += xb[3 + i]
            v1 += y[i, 0]
            out[b, 3 + i] = v1
            p1 = acc * (0.5 * T * T)
            p1 += xb[i]
            p1 += T * xb[3 + i]
            p1 += y[i, 1]
            out[b, i] = p1
        u0 = -(phi[b, 0, 0] * xb[12] + phi[b, 0, 1] * xb[13] + phi[b, 0, 2] * xb[14])
        u1 = -(phi[b, 1, 0] * xb[12] + phi[b, 1, 1] * xb[13] + phi[b, 1, 2] * xb[14])
        u2 = -(phi[b, 2, 0] * xb[12] + phi[b, 2, 1] * xb[13] + phi[b, 2, 2] * xb[14])
        for i in range(3):  # A = C0 dR
            for j in range(3):
                A[i, j] = C0[i, 0] * dR[b, 0, j] + C0[i, 1] * dR[b, 1, j] + C0[i, 2] * dR[b, 2, j]
        for r in range(3):  # m1 = A [u x]: row r_i x u
            m1[r, 0] = A[r, 1] * u2 - A[r, 2] * u1
            m1[r, 1] = A[r, 2] * u0 - A[r, 0] * u2
            m1[r, 2] = A[r, 0] * u1 - A[r, 1] * u0
        for r in range(3):
            A[r, 0] += m1[r, 0]
            A[r, 1] += m1[r, 1]
            A[r, 2] += m1[r, 2]
        for r in range(3):  # A += 0.5 m1 [u x]
            A[r, 0] += 0.5 * (m1[r, 1] * u2 - m1[r, 2] * u1)
            A[r, 1] += 0.5 * (m1[r, 2] * u0 - m1[r, 0] * u2)
            A[r, 2] += 0.5 * (m1[r, 0] * u1 - m1[r, 1] * u0)
        v0_, v1_, v2_ = 2.0 * w0, 2.0 * w1, 2.0 * w2
        c20 = A[2, 0] - (v0_ * A[1, 0] - v1_ * A[0, 0])
        c21 = A[2, 1] - (v0_ * A[1, 1] - v1_ * A[0, 1])
        c22 = A[2, 2] - (v0_ * A[1, 2] - v1_ * A[0, 2])
        c10 = A[1, 0] - (v2_ * A[0, 0] - v0_ * A[2, 0])
        c00 = A[0, 0] - (v1_ * A[2, 0] - v2_ * A[1, 0])
        roll = np.arctan2(c21, c22)
        pitch = -np.arcsin(min(max(c20, -1.0), 1.0))
        yaw = np.arctan2(c10, c00)
        e1_0 = xb[6] + _wrap(roll - xb[6])
        e1_2 = xb[8] + _wrap(yaw - xb[8])
        out[b, 6] = e1_0
        out[b, 7] = pitch
        out[b, 8] = e1_2
        for i in range(9, 15):
            out[b, i] = xb[i]
        # ------------------------------------------------------------------ the Jacobian F
        Fb = F[b]
        for i in range(15):
            for j in range(15):
                Fb[i, j] = 0.0
        for r in range(6):  # (p, v) block: (gradient @ G + earth_rate @ W) + c
            for c in range(6):
                q = 6 * r + c
                g = gradient[b, 0] * pv_G[0, q] + gradient[b, 1] * pv_G[1, q] + gradient[b, 2] * pv_G[2, q]
                w = om0 * pv_W[0, q] + om1 * pv_W[1, q] + om2 * pv_W[2, q]
                Fb[r, c] = (g + w) + pv_c[r, c]
        for i in range(9, 15):
            Fb[i, i] = 1.0
        _euler_rate(xb[7], xb[8], False, N0)
        for c in range(3):  # wN0 = w_h x N0 (columns)
            wN0[0, c], wN0[1, c], wN0[2, c] = _cross(w0, w1, w2, N0[0, c], N0[1, c], N0[2, c])
        for c in range(3):  # d(p, v)/de = -[(dp_t, dv_t) x] (N0 - wN0)
            n0, n1, n2 = N0[0, c] - wN0[0, c], N0[1, c] - wN0[1, c], N0[2, c] - wN0[2, c]
            a0, a1, a2 = _cross(y[0, 1], y[1, 1], y[2, 1], n0, n1, n2)
            Fb[0, 6 + c], Fb[1, 6 + c], Fb[2, 6 + c] = -a0, -a1, -a2
            a0, a1, a2 = _cross(y[0, 0], y[1, 0], y[2, 0], n0, n1, n2)
            Fb[3, 6 + c], Fb[4, 6 + c], Fb[5, 6 + c] = -a0, -a1, -a2
        for c in range(3):  # C0h = C0 - w_h x C0 (columns), into M3
            a0, a1, a2 = _cross(w0, w1, w2, C0[0, c], C0[1, c], C0[2, c])
            M3[0, c], M3[1, c], M3[2, c] = C0[0, c] - a0, C0[1, c] - a1, C0[2, c] - a2
        for i in range(3):  # d(v, p)/db = C0h J6 (v rows from J6's first three, p from the last)
            for c in range(6):
                Fb[3 + i, 9 + c] = M3[i, 0] * J6[b, 0, c] + M3[i, 1] * J6[b, 1, c] + M3[i, 2] * J6[b, 2, c]
                Fb[i, 9 + c] = M3[i, 0] * J6[b, 3, c] + M3[i, 1] * J6[b, 4, c] + M3[i, 2] * J6[b, 5, c]
        _euler_rate(pitch, e1_2, True, N1i)
        for i in range(3):  # de/de = N1^-1 (N0 - 2 wN0)
            for c in range(3):
                Fb[6 + i, 6 + c] = (
                    N1i[i, 0] * (N0[0, c] - 2.0 * wN0[0, c])
                    + N1i[i, 1] * (N0[1, c] - 2.0 * wN0[1, c])
                    + N1i[i, 2] * (N0[2, c] - 2.0 * wN0[2, c])
                )
        for c in range(3):  # C1 = A - (2 w_h) x A (columns), into m1
            a0, a1, a2 = _cross(v0_, v1_, v2_, A[0, c], A[1, c], A[2, c])
            m1[0, c], m1[1, c], m1[2, c] = A[0, c] - a0, A[1, c] - a1, A[2, c] - a2
        for c in range(3):  # M3 = phi - 0.5 u x phi (columns)
            a0, a1, a2 = _cross(u0, u1, u2, phi[b, 0, c], phi[b, 1, c], phi[b, 2, c])
            M3[0, c] = phi[b, 0, c] - 0.5 * a0
            M3[1, c] = phi[b, 1, c] - 0.5 * a1
            M3[2, c] = phi[b, 2, c] - 0.5 * a2
        for i in range(3):  # C1Jphi = C1 M3, into A (no longer needed)
            for c in range(3):
                A[i, c] = m1[i, 0] * M3[0, c] + m1[i, 1] * M3[1, c] + m1[i, 2] * M3[2, c]
        for i in range(3):  # de/db_g = -N1^-1 C1 J Phi
            for c in range(3):
                Fb[6 + i, 12 + c] = -(N1i[i, 0] * A[0, c] + N1i[i, 1] * A[1, c] + N1i[i, 2] * A[2, c])
