"""Compiled reset kernel of the Quadrotor env: IMU samples along the flight, errors, preintegration.

At reset the Quadrotor env simulates, for every episode, ``T x n_sub`` IMU samples (600 x 20 at
the defaults) and preintegrates each step's ``n_sub`` samples (:mod:`navgym.envs.quadrotor`).
The NumPy path (:func:`navgym.platforms.quadrotor.quadrotor_imu`, then
:func:`navgym.envs.quadrotor.preintegrate_components`) runs some 200 array passes over all the
samples and cost about 13 ms per batched step at B = 1024 against 5 ms for the EKF that consumes
it. This module fuses the whole chain per sample in one loop compiled by Numba, so nothing of
size ``B T n_sub`` is ever stored but the normals; speed is the reason it is hand-written (the
NumPy functions stay the reference, and ``tests/navgym/envs/test_quadrotor_kernel.py`` holds the
two to rounding).

Per sample at time ``t`` (mid-point of the IMU interval) of episode ``b``:

1. **Flat outputs** (:func:`navgym.platforms.quadrotor._design`): the active phase
   ``i = max{i : t_start_i <= t}``, ``tau = (t - t_start_i) / d_i`` and the septic smootherstep
   ``s(tau)`` and its derivatives give ``v = dp s' / d``, ``a = dp s'' / d^2``,
   ``j = dp s''' / d^3``, ``psi = psi_0 + dpsi s`` and ``dpsi/dt = dpsi s' / d``.
2. **Attitude and body rate** by differential flatness
   (:func:`navgym.platforms.quadrotor._attitude_and_rate`, Mellinger & Kumar 2011): the columns
   ``x_b, y_b, z_b`` of ``C_b^{n0}`` and ``omega_{n0 b}^b``.
3. **Ideal IMU in the home tangent frame n0.** The mechanization solved for the sensed
   quantities (:mod:`navgym.ins.inverse_mechanization`),
   ``f_ib^b = C_n^b (dv^n/dt - g^n + (omega_en^n + 2 omega_ie^n) x v^n)`` and
   ``omega_ib^b = omega_nb^b + C_n^b (omega_ie^n + omega_en^n)``, with the quadrotor's
   ``v^n = M v^{n0}``, ``dv^n/dt = M a^{n0} - omega_en^n x v^n``, ``C_b^n = M C_b^{n0}`` and
   ``omega_nb^b = omega_{n0 b}^b - C_n^b omega_en^n`` (``M = C_e^n C_e^{n0 T}``), is the same as::

       f_ib^b     = C_b^{n0 T} (a^{n0} + 2 Omega x v^{n0} - gamma^{n0})
       omega_ib^b = omega_{n0 b}^b + C_b^{n0 T} Omega

   exactly: the transport rate cancels, and ``Omega = M^T omega_ie^n`` is the Earth rate in the
   home frame, a constant per episode. Only the normal gravity vector
   ``gamma^{n0} = M^T (0, 0, gamma(lat, h))`` still depends on where the quadrotor is; it is
   computed exactly in NumPy (:func:`navgym.platforms.quadrotor.home_gravity`) at the GNSS
   epochs and the step mid-points, and the kernel interpolates it quadratically through those
   three nodes per step. Over
   0.1 s the vector turns by about 1e-7 rad, so the interpolation error is below 1e-10 m/s^2
   (the test measures it), 1e-7 of a consumer accelerometer's bias.
4. **Errors** (seed 001 eq. 2 and 5): ``f = f_ib + b_a + n_a e``, ``omega = omega_ib + b_g +
   n_g e`` with the step's bias and the sample's normals ``e``.
5. **Preintegration** (Forster et al. 2017 eq. 33-44, as
   :func:`navgym.envs.quadrotor.preintegrate_components`): Rodrigues' formula (seed 001 eq. 4)
   per half sample, mid-sample attitude for the velocity (eq. 6), trapezoid for the position
   (eq. 7), and the bias Jacobians.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from navgym.ins.imu_grades import G0

__all__ = ["preintegrated_imu"]


@njit(cache=True)
def _smooth(tau: float) -> tuple[float, float, float, float]:
    """Septic smootherstep and its first three derivatives (``navgym.platforms.profiles.smootherstep``)."""
    t = min(max(tau, 0.0), 1.0)
    u = 1.0 - t
    t2 = t * t
    tu = t * u
    s0 = t2 * t2 * (35.0 + t * (-84.0 + t * (70.0 - 20.0 * t)))
    s1 = 140.0 * tu * tu * tu
    s2 = 420.0 * tu * tu * (1.0 - 2.0 * t)
    s3 = 840.0 * t * u * (1.0 - 5.0 * t + 5.0 * t * t)
    return s0, s1, s2, s3


@njit(cache=True)
def _rodrigues(tx: float, ty: float, tz: float, H: np.ndarray) -> None:
    """``H = Exp(th) = cos|th| I + sinc|th| [th x] + (1 - cos|th|)/|th|^2 th th^T`` (seed 001 eq. 4).

    ``(1 - cos x) / x^2 = sinc(x/2)^2 / 2`` keeps small angles free of cancellation; below
    0.01 rad the three coefficients come from their Taylor series (``cos x = 1 - x^2 b``), with no
    trigonometric call (a 200 Hz gyro sample turns by a few milliradians).
    """
    x2 = tx * tx + ty * ty + tz * tz
    if x2 < 1e-4:  # |th| < 0.01 rad (every sample of a flight): Taylor series, exact to rounding
        # the first omitted terms are x^8 / 9! and x^8 / 8! < 3e-21 relative
        a = 1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0))
        b = 0.5 - x2 / 24.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0))
        c = 1.0 - x2 * b
    else:
        x = math.sqrt(x2)
        a = math.sin(x) / x
        sh = math.sin(0.5 * x) / (0.5 * x)
        b = 0.5 * sh * sh
        c = math.cos(x)
    th = (tx, ty, tz)
    for i in range(3):
        for j in range(3):
            H[i, j] = b * th[i] * th[j]
        H[i, i] += c
    H[0, 1] -= a * tz
    H[1, 0] += a * tz
    H[0, 2] += a * ty
    H[2, 0] -= a * ty
    H[1, 2] -= a * tx
    H[2, 1] += a * tx


@njit(cache=True)
def _kernel(
    t_seg, dur, p_start, p_end, yaw_start, yaw_end,
    t0, k0, nc, dt, n_sub,
    omega, gamma_nodes, bias, noise, na, ng,
    dR, phi, d6, J6,
):  # fmt: skip  # pragma: no cover - compiled; exercised through preintegrated_imu
    B, P = t_seg.shape
    delta = dt / n_sub
    h = 0.5 * delta
    q = 0.25 * delta
    d2 = 0.5 * delta * delta
    H = np.empty((3, 3))
    R = np.empty((3, 3))
    Rm = np.empty((3, 3))
    Rn = np.empty((3, 3))
    psi = np.empty((3, 3))
    psim = np.empty((3, 3))
    G = np.empty((3, 3))
    jva = np.empty((3, 3))
    jvg = np.empty((3, 3))
    jpa = np.empty((3, 3))
    jpg = np.empty((3, 3))
    dv = np.empty(3)
    dp = np.empty(3)
    acc = np.empty(3)
    fm = np.empty(3)
    wm = np.empty(3)
    for b in range(B):
        Ox, Oy, Oz = omega[b, 0], omega[b, 1], omega[b, 2]
        seg = 0
        for kk in range(nc):
            k = k0 + kk
            R[:] = 0.0
            R[0, 0] = R[1, 1] = R[2, 2] = 1.0
            psi[:] = 0.0
            jva[:] = 0.0
            jvg[:] = 0.0
            jpa[:] = 0.0
            jpg[:] = 0.0
            dv[:] = 0.0
            dp[:] = 0.0
            for j in range(n_sub):
                t = t0[b] + k * dt + (j + 0.5) * delta
                # 1. flat outputs of the active phase
                while seg + 1 < P and t_seg[b, seg + 1] <= t:
                    seg += 1
                d = dur[b, seg]
                inv = 1.0 / d
                s0, s1, s2, s3 = _smooth((t - t_seg[b, seg]) / d)
                s1 *= inv
                s2 *= inv * inv
                s3 *= inv * inv * inv
                dpx = p_end[b, seg, 0] - p_start[b, seg, 0]
                dpy = p_end[b, seg, 1] - p_start[b, seg, 1]
                dpz = p_end[b, seg, 2] - p_start[b, seg, 2]
                y0 = yaw_start[b, seg]
                dy = yaw_end[b, seg] - y0
                if dy != 0.0:
                    yaw = y0 + dy * s0
                    cy, sy = math.cos(yaw), math.sin(yaw)
                else:
                    cy, sy = math.cos(y0), math.sin(y0)
                vx, vy, vz = dpx * s1, dpy * s1, dpz * s1
                ax, ay, az = dpx * s2, dpy * s2, dpz * s2
                jx, jy, jz = dpx * s3, dpy * s3, dpz * s3
                r_ = dy * s1
                # 2. attitude and body rate (differential flatness)
                fx, fy, fz = ax, ay, az - G0
                inv_nf = 1.0 / math.sqrt(fx * fx + fy * fy + fz * fz)
                zx, zy, zz = -fx * inv_nf, -fy * inv_nf, -fz * inv_nf
                uj = -(zx * jx + zy * jy + zz * jz)
                dzx = -(jx + uj * zx) * inv_nf
                dzy = -(jy + uj * zy) * inv_nf
                dzz = -(jz + uj * zz) * inv_nf
                wx, wy, wz = -zz * sy, zz * cy, zx * sy - zy * cy
                nw = math.sqrt(wx * wx + wy * wy + wz * wz)
                yx, yy, yz = wx / nw, wy / nw, wz / nw
                xx = yy * zz - yz * zy
                xy = yz * zx - yx * zz
                xz = yx * zy - yy * zx
                dwx = -dzz * sy - zz * r_ * cy
                dwy = dzz * cy - zz * r_ * sy
                dwz = dzx * sy - dzy * cy + r_ * (zx * cy + zy * sy)
                p_ = -(yx * dzx + yy * dzy + yz * dzz)
                q_ = xx * dzx + xy * dzy + xz * dzz
                rr = -(xx * dwx + xy * dwy + xz * dwz) / nw
                # 3. ideal IMU in the home frame; gravity through the step's three nodes
                sf = (j + 0.5) / n_sub
                l0 = 2.0 * (sf - 0.5) * (sf - 1.0)
                lm = -4.0 * sf * (sf - 1.0)
                l1 = 2.0 * sf * (sf - 0.5)
                gn = gamma_nodes[b]
                gx = l0 * gn[2 * k, 0] + lm * gn[2 * k + 1, 0] + l1 * gn[2 * k + 2, 0]
                gy = l0 * gn[2 * k, 1] + lm * gn[2 * k + 1, 1] + l1 * gn[2 * k + 2, 1]
                gz = l0 * gn[2 * k, 2] + lm * gn[2 * k + 1, 2] + l1 * gn[2 * k + 2, 2]
                cx = ax + 2.0 * (Oy * vz - Oz * vy) - gx
                cyy = ay + 2.0 * (Oz * vx - Ox * vz) - gy
                cz = az + 2.0 * (Ox * vy - Oy * vx) - gz
                # 4. errors: measured = true + bias + white noise (bias constant over the step)
                e = noise[b, kk, j]
                fm[0] = (xx * cx + xy * cyy + xz * cz) + bias[b, k, 0] + na[b] * e[0]
                fm[1] = (yx * cx + yy * cyy + yz * cz) + bias[b, k, 1] + na[b] * e[1]
                fm[2] = (zx * cx + zy * cyy + zz * cz) + bias[b, k, 2] + na[b] * e[2]
                wm[0] = (p_ + xx * Ox + xy * Oy + xz * Oz) + bias[b, k, 3] + ng[b] * e[3]
                wm[1] = (q_ + yx * Ox + yy * Oy + yz * Oz) + bias[b, k, 4] + ng[b] * e[4]
                wm[2] = (rr + zx * Ox + zy * Oy + zz * Oz) + bias[b, k, 5] + ng[b] * e[5]
                # 5. preintegration (Forster et al. 2017; seed 001 eq. 4, 6, 7)
                _rodrigues(wm[0] * h, wm[1] * h, wm[2] * h, H)
                for r in range(3):
                    for c in range(3):
                        Rm[r, c] = R[r, 0] * H[0, c] + R[r, 1] * H[1, c] + R[r, 2] * H[2, c]
                for r in range(3):
                    acc[r] = Rm[r, 0] * fm[0] + Rm[r, 1] * fm[1] + Rm[r, 2] * fm[2]
                for r in range(3):
                    for c in range(3):
                        psim[r, c] = psi[r, c] + (R[r, c] + Rm[r, c]) * q
                for c in range(3):
                    G[0, c] = acc[1] * psim[2, c] - acc[2] * psim[1, c]
                    G[1, c] = acc[2] * psim[0, c] - acc[0] * psim[2, c]
                    G[2, c] = acc[0] * psim[1, c] - acc[1] * psim[0, c]
                for r in range(3):
                    dp[r] += dv[r] * delta + acc[r] * d2
                    for c in range(3):
                        jpa[r, c] += jva[r, c] * delta + Rm[r, c] * d2
                        jpg[r, c] += jvg[r, c] * delta + G[r, c] * d2
                    dv[r] += acc[r] * delta
                    for c in range(3):
                        jva[r, c] += Rm[r, c] * delta
                        jvg[r, c] += G[r, c] * delta
                for r in range(3):
                    for c in range(3):
                        Rn[r, c] = Rm[r, 0] * H[0, c] + Rm[r, 1] * H[1, c] + Rm[r, 2] * H[2, c]
                for r in range(3):
                    for c in range(3):
                        psi[r, c] = psim[r, c] + (Rm[r, c] + Rn[r, c]) * q
                R[:] = Rn
            for r in range(3):
                for c in range(3):
                    dR[b, k, r, c] = R[r, c]
                    phi[b, k, r, c] = R[0, r] * psi[0, c] + R[1, r] * psi[1, c] + R[2, r] * psi[2, c]
                    J6[b, k, r, c] = -jva[r, c]
                    J6[b, k, r, 3 + c] = jvg[r, c]
                    J6[b, k, 3 + r, c] = -jpa[r, c]
                    J6[b, k, 3 + r, 3 + c] = jpg[r, c]
                d6[b, k, r] = dv[r]
                d6[b, k, 3 + r] = dp[r]


def preintegrated_imu(
    plans,
    t0: np.ndarray,
    k0: int,
    dt: float,
    n_sub: int,
    omega: np.ndarray,
    gamma_nodes: np.ndarray,
    bias: np.ndarray,
    noise: np.ndarray,
    na: np.ndarray,
    ng: np.ndarray,
    out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """Preintegrate steps ``k0 .. k0 + nc - 1`` of B episodes from their measured IMU samples.

    Step ``k`` of episode ``b`` integrates the ``n_sub`` samples at
    ``t0[b] + k dt + (j + 1/2) dt / n_sub`` (module docstring, items 1-5).

    Args:
        plans: :class:`~navgym.platforms.quadrotor.QuadrotorPlan` of the B episodes.
        t0: Flight time of each episode's epoch 0 [s], ``(B,)``.
        k0: First step of the chunk.
        dt: Step (GNSS epoch) [s].
        n_sub: IMU samples per step.
        omega: Earth rate in the home frame [rad/s], ``(B, 3)``.
        gamma_nodes: :func:`~navgym.platforms.quadrotor.home_gravity` at the epochs and step
            mid-points, ``t0 + i dt / 2``, ``(B, 2 T + 1, 3)``.
        bias: IMU biases ``[b_a, b_g]`` per epoch, ``(B, T + 1, 6)`` (step ``k`` uses epoch ``k``).
        noise: Standard normals of the chunk's samples, ``(B, nc, n_sub, 6)``.
        na: Accelerometer white-noise standard deviation per sample [m/s^2], ``(B,)``.
        ng: Gyro white-noise standard deviation per sample [rad/s], ``(B,)``.
        out: ``(dR, phi, d6, J6)`` of shapes ``(B, T, 3, 3)``, ``(B, T, 3, 3)``, ``(B, T, 6)``,
            ``(B, T, 6, 6)``, written at steps ``k0 .. k0 + nc - 1``.
    """
    nc = noise.shape[1]
    if noise.shape[2] != n_sub or noise.shape[3] != 6:
        raise ValueError(f"noise must be (B, nc, {n_sub}, 6); got {noise.shape}")
    if gamma_nodes.shape[1] < 2 * (k0 + nc) + 1:
        raise ValueError(f"gamma_nodes must cover epoch {k0 + nc}; got {gamma_nodes.shape[1]} nodes")

    def f64(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a, dtype=np.float64)

    _kernel(
        f64(plans.t_start), f64(plans.duration), f64(plans.p_start), f64(plans.p_end),
        f64(plans.yaw_start), f64(plans.yaw_end),
        f64(t0), int(k0), int(nc), float(dt), int(n_sub),
        f64(omega), f64(gamma_nodes), f64(bias), f64(noise), f64(na), f64(ng),
        *out,
    )  # fmt: skip
