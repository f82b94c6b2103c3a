"""Compiled (Numba) twin of :func:`navgym.quadrotor.models.preintegrate_components`.

:func:`preintegrate_rows` integrates ``n_sub`` IMU samples per step (Benzerrouk 2014, eq. 4, 6,
7; Forster et al. 2017, eq. 33-44) with the recursion and order of the NumPy form (which stays
the reference): per sample ``j``, ``H = Exp(w_j delta / 2)`` (Rodrigues), ``R_mid = R_j H``,
``a = R_mid f_j``, ``psi_mid = psi + (R + R_mid) delta / 4``, ``G = [a x] psi_mid``;
``dp += dv delta + a delta^2 / 2``, ``jpa += jva delta + R_mid delta^2 / 2``,
``jpg += jvg delta + G delta^2 / 2``, ``dv += a delta``, ``jva += R_mid delta``,
``jvg += G delta``, ``R_{j+1} = R_mid H``, ``psi_{j+1} = psi_mid + (R_mid + R_{j+1}) delta / 4``;
at the end ``phi = R^T psi``.

Why: the NumPy form runs about 25 passes over ``(3, 3, N)`` slabs per sample, and the Pedestrian
and Replay platforms preintegrate at reset (the Pedestrian's 100 samples a stride); one compiled
pass keeps each step's matrices in registers. The Quadrotor's reset has its own fused kernel
(:mod:`navgym.quadrotor.imu_kernel`).

Two passes around NumPy's transcendentals, so that the results are the NumPy form's **bit for
bit**: :func:`rodrigues_arguments_pass` forms each sample's angle ``x = |w delta / 2|`` and the
arguments of its two ``np.sinc`` (``pi (x / pi)`` and ``pi (x / 2 pi)``, the machine epsilon for
0, as ``np.sinc`` forms them); the caller takes their ``sin`` and ``cos(x)`` with NumPy's SIMD
functions (Numba's scalar ``libm`` calls give other last bits, and cost about half of a scalar
pass); :func:`preintegrate_rows_pass` runs the recursion on them with the reference's operations in
its order (no fast-math contraction). The samples are read in the row layout ``(N, n_sub, 3)`` of
:func:`navgym.quadrotor.models.preintegrate`, each step's samples contiguous.
``tests/navgym/quadrotor/test_strapdown_kernel.py`` holds the twins equal with ``array_equal``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["preintegrate_rows", "preintegrate_rows_pass", "rodrigues_arguments_pass"]

_EPS = float(np.finfo(np.float64).eps)  # np.sinc's stand-in for a zero argument


@njit(cache=True, error_model="numpy")
def rodrigues_arguments_pass(w, h, x, y1, y2):  # pragma: no cover - compiled
    """Per sample of ``w (N, n_sub, 3)``: ``x = |w h|``, ``y1 = pi (x / pi)``, ``y2 = pi (x / 2 pi)``.

    The outputs are ``(N, n_sub)``; ``y1``, ``y2`` are the arguments ``np.sinc(x / pi)`` and
    ``np.sinc(x / (2 pi))`` take the sine of (a zero replaced by the machine epsilon, as
    ``np.sinc`` does).
    """
    N, n_sub, _ = w.shape
    for n in range(N):
        for s in range(n_sub):
            t0, t1, t2 = w[n, s, 0] * h, w[n, s, 1] * h, w[n, s, 2] * h
            xs = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            x[n, s] = xs
            u = np.pi * (xs / np.pi)
            y1[n, s] = u if u != 0.0 else _EPS
            u = np.pi * (xs / (2.0 * np.pi))
            y2[n, s] = u if u != 0.0 else _EPS


@njit(cache=True, error_model="numpy")
def preintegrate_rows_pass(
    w, f, delta, y1, s1, y2, s2, cx, dR, phi, dv, dp, jva, jvg, jpa, jpg
):  # pragma: no cover - compiled
    """The recursion (module docstring) of samples ``w, f (N, n_sub, 3)``; outputs ``(N, 3, 3)``, ``(N, 3)``.

    ``y1, s1, y2, s2, cx (N, n_sub)``: the sinc arguments of :func:`rodrigues_arguments_pass`,
    their sines and ``cos(x)``: ``H = (b t) t^T + c I + a [t x]`` with ``t = w delta / 2``,
    ``a = s1 / y1``, ``b = 0.5 (s2 / y2)^2``, ``c = cx``.
    """
    N, n_sub, _ = w.shape
    h = 0.5 * delta
    q = 0.25 * delta
    d2 = 0.5 * delta * delta
    H = np.empty((3, 3))
    R = np.empty((3, 3))
    Rm = np.empty((3, 3))
    Rn = np.empty((3, 3))
    psi = np.empty((3, 3))
    pm = np.empty((3, 3))
    G = np.empty((3, 3))
    a = np.empty(3)
    v = np.empty(3)
    p = np.empty(3)
    th = np.empty(3)
    Jva = np.empty((3, 3))
    Jvg = np.empty((3, 3))
    Jpa = np.empty((3, 3))
    Jpg = np.empty((3, 3))
    for n in range(N):
        for i in range(3):
            v[i] = 0.0
            p[i] = 0.0
            for j in range(3):
                R[i, j] = 1.0 if i == j else 0.0
                psi[i, j] = 0.0
                Jva[i, j] = 0.0
                Jvg[i, j] = 0.0
                Jpa[i, j] = 0.0
                Jpg[i, j] = 0.0
        for s in range(n_sub):
            # H = Exp(t) (navgym.ins.attitude.rotation_matrix_components)
            ca = s1[n, s] / y1[n, s]
            sb = s2[n, s] / y2[n, s]
            cb = 0.5 * (sb * sb)
            c = cx[n, s]
            for i in range(3):
                th[i] = w[n, s, i] * h
            for i in range(3):
                for j in range(3):
                    H[i, j] = (cb * th[i]) * th[j]
            H[0, 0] += c
            H[1, 1] += c
            H[2, 2] += c
            H[0, 1] -= ca * th[2]
            H[1, 0] += ca * th[2]
            H[0, 2] += ca * th[1]
            H[2, 0] -= ca * th[1]
            H[1, 2] -= ca * th[0]
            H[2, 1] += ca * th[0]
            for i in range(3):
                for j in range(3):
                    Rm[i, j] = R[i, 0] * H[0, j] + R[i, 1] * H[1, j] + R[i, 2] * H[2, j]
            for i in range(3):
                a[i] = Rm[i, 0] * f[n, s, 0] + Rm[i, 1] * f[n, s, 1] + Rm[i, 2] * f[n, s, 2]
            for i in range(3):
                for j in range(3):
                    pm[i, j] = psi[i, j] + (R[i, j] + Rm[i, j]) * q
            for col in range(3):  # G = [a x] psi_mid, column by column
                G[0, col] = a[1] * pm[2, col] - a[2] * pm[1, col]
                G[1, col] = a[2] * pm[0, col] - a[0] * pm[2, col]
                G[2, col] = a[0] * pm[1, col] - a[1] * pm[0, col]
            for i in range(3):
                p[i] += v[i] * delta + a[i] * d2
                for j in range(3):
                    Jpa[i, j] += Jva[i, j] * delta + Rm[i, j] * d2
                    Jpg[i, j] += Jvg[i, j] * delta + G[i, j] * d2
                v[i] += a[i] * delta
                for j in range(3):
                    Jva[i, j] += Rm[i, j] * delta
                    Jvg[i, j] += G[i, j] * delta
            for i in range(3):
                for j in range(3):
                    Rn[i, j] = Rm[i, 0] * H[0, j] + Rm[i, 1] * H[1, j] + Rm[i, 2] * H[2, j]
            for i in range(3):
                for j in range(3):
                    psi[i, j] = pm[i, j] + (Rm[i, j] + Rn[i, j]) * q
                    R[i, j] = Rn[i, j]
        for i in range(3):
            dv[n, i] = v[i]
            dp[n, i] = p[i]
            for j in range(3):
                dR[n, i, j] = R[i, j]
                phi[n, i, j] = R[0, i] * psi[0, j] + R[1, i] * psi[1, j] + R[2, i] * psi[2, j]
                jva[n, i, j] = Jva[i, j]
                jvg[n, i, j] = Jvg[i, j]
                jpa[n, i, j] = Jpa[i, j]
                jpg[n, i, j] = Jpg[i, j]


def preintegrate_rows(w: np.ndarray, f: np.ndarray, delta: float) -> tuple[np.ndarray, ...]:
    """The two passes on samples ``w, f (N, n_sub, 3)``: ``dR, phi, dv, dp, jva, jvg, jpa, jpg``, N first."""
    f64 = np.float64
    w, f = np.ascontiguousarray(w, f64), np.ascontiguousarray(f, f64)
    N, n_sub, _ = w.shape
    x, y1, y2 = np.empty((N, n_sub)), np.empty((N, n_sub)), np.empty((N, n_sub))
    rodrigues_arguments_pass(w, 0.5 * delta, x, y1, y2)
    out = [np.empty((N, 3, 3)), np.empty((N, 3, 3)), np.empty((N, 3)), np.empty((N, 3))]
    out += [np.empty((N, 3, 3)) for _ in range(4)]
    preintegrate_rows_pass(w, f, float(delta), y1, np.sin(y1), y2, np.sin(y2), np.cos(x), *out)
    return tuple(out)
