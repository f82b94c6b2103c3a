"""Quadrotor "return to home" closed-triangle flights (seed 001 §2.7a), batched truth generator.

Seed 001 §2.7a: an AR.Drone 2.0 flies a closed triangle whose vertices are 100 to 500 m apart
(Fig. 16) and must return home without (or with jammed) GNSS. Each sampled flight here is:

rest on the ground -> vertical climb -> hover and yaw towards vertex A -> leg 1 (with a climb or
descent to A's altitude) -> hover and turn -> leg 2 to B -> hover and turn -> leg 3 home -> hover
(yaw back to the take-off heading) -> vertical descent -> rest until the episode ends.

Every phase is a rest-to-rest straight move (or yaw turn) along the septic smootherstep of
:mod:`navgym.platforms.profiles`, so position is C^3: velocity, acceleration and jerk are
continuous, and so are the attitude and the angular rate. The attitude is that of a quadrotor
(differential flatness, Mellinger & Kumar, ICRA 2011): the thrust axis -z_b is aligned with the
specific force ``a - g`` and the yaw follows the plan. Trajectories are designed in the home's
Earth-fixed NED tangent frame, then mapped exactly onto the ellipsoid: lat/lon/h through ECEF,
velocity and attitude rotated into the local NED frame, ``dv^n/dt = C_e^n a^e - omega_en x v^n``
and ``omega_nb^b = omega_{n0 b}^b - C_n^b omega_en^n``.

Plans are sampled per episode from its own generator; trajectories are closed-form in t, so
they can be evaluated for a whole episode at reset or one step at a time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo import ecef_to_geodetic, ecef_to_ned_matrix, ned_to_ecef
from navgym.ins.frame_rates import transport_rate_ned
from navgym.ins.imu_grades import G0
from navgym.platforms.profiles import (
    SMOOTHERSTEP_PEAK_ACCEL,
    SMOOTHERSTEP_PEAK_RATE,
    segment_index,
    smootherstep,
    wrap_angle,
)
from navgym.platforms.trajectory import Trajectory, make_trajectory, query_times
from navgym.scenarios.seeding import SeedsOrGenerators, as_generators
from navgym.scenarios.validation import check_positive, check_range

__all__ = [
    "QuadrotorParams",
    "QuadrotorPlan",
    "N_PHASES",
    "sample_quadrotor_plans",
    "quadrotor_trajectory",
    "quadrotor_leg_lengths",
]

#: Number of phases of every flight plan (see the module docstring).
N_PHASES = 11


@dataclass(frozen=True)
class QuadrotorParams:
    """Distribution of triangle flights (defaults follow seed 001 §2.7a and AR.Drone 2.0 limits).

    Attributes:
        leg_length: Range of each of the three triangle sides [m] (seed 001: 100 to 500 m).
        speed: Range of the cruise speed [m/s] (AR.Drone 2.0 tops out near 11 m/s).
        max_accel: Horizontal/vertical acceleration limit used to time moves [m/s^2].
        climb_rate: Peak vertical speed of take-off and landing [m/s].
        altitude: Range of the altitude at home departure and at vertices A and B [m].
        hover: Range of the hover time at each vertex [s].
        yaw_rate: Peak yaw rate during turns [rad/s].
        rest: Range of the time on the ground before take-off [s].
        min_angle_deg: Smallest interior angle of the triangle [deg].
        origin_lat_deg: Range of the home latitude [deg].
        origin_lon_deg: Range of the home longitude [deg].
        origin_h: Range of the home ellipsoidal height [m].

    """

    leg_length: tuple[float, float] = (100.0, 500.0)
    speed: tuple[float, float] = (5.0, 11.0)
    max_accel: float = 2.0
    climb_rate: float = 2.0
    altitude: tuple[float, float] = (20.0, 80.0)
    hover: tuple[float, float] = (2.0, 6.0)
    yaw_rate: float = np.deg2rad(45.0)
    rest: tuple[float, float] = (1.0, 3.0)
    min_angle_deg: float = 20.0
    origin_lat_deg: tuple[float, float] = (43.0, 61.0)
    origin_lon_deg: tuple[float, float] = (-5.0, 40.0)
    origin_h: tuple[float, float] = (0.0, 300.0)

    def __post_init__(self) -> None:
        check_range("leg_length", self.leg_length, lower=0.0, lower_open=True)
        check_range("speed", self.speed, lower=0.0, lower_open=True)
        check_positive("max_accel", self.max_accel)
        check_positive("climb_rate", self.climb_rate)
        check_range("altitude", self.altitude, lower=0.0, lower_open=True)
        check_range("hover", self.hover, lower=0.0)
        check_positive("yaw_rate", self.yaw_rate)
        check_range("rest", self.rest, lower=0.0)
        if not 0.0 <= self.min_angle_deg < 60.0:
            raise ValueError(f"min_angle_deg must lie in [0, 60), got {self.min_angle_deg!r}")
        check_range("origin_lat_deg", self.origin_lat_deg, lower=-89.0, upper=89.0)
        check_range("origin_lon_deg", self.origin_lon_deg, lower=-180.0, upper=180.0)
        check_range("origin_h", self.origin_h, lower=-500.0, upper=9000.0)


class QuadrotorPlan(NamedTuple):
    """Sampled flight plans, batch axis first (``P = N_PHASES`` phases).

    Attributes:
        origin: Home (lat [rad], lon [rad], h [m]), shape ``(B, 3)``.
        t_start: Phase start times [s], shape ``(B, P)``.
        duration: Phase durations [s], shape ``(B, P)`` (the final rest phase has 1 s nominal).
        p_start: Phase start positions in the home NED tangent frame [m], ``(B, P, 3)``.
        p_end: Phase end positions, ``(B, P, 3)``.
        yaw_start: Phase start yaw [rad], ``(B, P)``.
        yaw_end: Phase end yaw (unwrapped) [rad], ``(B, P)``.
        vertices: Home, A and B at their flight altitudes [m], ``(B, 3, 3)``.
        t_landed: Time the flight ends on the ground at home [s], ``(B,)``.

    """

    origin: NDArray[np.float64]
    t_start: NDArray[np.float64]
    duration: NDArray[np.float64]
    p_start: NDArray[np.float64]
    p_end: NDArray[np.float64]
    yaw_start: NDArray[np.float64]
    yaw_end: NDArray[np.float64]
    vertices: NDArray[np.float64]
    t_landed: NDArray[np.float64]


def _move_time(distance: float, speed: float, accel: float) -> float:
    """Duration of a rest-to-rest smootherstep move respecting peak speed and acceleration."""
    if distance <= 0.0:
        return 0.0
    return max(
        SMOOTHERSTEP_PEAK_RATE * distance / speed,
        np.sqrt(SMOOTHERSTEP_PEAK_ACCEL * distance / accel),
        1.0,
    )


def _triangle(rng: np.random.Generator, p: QuadrotorParams) -> tuple[NDArray, NDArray]:
    """Vertices A and B (horizontal NED) such that |HA|, |AB|, |BH| lie in ``leg_length``."""
    lo, hi = p.leg_length
    min_angle = np.deg2rad(p.min_angle_deg)
    for _ in range(10_000):
        d1, d3 = rng.uniform(lo, hi, size=2)
        bearing = rng.uniform(0.0, 2.0 * np.pi)
        turn = rng.choice([-1.0, 1.0]) * rng.uniform(min_angle, np.pi - min_angle)
        a = d1 * np.array([np.cos(bearing), np.sin(bearing)])
        b = d3 * np.array([np.cos(bearing + turn), np.sin(bearing + turn)])
        d2 = np.linalg.norm(b - a)
        if not lo <= d2 <= hi:
            continue
        sides = np.array([d1, d2, d3])
        # interior angles by the law of cosines
        cosines = [
            (sides[(i + 1) % 3] ** 2 + sides[(i + 2) % 3] ** 2 - sides[i] ** 2)
            / (2 * sides[(i + 1) % 3] * sides[(i + 2) % 3])
            for i in range(3)
        ]
        if np.min(np.arccos(np.clip(cosines, -1, 1))) >= min_angle:
            return a, b
    raise ValueError("leg_length and min_angle_deg admit no triangle")  # pragma: no cover


def _sample_one(rng: np.random.Generator, p: QuadrotorParams) -> tuple:
    lat0 = np.deg2rad(rng.uniform(*p.origin_lat_deg))
    lon0 = np.deg2rad(rng.uniform(*p.origin_lon_deg))
    h0 = rng.uniform(*p.origin_h)
    speed = rng.uniform(*p.speed)
    alt = rng.uniform(*p.altitude, size=3)
    hover = rng.uniform(*p.hover, size=4)
    rest = rng.uniform(*p.rest)
    yaw0 = rng.uniform(-np.pi, np.pi)
    a, b = _triangle(rng, p)

    home_air = np.array([0.0, 0.0, -alt[0]])
    va = np.array([a[0], a[1], -alt[1]])
    vb = np.array([b[0], b[1], -alt[2]])
    ground = np.zeros(3)

    phases: list[tuple[NDArray, NDArray, float, float, float]] = []  # p0, p1, yaw0, yaw1, T
    yaw = yaw0

    def move(p0: NDArray, p1: NDArray, speed_: float) -> None:
        d = float(np.linalg.norm(p1 - p0))
        phases.append((p0, p1, yaw, yaw, _move_time(d, speed_, p.max_accel)))

    def turn(at: NDArray, target_yaw: float, hover_time: float) -> float:
        dpsi = float(wrap_angle(target_yaw - yaw))
        need = SMOOTHERSTEP_PEAK_RATE * abs(dpsi) / p.yaw_rate
        phases.append((at, at, yaw, yaw + dpsi, max(hover_time, need, 1.0)))
        return yaw + dpsi

    def bearing(p0: NDArray, p1: NDArray) -> float:
        return float(np.arctan2(p1[1] - p0[1], p1[0] - p0[0]))

    phases.append((ground, ground, yaw, yaw, rest))
    move(ground, home_air, p.climb_rate)
    yaw = turn(home_air, bearing(home_air, va), hover[0])
    move(home_air, va, speed)
    yaw = turn(va, bearing(va, vb), hover[1])
    move(va, vb, speed)
    yaw = turn(vb, bearing(vb, home_air), hover[2])
    move(vb, home_air, speed)
    yaw = turn(home_air, yaw0, hover[3])
    move(home_air, ground, p.climb_rate)
    phases.append((ground, ground, yaw, yaw, 1.0))  # final rest (held for t >= its start)
    assert len(phases) == N_PHASES

    dur = np.array([ph[4] for ph in phases])
    t_start = np.concatenate([[0.0], np.cumsum(dur[:-1])])
    return (
        np.array([lat0, lon0, h0]),
        t_start,
        dur,
        np.array([ph[0] for ph in phases]),
        np.array([ph[1] for ph in phases]),
        np.array([ph[2] for ph in phases]),
        np.array([ph[3] for ph in phases]),
        np.array([home_air, va, vb]),
        t_start[-1],
    )


def sample_quadrotor_plans(
    seeds_or_rngs: SeedsOrGenerators, params: QuadrotorParams | None = None
) -> QuadrotorPlan:
    """Sample one triangle flight per episode, each from its own generator.

    Sampling B episodes at once equals B single draws with the same seeds.

    Args:
        seeds_or_rngs: Seeds or generators, one per episode.
        params: Flight distribution (defaults: :class:`QuadrotorParams`).

    Returns:
        The plans, batch axis first.

    """
    params = QuadrotorParams() if params is None else params
    rows = [_sample_one(rng, params) for rng in as_generators(seeds_or_rngs)]
    return QuadrotorPlan(*(np.stack([np.asarray(r[i]) for r in rows]) for i in range(9)))


class _Flat(NamedTuple):
    """Flat outputs and derivatives in the home tangent frame at the query times."""

    pos: NDArray
    vel: NDArray
    acc: NDArray
    jerk: NDArray
    yaw: NDArray
    yaw_rate: NDArray


def _design(plan: QuadrotorPlan, t: NDArray) -> _Flat:
    """Position and its derivatives up to jerk, yaw and yaw rate at times ``(B, T)``."""
    i = segment_index(plan.t_start, t)
    take = np.take_along_axis
    d = take(plan.duration, i, axis=1)
    tau = (t - take(plan.t_start, i, axis=1)) / d
    p0 = take(plan.p_start, i[..., None], axis=1)
    dp = take(plan.p_end, i[..., None], axis=1) - p0
    y0 = take(plan.yaw_start, i, axis=1)
    dy = take(plan.yaw_end, i, axis=1) - y0
    s0, s1, s2, s3 = (smootherstep(tau, k) for k in (0, 1, 2, 3))
    inv = 1.0 / d
    return _Flat(
        p0 + dp * s0[..., None],
        dp * (s1 * inv)[..., None],
        dp * (s2 * inv * inv)[..., None],
        dp * (s3 * inv * inv * inv)[..., None],
        y0 + dy * s0,
        dy * s1 * inv,
    )


def _attitude_and_rate(flat: _Flat) -> tuple[NDArray, NDArray]:
    """Quadrotor attitude C_b^{n0} and body rate omega_{n0 b}^b from the flat outputs.

    Differential flatness (Mellinger & Kumar 2011), NED form: the body z axis points against
    the specific force ``f = a - g e_3``, ``z_b = -f / |f|``; with ``x_c = [cos psi, sin psi, 0]``,
    ``y_b = (z_b x x_c) / |z_b x x_c|`` and ``x_b = y_b x z_b``. Differentiating,
    ``dz_b/dt = -(j - (u.j) u) / |f|`` (``u = f / |f|``, ``j`` the jerk) and the body rates are
    ``p = -y_b . dz_b/dt``, ``q = x_b . dz_b/dt``,
    ``r = -x_b . (dz_b/dt x x_c + z_b x dx_c/dt) / |z_b x x_c|``.
    """
    f = flat.acc.copy()
    f[..., 2] -= G0
    nf = np.linalg.norm(f, axis=-1, keepdims=True)
    u = f / nf
    z_b = -u
    dz_b = -(flat.jerk - (u * flat.jerk).sum(axis=-1, keepdims=True) * u) / nf
    cy, sy = np.cos(flat.yaw), np.sin(flat.yaw)
    zero = np.zeros_like(cy)
    x_c = np.stack([cy, sy, zero], axis=-1)
    dx_c = flat.yaw_rate[..., None] * np.stack([-sy, cy, zero], axis=-1)
    w = np.cross(z_b, x_c)
    nw = np.linalg.norm(w, axis=-1, keepdims=True)
    y_b = w / nw
    x_b = np.cross(y_b, z_b)
    dw = np.cross(dz_b, x_c) + np.cross(z_b, dx_c)
    rate = np.stack(
        [
            -(y_b * dz_b).sum(axis=-1),
            (x_b * dz_b).sum(axis=-1),
            -(x_b * dw).sum(axis=-1) / nw[..., 0],
        ],
        axis=-1,
    )
    return np.stack([x_b, y_b, z_b], axis=-1), rate


def quadrotor_trajectory(plan: QuadrotorPlan, t: ArrayLike) -> Trajectory:
    """Evaluate the flights at arbitrary times (whole episode at reset, or one step at a time).

    Args:
        plan: Flight plans of B episodes.
        t: Times [s]: scalar, ``(T,)`` shared, or ``(B, T)`` per episode.

    Returns:
        Truth :class:`~navgym.platforms.trajectory.Trajectory` of shape ``(B, T, ...)``, with
        the ideal IMU outputs at those times.

    """
    b = plan.origin.shape[0]
    t = query_times(t, b)
    flat = _design(plan, t)
    C_b_n0, w_n0b_b = _attitude_and_rate(flat)

    o = plan.origin[:, None, :]
    ecef = ned_to_ecef(flat.pos, o[..., 0], o[..., 1], o[..., 2])
    lat, lon, h = ecef_to_geodetic(ecef)
    M = ecef_to_ned_matrix(lat, lon) @ np.swapaxes(ecef_to_ned_matrix(o[..., 0], o[..., 1]), -1, -2)
    v_n = (M @ flat.vel[..., None])[..., 0]
    w_en = transport_rate_ned(lat, h, v_n)
    a_n = (M @ flat.acc[..., None])[..., 0] - np.cross(w_en, v_n)
    C_b_n = M @ C_b_n0
    w_nb_b = w_n0b_b - (np.swapaxes(C_b_n, -1, -2) @ w_en[..., None])[..., 0]
    return make_trajectory(t, lat, lon, h, flat.pos, v_n, a_n, C_b_n, w_nb_b, plan.origin)


def quadrotor_leg_lengths(plan: QuadrotorPlan) -> NDArray[np.float64]:
    """Horizontal lengths of the three triangle sides HA, AB, BH [m], shape ``(B, 3)``."""
    v = plan.vertices[..., :2]
    return np.linalg.norm(v - np.roll(v, -1, axis=1), axis=-1)
