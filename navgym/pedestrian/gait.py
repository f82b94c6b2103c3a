"""A walker's foot: piecewise constant heading and speed, one stride per second, stance phases.

**The walk** (Benzerrouk 2014, §2.7c: a foot-mounted MEMS IMU on a walk in a city): segments of
straight walking at a constant speed (uniform in :data:`SPEED`, about 1.4 m/s) and heading,
separated by turns; a segment ends with probability :data:`SEGMENT_HAZARD` per stride (city
blocks of ~25 m on average); a new segment turns by +-90 deg (a street corner, probability
:data:`CORNER_PROBABILITY`) or by a uniform angle within +-60 deg, and is a stop (standing at a
crossing, speed 0, no turn) with probability :data:`STOP_PROBABILITY`. The foot turns by at most
:data:`MAX_TURN_PER_STRIDE` per stride (a corner takes two strides).

**One stride** is one filter step ``k -> k + 1`` of ``dt`` seconds (cadence one stride per second,
two steps per second: a stride length of ``L = speed dt``). The epochs ``t_k`` are mid-stance:
the foot rests during ``[t_k, t_k + s)`` and ``[t_k + dt - s, t_k + dt)`` (``s = STANCE_HALF dt``)
and swings in between, over ``T_sw = dt - 2 s`` with phase ``tau`` in [0, 1]::

    p(tau)     = p_k + d_k sigma(tau),        sigma(tau) = tau - sin(2 pi tau) / (2 pi)
    down(tau)  = -H sin^4(pi tau)             (foot clearance, H = CLEARANCE L / 1.4 m)
    yaw(tau)   = psi_k + (psi_{k+1} - psi_k) sigma(tau)
    pitch(tau) = Theta sin(2 pi tau) sin^2(pi tau)   (Theta = PITCH_AMPLITUDE L / 1.4 m)

with ``d_k = L [cos chi_k, sin chi_k, 0]``, ``chi_k = (psi_k + psi_{k+1}) / 2``: velocity,
acceleration and angular rate vanish at both ends of the swing (``sigma' = 1 - cos 2 pi tau``),
so the foot is at rest at every epoch: the zero-velocity update there is exact. Roll is 0.

**The IMU** (:func:`foot_imu`) samples the exact kinematics in the Earth-fixed home NED frame of
the filter's mechanization (:mod:`navgym.quadrotor.models`, Benzerrouk 2014, eq. 3-7)::

    omega_ib^b = omega_nb^b + C^T Omega,    f^b = C^T (a - g(p) + 2 Omega x v)

with ``omega_nb^b = [-yaw' sin(pitch), pitch', yaw' cos(pitch)]`` (roll 0; Groves 2013, eq.
2.58), ``C = C_b^n`` of the Euler angles, ``Omega`` the Earth rate in the home frame and ``g(p) =
g0 + diag(Gamma) p`` the filter's gravity model (its neglected terms are below 1e-5 m/s^2 within
a kilometre of home).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Walking speed range of a segment [m/s] (uniform).
SPEED = (1.0, 1.8)
#: Probability per stride that a segment ends.
SEGMENT_HAZARD = 0.04
#: Probability that a new segment turns a street corner (+-90 deg), else a uniform turn in +-60 deg.
CORNER_PROBABILITY = 0.5
#: Probability that a new segment is a stop (speed 0, no turn).
STOP_PROBABILITY = 0.15
#: Largest turn of the foot within one stride [rad].
MAX_TURN_PER_STRIDE = np.deg2rad(45.0)
#: Half stance per stride, as a fraction of the stride (stance 40 % of the gait cycle).
STANCE_HALF = 0.2
#: Foot clearance [m] and pitch swing [rad] of a 1.4 m stride (scaled by the stride length).
CLEARANCE = 0.12
PITCH_AMPLITUDE = np.deg2rad(30.0)
#: Stride length at which clearance and pitch have their nominal amplitude [m].
NOMINAL_STRIDE = 1.4
#: Uniforms per stride of :func:`stride_plan`: segment end, stop, corner, turn size, speed.
PLAN_WIDTH = 5


class StridePlan(NamedTuple):
    """B walks of T strides (episode axis first)."""

    yaw: np.ndarray  #: (B, T + 1) foot yaw at the epochs [rad] (unwrapped)
    length: np.ndarray  #: (B, T) stride length of step k [m]
    start: np.ndarray  #: (B, T + 1, 3) foot position at the epochs, NED [m]


def stride_plan(u: np.ndarray, yaw0: np.ndarray) -> StridePlan:
    """The walk of uniforms ``u (B, T, PLAN_WIDTH)`` from headings ``yaw0 (B,)`` (module docstring)."""
    B, T, _ = u.shape
    new = u[..., 0] < SEGMENT_HAZARD
    new[:, 0] = True
    stop = new & (u[..., 1] < STOP_PROBABILITY)
    corner = np.where(u[..., 3] < 0.5, -0.5 * np.pi, 0.5 * np.pi)
    turn = np.where(u[..., 2] < CORNER_PROBABILITY, corner, np.deg2rad(120.0) * (u[..., 3] - 0.5))
    turn = np.where(new & ~stop, turn, 0.0)
    turn[:, 0] = 0.0
    idx = np.maximum.accumulate(np.where(new, np.arange(T), 0), axis=1)  # segment start of each stride
    rows = np.arange(B)[:, None]
    speed = SPEED[0] + (SPEED[1] - SPEED[0]) * u[..., 4]
    length = np.where(stop[rows, idx], 0.0, speed[rows, idx])  # dt = 1 s: L = speed
    target = yaw0[:, None] + np.cumsum(turn, axis=1)
    yaw = np.empty((B, T + 1))
    yaw[:, 0] = yaw0
    for k in range(T):  # over strides, batched: the foot turns at most MAX_TURN_PER_STRIDE
        yaw[:, k + 1] = yaw[:, k] + np.clip(
            target[:, k] - yaw[:, k], -MAX_TURN_PER_STRIDE, MAX_TURN_PER_STRIDE
        )
    chi = 0.5 * (yaw[:, 1:] + yaw[:, :-1])
    d = np.zeros((B, T, 3))
    d[..., 0], d[..., 1] = length * np.cos(chi), length * np.sin(chi)
    start = np.zeros((B, T + 1, 3))
    start[:, 1:] = np.cumsum(d, axis=1)
    return StridePlan(yaw, length, start)


class PhaseTables(NamedTuple):
    """The phase functions of :func:`foot_state`: functions of the fraction of the stride alone.

    ``swing`` (True in the swing), ``sig``, ``sig1``, ``sig2`` (``sigma`` and its time
    derivatives), ``sp2, sp3, sp4, cp2`` (powers of ``sin(pi tau)``, ``cos(pi tau)``), ``cp``,
    ``q = sin(w) - sin(2 w) / 2`` (pitch) and ``q1 = cos(w) - cos(2 w)`` (its rate), each formed as
    :func:`foot_state` uses them. Tabulated once per sub-sample fraction, they are also the
    tables of the compiled twin (:mod:`navgym.pedestrian.imu_kernel`).
    """

    swing: np.ndarray
    sig: np.ndarray
    sig1: np.ndarray
    sig2: np.ndarray
    sp2: np.ndarray
    sp3: np.ndarray
    sp4: np.ndarray
    cp: np.ndarray
    cp2: np.ndarray
    q: np.ndarray
    q1: np.ndarray


def phase_tables(frac: np.ndarray, dt: float) -> PhaseTables:
    """:class:`PhaseTables` at fractions ``frac`` (any shape) of a stride of ``dt`` seconds."""
    t_sw = dt * (1.0 - 2.0 * STANCE_HALF)
    tau = np.clip((frac - STANCE_HALF) / (1.0 - 2.0 * STANCE_HALF), 0.0, 1.0)
    swing = (tau > 0.0) & (tau < 1.0)
    w = 2.0 * np.pi * tau
    sig = tau - np.sin(w) / (2.0 * np.pi)
    sig1 = np.where(swing, (1.0 - np.cos(w)) / t_sw, 0.0)
    sig2 = np.where(swing, 2.0 * np.pi * np.sin(w) / t_sw**2, 0.0)
    sp, cp = np.sin(np.pi * tau), np.cos(np.pi * tau)
    q = np.sin(w) - 0.5 * np.sin(2.0 * w)
    q1 = np.cos(w) - np.cos(2.0 * w)
    return PhaseTables(swing, sig, sig1, sig2, sp**2, sp**3, sp**4, cp, cp**2, q, q1)


class FootState(NamedTuple):
    """Foot kinematics at times within strides (leading axes of the inputs)."""

    pos: np.ndarray  #: (..., 3) NED [m]
    vel: np.ndarray  #: (..., 3) [m/s]
    acc: np.ndarray  #: (..., 3) [m/s^2]
    euler: np.ndarray  #: (..., 3) roll, pitch, yaw [rad]
    rate: np.ndarray  #: (..., 3) roll, pitch, yaw rates [rad/s]


def foot_state(plan: StridePlan, k: np.ndarray, frac: np.ndarray, dt: float) -> FootState:
    """Foot kinematics in stride ``k (B, S)`` (int) at fraction ``frac`` of it (module docstring).

    ``frac`` broadcasts against ``k`` (``(1, S)``: the phase functions are computed once).
    """
    rows = np.arange(k.shape[0])[:, None]
    t_sw = dt * (1.0 - 2.0 * STANCE_HALF)
    ph = phase_tables(frac, dt)
    swing, sig = ph.swing, ph.sig
    L = plan.length[rows, k]
    y0, y1 = plan.yaw[rows, k], plan.yaw[rows, k + 1]
    chi = 0.5 * (y0 + y1)
    u = np.stack([np.cos(chi), np.sin(chi), np.zeros_like(chi)], axis=-1)
    s = L / NOMINAL_STRIDE
    # clearance: down = -H sin^4(pi tau), derivatives in time (d tau / dt = 1 / t_sw)
    H = CLEARANCE * s
    a = np.pi / t_sw
    down = -H * ph.sp4
    down1 = np.where(swing, -H * 4.0 * ph.sp3 * ph.cp * a, 0.0)
    down2 = np.where(swing, -H * 4.0 * a * a * (3.0 * ph.sp2 * ph.cp2 - ph.sp4), 0.0)
    pos = plan.start[rows, k] + (L * sig)[..., None] * u
    pos[..., 2] = pos[..., 2] + down
    vel = (L * ph.sig1)[..., None] * u
    vel[..., 2] = down1
    acc = (L * ph.sig2)[..., None] * u
    acc[..., 2] = down2
    # pitch = Theta sin(w) sin^2(pi tau) = Theta (sin(w) - sin(2w) / 2) / 2
    th = PITCH_AMPLITUDE * s
    b = 2.0 * np.pi / t_sw
    pitch = 0.5 * th * ph.q
    pitch1 = np.where(swing, 0.5 * th * b * ph.q1, 0.0)
    yaw = y0 + (y1 - y0) * sig
    yaw1 = (y1 - y0) * ph.sig1
    zero = np.zeros_like(yaw)
    pitch, pitch1 = pitch + zero, pitch1 + zero
    euler = np.stack([zero, pitch, yaw], axis=-1)
    rate = np.stack([zero, pitch1, yaw1], axis=-1)
    return FootState(pos, vel, acc, euler, rate)


def to_body(euler: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``C^T v`` ``(..., 3)``: a NED vector in the body frame, ``C = R_z(yaw) R_y(pitch)`` (roll 0)."""
    sy, cy = np.sin(euler[..., 2]), np.cos(euler[..., 2])
    sp, cp = np.sin(euler[..., 1]), np.cos(euler[..., 1])
    u0 = cy * v[..., 0] + sy * v[..., 1]
    out = np.empty(np.broadcast_shapes(euler.shape, v.shape))
    out[..., 0] = cp * u0 - sp * v[..., 2]
    out[..., 1] = cy * v[..., 1] - sy * v[..., 0]
    out[..., 2] = sp * u0 + cp * v[..., 2]
    return out


