"""Compiled (Numba) twin of :func:`navgym.quadrotor.models.preintegrate_components`.

:func:`preintegrate_pass` integrates ``n_sub`` IMU samples per step (Benzerrouk 2014, eq. 4, 6,
7; Forster et al. 2017, eq. 33-44), one step per loop iteration, with the recursion and order of
the NumPy form (which stays the reference): per sample ``j``, ``H = Exp(w_j delta / 2)``
(Rodrigues), ``R_mid = R_j H``, ``a = R_mid f_j``, ``psi_mid = psi + (R + R_mid) delta / 4``,
``G = [a x] psi_mid``; ``dp += dv delta + a delta^2 / 2``, ``jpa += jva delta + R_mid delta^2 / 2``,
``jpg += jvg delta + G delta^2 / 2``, ``dv += a delta``, ``jva += R_mid delta``,
``jvg += G delta``, ``R_{j+1} = R_mid H``, ``psi_{j+1} = psi_mid + (R_mid + R_{j+1}) delta / 4``;
at the end ``phi = R^T psi``.

Why: the NumPy form runs about 25 passes over ``(3, 3, N)`` slabs per sample, and the Pedestrian
and Replay platforms preintegrate at reset (the Pedestrian's 100 samples a stride: about 120 ms
of a 225 ms reset of 16 walks, 72 % of a PedestrianNoiseScale-v3 training step at 16 sub-envs);
one compiled pass keeps each step's matrices in registers. The Quadrotor's reset has its own
fused kernel (:mod:`navgym.quadrotor.imu_kernel`). ``tests/navgym/quadrotor/test_strapdown_kernel.py``
holds the twins equal to rounding.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["preintegrate_pass"]


@njit(cache=True, error_model="numpy")
def _rotation(t0, t1, t2, H):  # pragma: no cover - compiled
    """``H = Exp(th)`` (Rodrigues, as :func:`navgym.ins.attitude.rotation_matrix_components`)."""
    x = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    y = x / np.pi
    a = np.sin(np.pi * y) / (np.pi * y) if y != 0.0 else 1.0
    y2 = x / (2.0 * np.pi)
    s = np.sin(np.pi * y2) / (np.pi * y2) if y2 != 0.0 else 1.0
    b = 0.5 * s * s
    c = np.cos(x)
    th = (t0, t1, t2)
    for i in range(3):
        for j in range(3):
            H[i, j] = (b * th[i]) * th[j]
    H[0, 0] += c
    H[1, 1] += c
    H[2, 2] += c
    H[0, 1] -= a * t2
    H[1, 0] += a * t2
    H[0, 2] += a * t1
    H[2, 0] -= a * t1
    H[1, 2] -= a * t0
    H[2, 1] += a * t0


@njit(cache=True, error_model="numpy")
def preintegrate_pass(w, f, delta, dR, phi, dv, dp, jva, jvg, jpa, jpg):  # pragma: no cover - compiled
    """Samples ``w, f (n_sub, 3, N)``; outputs ``(3, 3, N)`` and ``(3, N)`` as the NumPy form's."""
    n_sub, _, N = w.shape
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
            _rotation(w[s, 0, n] * h, w[s, 1, n] * h, w[s, 2, n] * h, H)
            for i in range(3):
                for j in range(3):
                    Rm[i, j] = R[i, 0] * H[0, j] + R[i, 1] * H[1, j] + R[i, 2] * H[2, j]
            for i in range(3):
                a[i] = Rm[i, 0] * f[s, 0, n] + Rm[i, 1] * f[s, 1, n] + Rm[i, 2] * f[s, 2, n]
            for i in range(3):
                for j in range(3):
                    pm[i, j] = psi[i, j] + (R[i, j] + Rm[i, j]) * q
            for c in range(3):  # G = [a x] psi_mid, column by column
                G[0, c] = a[1] * pm[2, c] - a[2] * pm[1, c]
                G[1, c] = a[2] * pm[0, c] - a[0] * pm[2, c]
                G[2, c] = a[0] * pm[1, c] - a[1] * pm[0, c]
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
            dv[i, n] = v[i]
            dp[i, n] = p[i]
            for j in range(3):
                dR[i, j, n] = R[i, j]
                phi[i, j, n] = R[0, i] * psi[0, j] + R[1, i] * psi[1, j] + R[2, i] * psi[2, j]
                jva[i, j, n] = Jva[i, j]
                jvg[i, j, n] = Jvg[i, j]
                jpa[i, j, n] = Jpa[i, j]
                jpg[i, j, n] = Jpg[i, j]
