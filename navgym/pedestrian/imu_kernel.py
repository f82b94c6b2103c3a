"""Compiled (Numba) twin of the foot IMU of a Pedestrian reset, in two passes.

The twin of :func:`~navgym.pedestrian.gait.foot_state`, :func:`~navgym.pedestrian.gait.foot_imu`
and the sensor errors added by the platform's reset.

Why: the NumPy form builds the foot's kinematics and its IMU in some sixty passes over
``(B, S)`` and ``(B, S, 3)`` arrays of the reset's samples (``S = T n_sub``: 100 samples a
stride), about 55 ms of a 126 ms reset of 16 PedestrianNoiseScale-v3 walks, whose resets are
59 % of a training step at 16 sub-environments. Here one pass per sample forms them in
registers.

The NumPy form stays the reference and the numbers are the same **bit for bit**: the sines and
cosines are NumPy's (its SIMD ``sin``/``cos``, which Numba's scalar calls would not reproduce),
taken on whole arrays between the two passes, and every other quantity is computed with the
reference's operations in the reference's order (no fast-math contraction):

* :func:`foot_angles_pass`: per sample the pitch ``(0.5 Theta) q_j`` and the yaw
  ``psi_k + (psi_{k+1} - psi_k) sigma_j`` (their phase functions ``q_j``, ``sigma_j`` tabulated
  per sub-sample by :func:`navgym.pedestrian.gait.phase_tables`, which the NumPy form uses too),
  whose sines and cosines the caller then takes;
* :func:`foot_imu_pass`: the position, velocity and acceleration of the foot, its Euler rates,
  the gyro ``C^T Omega + omega_nb^b`` and the specific force ``C^T (a - g(p) + 2 Omega x v)``
  (``navgym.pedestrian.gait``'s module docstring), then the sensor errors
  ``(x + b_k) + sigma_k n`` of :meth:`navgym.pedestrian.platform.PedestrianPlatform.simulate`.

``tests/navgym/pedestrian/test_imu_kernel.py`` holds the twins equal with ``array_equal``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from navgym.pedestrian.gait import (
    CLEARANCE,
    NOMINAL_STRIDE,
    PITCH_AMPLITUDE,
    STANCE_HALF,
    PhaseTables,
    StridePlan,
)

__all__ = ["foot_angles_pass", "foot_imu_pass", "sampled_imu"]


@njit(cache=True, error_model="numpy")
def foot_angles_pass(yaw, length, c0, n_sub, sig, q, pitch, heading):  # pragma: no cover - compiled
    """Pitch and yaw of every sample of strides ``c0 ..`` (``pitch, heading (B, nc n_sub)``).

    ``yaw (B, T + 1)`` and ``length (B, T)`` of the plan; ``sig, q (n_sub,)`` of
    :func:`~navgym.pedestrian.gait.phase_tables`. ``pitch = (0.5 Theta) q_j + 0`` with
    ``Theta = PITCH_AMPLITUDE L / L_0``, ``heading = psi_k + (psi_{k+1} - psi_k) sigma_j``.
    """
    B, S = pitch.shape
    for b in range(B):
        for i in range(S):
            k = c0 + i // n_sub
            j = i % n_sub
            s = length[b, k] / NOMINAL_STRIDE
            th = PITCH_AMPLITUDE * s
            pitch[b, i] = 0.5 * th * q[j] + 0.0
            y0 = yaw[b, k]
            heading[b, i] = y0 + (yaw[b, k + 1] - y0) * sig[j]


@njit(cache=True, error_model="numpy")
def foot_imu_pass(
    yaw,
    length,
    start,
    cos_chi,
    sin_chi,
    c0,
    n_sub,
    dt,
    tables,
    sin_p,
    cos_p,
    sin_y,
    cos_y,
    gravity,
    gradient,
    earth_rate,
    bias,
    na,
    ng,
    noise,
    gyro,
    accel,
):  # pragma: no cover - compiled
    """Gyro and accelerometer ``(B, nc n_sub, 3)`` of the samples of strides ``c0 ..``, errors included.

    Plan arrays ``yaw (B, T + 1)``, ``length (B, T)``, ``start (B, T + 1, 3)``, the course's
    ``cos_chi, sin_chi (B, T)``; the :class:`PhaseTables` ``tables``; the samples' pitch and yaw
    sines and cosines ``(B, nc n_sub)``; the home's ``gravity, gradient, earth_rate (B, 3)``;
    per stride the IMU biases ``bias (B, T, 6)`` (accelerometer, gyro) and noise sigmas
    ``na, ng (B, T)``; the unit normals ``noise (B, nc n_sub, 6)``.
    """
    swing, sig, sig1, sig2, sp2, sp3, sp4, cp, cp2, q, q1 = tables
    t_sw = dt * (1.0 - 2.0 * STANCE_HALF)
    a = np.pi / t_sw
    bb = 2.0 * np.pi / t_sw
    B, S = sin_p.shape
    for b in range(B):
        g0x, g0y, g0z = gravity[b, 0], gravity[b, 1], gravity[b, 2]
        gmx, gmy, gmz = gradient[b, 0], gradient[b, 1], gradient[b, 2]
        om0, om1, om2 = earth_rate[b, 0], earth_rate[b, 1], earth_rate[b, 2]
        for i in range(S):
            k = c0 + i // n_sub
            j = i % n_sub
            L = length[b, k]
            y0 = yaw[b, k]
            cx, sx = cos_chi[b, k], sin_chi[b, k]
            s = L / NOMINAL_STRIDE
            mH = -(CLEARANCE * s)
            th = PITCH_AMPLITUDE * s
            on = swing[j]
            # foot_state: position, velocity, acceleration (u = [cos chi, sin chi, 0])
            Ls, Ls1, Ls2 = L * sig[j], L * sig1[j], L * sig2[j]
            p0 = start[b, k, 0] + Ls * cx
            p1 = start[b, k, 1] + Ls * sx
            p2 = (start[b, k, 2] + Ls * 0.0) + mH * sp4[j]
            v0, v1 = Ls1 * cx, Ls1 * sx
            v2 = mH * 4.0 * sp3[j] * cp[j] * a if on else 0.0
            a0, a1 = Ls2 * cx, Ls2 * sx
            a2 = mH * 4.0 * a * a * (3.0 * sp2[j] * cp2[j] - sp4[j]) if on else 0.0
            pitch1 = (0.5 * th * bb * q1[j] if on else 0.0) + 0.0
            yaw1 = (yaw[b, k + 1] - y0) * sig1[j]
            sp_, cp_, sy, cy = sin_p[b, i], cos_p[b, i], sin_y[b, i], cos_y[b, i]
            # foot_imu: C^T Omega + Euler rates, then C^T (a - g(p) + 2 Omega x v)
            u0 = cy * om0 + sy * om1
            w0 = (cp_ * u0 - sp_ * om2) + (0.0 - yaw1 * sp_)
            w1 = (cy * om1 - sy * om0) + pitch1
            w2 = (sp_ * u0 + cp_ * om2) + yaw1 * cp_
            f0 = a0 - (g0x + gmx * p0)
            f1 = a1 - (g0y + gmy * p1)
            f2 = a2 - (g0z + gmz * p2)
            f0 = f0 + 2.0 * (om1 * v2 - om2 * v1)
            f1 = f1 + 2.0 * (om2 * v0 - om0 * v2)
            f2 = f2 + 2.0 * (om0 * v1 - om1 * v0)
            u0 = cy * f0 + sy * f1
            x0 = cp_ * u0 - sp_ * f2
            x1 = cy * f1 - sy * f0
            x2 = sp_ * u0 + cp_ * f2
            # the sensor errors: (x + b_k) + sigma_k n
            sa, sg = na[b, k], ng[b, k]
            accel[b, i, 0] = (x0 + bias[b, k, 0]) + sa * noise[b, i, 0]
            accel[b, i, 1] = (x1 + bias[b, k, 1]) + sa * noise[b, i, 1]
            accel[b, i, 2] = (x2 + bias[b, k, 2]) + sa * noise[b, i, 2]
            gyro[b, i, 0] = (w0 + bias[b, k, 3]) + sg * noise[b, i, 3]
            gyro[b, i, 1] = (w1 + bias[b, k, 4]) + sg * noise[b, i, 4]
            gyro[b, i, 2] = (w2 + bias[b, k, 5]) + sg * noise[b, i, 5]


def sampled_imu(
    plan: StridePlan,
    course: tuple[np.ndarray, np.ndarray],
    c0: int,
    nc: int,
    n_sub: int,
    dt: float,
    tables: PhaseTables,
    home: tuple[np.ndarray, np.ndarray, np.ndarray],
    bias: np.ndarray,
    na: np.ndarray,
    ng: np.ndarray,
    noise: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Measured gyro and accelerometer ``(B, nc n_sub, 3)`` of strides ``c0 .. c0 + nc`` (the two passes).

    ``course``: ``cos chi, sin chi (B, T)`` of the plan's strides (``chi`` the mean of the two
    epochs' yaws); ``home``: gravity, gradient and Earth rate ``(B, 3)``.
    """
    B = plan.length.shape[0]
    S = nc * n_sub
    pitch, heading = np.empty((B, S)), np.empty((B, S))
    foot_angles_pass(plan.yaw, plan.length, c0, n_sub, tables.sig, tables.q, pitch, heading)
    gyro, accel = np.empty((B, S, 3)), np.empty((B, S, 3))
    foot_imu_pass(
        plan.yaw, plan.length, plan.start, course[0], course[1], c0, n_sub, dt, tables,
        np.sin(pitch), np.cos(pitch), np.sin(heading), np.cos(heading), *home,
        bias, na, ng, noise, gyro, accel,
    )  # fmt: skip
    return gyro, accel