def foot_imu(
    st: FootState, gravity: np.ndarray, gradient: np.ndarray, earth_rate: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """True gyro and accelerometer ``(..., 3)`` of foot states (leading axes ``(B, ...)``, roll 0).

    ``gravity``, ``gradient``, ``earth_rate`` ``(B, 3)``: the home's ``g0``, ``diag(Gamma)`` and
    ``Omega`` (module docstring).
    """
    extra = (None,) * (st.pos.ndim - 2)
    g0, gam, om = (x[(slice(None), *extra)] for x in (gravity, gradient, earth_rate))
    pitch, pitch_rate, yaw_rate = st.euler[..., 1], st.rate[..., 1], st.rate[..., 2]
    gyro = to_body(st.euler, np.broadcast_to(om, st.pos.shape))
    gyro[..., 0] += st.rate[..., 0] - yaw_rate * np.sin(pitch)
    gyro[..., 1] += pitch_rate
    gyro[..., 2] += yaw_rate * np.cos(pitch)
    v = st.vel
    spec = st.acc - (g0 + gam * st.pos)
    spec[..., 0] += 2.0 * (om[..., 1] * v[..., 2] - om[..., 2] * v[..., 1])
    spec[..., 1] += 2.0 * (om[..., 2] * v[..., 0] - om[..., 0] * v[..., 2])
    spec[..., 2] += 2.0 * (om[..., 0] * v[..., 1] - om[..., 1] * v[..., 0])
    return gyro, to_body(st.euler, spec)
