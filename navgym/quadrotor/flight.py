"""Quadrotor "return to home" closed-triangle flights (Benzerrouk 2014, §2.7a), batched truth generator.

In Benzerrouk 2014 (§2.7a) an AR.Drone 2.0 flies a closed triangle whose vertices are 100 to 500 m
apart (Fig. 16) and must return home without (or with jammed) GNSS. Each sampled flight here is:

rest on the ground -> vertical climb -> hover and yaw towards vertex A -> leg 1 (with a climb or
descent to A's altitude) -> hover and turn -> leg 2 to B -> hover and turn -> leg 3 home -> hover
(yaw back to the take-off heading) -> vertical descent -> rest until the episode ends.

Every phase is a rest-to-rest straight move (or yaw turn) along the septic smootherstep of
:mod:`navgym.motion.profiles`, so position is C^3: velocity, acceleration and jerk are
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
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo import (
    ecef_to_geodetic_sincos,
    ecef_to_ned_matrix,
    geodetic_to_ecef,
    gravity,
)
from navgym.ins.attitude import euler_from_dcm_entries, wrap_angle
from navgym.ins.frame_rates import transport_rate_components
from navgym.ins.imu_grades import G0
from navgym.ins.inverse_mechanization import imu_from_components
from navgym.ins.vec3 import Vec3, cross, dot
from navgym.motion.profiles import (
    SMOOTHERSTEP_PEAK_ACCEL,
    SMOOTHERSTEP_PEAK_RATE,
    segment_index,
    smootherstep,
)
from navgym.motion.trajectory import Trajectory, query_times
from navgym.scenarios.seeding import SeedsOrGenerators, as_generators
from navgym.scenarios.validation import check_positive, check_range

__all__ = [
    "QuadrotorParams",
    "QuadrotorPlan",
    "N_PHASES",
    "sample_quadrotor_plans",
    "quadrotor_trajectory",
    "quadrotor_imu",
    "quadrotor_positions",
    "quadrotor_home_truth",
    "home_gravity",
    "quadrotor_leg_lengths",
]

#: Number of phases of every flight plan (see the module docstring).
N_PHASES = 11


@dataclass(frozen=True)
class QuadrotorParams:
    """Distribution of triangle flights (defaults: Benzerrouk 2014, §2.7a, and AR.Drone 2.0 limits).

    Attributes:
        leg_length: Range of each of the three triangle sides [m] (Benzerrouk 2014: 100 to 500 m).
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
    """Flat outputs and derivatives in the home tangent frame at the query times.

    Vectors are component triples of ``(B, T)`` arrays (north, east, down).
    """

    pos: Vec3
    vel: Vec3
    acc: Vec3
    jerk: Vec3
    yaw: NDArray
    yaw_rate: NDArray
    cos_yaw: NDArray
    sin_yaw: NDArray


def _design(plan: QuadrotorPlan, t: NDArray) -> _Flat:
    """Position and its derivatives up to jerk, yaw and yaw rate at times ``(B, T)``."""
    B, P = plan.t_start.shape
    flat = segment_index(plan.t_start, t) + P * np.arange(B)[:, None]

    def take(a: NDArray) -> NDArray:  # per-phase (B, P) values at the query times (B, T)
        return np.take(np.ascontiguousarray(a).reshape(-1), flat)

    d = take(plan.duration)
    tau = (t - take(plan.t_start)) / d
    inv = 1.0 / d
    s0 = smootherstep(tau, 0)
    s1 = smootherstep(tau, 1) * inv
    s2 = smootherstep(tau, 2) * (inv * inv)
    s3 = smootherstep(tau, 3) * (inv * inv * inv)
    p0 = [take(plan.p_start[..., c]) for c in range(3)]
    dp = [take(plan.p_end[..., c]) - p0[c] for c in range(3)]
    y0 = take(plan.yaw_start)
    dy = take(plan.yaw_end) - y0
    yaw = y0 + dy * s0
    # cos/sin of the yaw: per phase where it is constant (legs, climbs, rests), per time in turns
    cos_yaw, sin_yaw = take(np.cos(plan.yaw_start)), take(np.sin(plan.yaw_start))
    turn = np.flatnonzero(dy)
    if turn.size:
        yt = yaw.reshape(-1)[turn]
        cos_yaw.reshape(-1)[turn] = np.cos(yt)
        sin_yaw.reshape(-1)[turn] = np.sin(yt)
    return _Flat(
        tuple(p0[c] + dp[c] * s0 for c in range(3)),
        tuple(dp[c] * s1 for c in range(3)),
        tuple(dp[c] * s2 for c in range(3)),
        tuple(dp[c] * s3 for c in range(3)),
        yaw,
        dy * s1,
        cos_yaw,
        sin_yaw,
    )


def _attitude_and_rate(flat: _Flat) -> tuple[tuple[Vec3, Vec3, Vec3], Vec3]:
    """Quadrotor body axes in the home frame n0 and body rate omega_{n0 b}^b (flat outputs).

    Differential flatness (Mellinger & Kumar 2011), NED form: the body z axis points against
    the specific force ``f = a - g e_3``, ``z_b = -f / |f|``; with ``x_c = [cos psi, sin psi, 0]``,
    ``y_b = (z_b x x_c) / |z_b x x_c|`` and ``x_b = y_b x z_b``. Differentiating,
    ``dz_b/dt = -(j - (u.j) u) / |f|`` (``u = f / |f|``, ``j`` the jerk) and the body rates are
    ``p = -y_b . dz_b/dt``, ``q = x_b . dz_b/dt``,
    ``r = -x_b . (dz_b/dt x x_c + z_b x dx_c/dt) / |z_b x x_c|``.

    Returns:
        ``((x_b, y_b, z_b), rate)``: the columns of ``C_b^{n0}`` and the body rate, component
        triples of ``(B, T)`` arrays.
    """
    f = (flat.acc[0], flat.acc[1], flat.acc[2] - G0)
    inv_nf = 1.0 / np.sqrt(dot(f, f))
    z_b = tuple(-fc * inv_nf for fc in f)  # -u
    uj = -dot(z_b, flat.jerk)  # u . j
    dz_b = tuple(-(flat.jerk[c] + uj * z_b[c]) * inv_nf for c in range(3))  # -(j - (u.j) u) / |f|
    cy, sy = flat.cos_yaw, flat.sin_yaw
    # w = z_b x x_c with x_c = (cy, sy, 0)
    w = (-z_b[2] * sy, z_b[2] * cy, z_b[0] * sy - z_b[1] * cy)
    nw = np.sqrt(dot(w, w))
    y_b = tuple(wc / nw for wc in w)
    x_b = cross(y_b, z_b)
    # dw = dz_b x x_c + z_b x dx_c with dx_c = yaw_rate (-sy, cy, 0)
    r_ = flat.yaw_rate
    dw = (
        -dz_b[2] * sy - z_b[2] * r_ * cy,
        dz_b[2] * cy - z_b[2] * r_ * sy,
        dz_b[0] * sy - dz_b[1] * cy + r_ * (z_b[0] * cy + z_b[1] * sy),
    )
    rate = (-dot(y_b, dz_b), dot(x_b, dz_b), -dot(x_b, dw) / nw)
    return (x_b, y_b, z_b), rate


def _home_to_ecef(origin: NDArray, pos: Vec3) -> tuple[NDArray, NDArray]:
    """ECEF points ``(B, T, 3)`` of home-frame positions, and the home's ``C_e^{n0}`` ``(B, 1, 3, 3)``.

    ``r^e = r0^e + C_e^{n0 T} p^{n0}`` with ``r0^e`` the home (``origin`` rows lat, lon, h) and
    the rows of ``C_e^{n0}`` its north, east and down axes in ECEF.
    """
    lat0, lon0, h0 = (origin[:, k : k + 1] for k in range(3))
    R0 = ecef_to_ned_matrix(lat0, lon0)  # (B, 1, 3, 3): rows N0, E0, D0 in ECEF
    r0 = geodetic_to_ecef(lat0, lon0, h0)  # (B, 1, 3)
    ecef = np.stack(
        [
            r0[..., j] + R0[..., 0, j] * pos[0] + R0[..., 1, j] * pos[1] + R0[..., 2, j] * pos[2]
            for j in range(3)
        ],
        axis=-1,
    )
    return ecef, R0


def home_gravity(origin: NDArray, pos: Vec3) -> NDArray[np.float64]:
    """Normal gravity vector ``gamma^{n0}`` [m/s^2] in the home NED tangent frame, ``(B, T, 3)``.

    ``gamma^{n0} = gamma(lat, h) C_e^{n0} d^e`` with ``d^e = -(cos lat cos lon, cos lat sin lon,
    sin lat)`` the local down axis at the point (Groves eq. 2.150) and ``gamma`` WGS-84 normal
    gravity (:func:`navgym.geo.gravity`), the gravity model of
    :func:`navgym.ins.inverse_mechanization.imu_from_components` (the Quadrotor env's reset
    kernel, :mod:`navgym.quadrotor.imu_kernel`, interpolates it).

    Args:
        origin: Homes (lat [rad], lon [rad], h [m]), ``(B, 3)``.
        pos: Positions in the home frame, three ``(B, T)`` arrays (north, east, down) [m].
    """
    ecef, R0 = _home_to_ecef(origin, pos)
    lat, _, h, sl, cl, so, co = ecef_to_geodetic_sincos(ecef)
    g = gravity(lat, h, sl)
    down = (-cl * co, -cl * so, -sl)
    return np.stack(
        [g * (R0[..., k, 0] * down[0] + R0[..., k, 1] * down[1] + R0[..., k, 2] * down[2]) for k in range(3)],
        axis=-1,
    )


def _truth_components(plan: QuadrotorPlan, t: NDArray) -> dict[str, Any]:
    """The truth of :func:`quadrotor_trajectory` as component arrays ``(B, T)`` (unstacked)."""
    flat = _design(plan, t)
    body0, w_n0b_b = _attitude_and_rate(flat)

    ecef, R0 = _home_to_ecef(plan.origin, flat.pos)
    lat, lon, h, sl, cl, so, co = ecef_to_geodetic_sincos(ecef)
    # local NED axes in ECEF (Groves eq. 2.150) and M_ik = n_i . n0_k
    axes = ((-sl * co, -sl * so, cl), (-so, co, None), (-cl * co, -cl * so, -sl))

    def dot_home(axis: tuple, k: int) -> NDArray:
        out = axis[0] * R0[..., k, 0] + axis[1] * R0[..., k, 1]
        return out if axis[2] is None else out + axis[2] * R0[..., k, 2]

    M = tuple(tuple(dot_home(axes[i], k) for k in range(3)) for i in range(3))

    def rotate(v: Vec3) -> Vec3:
        return tuple(M[i][0] * v[0] + M[i][1] * v[1] + M[i][2] * v[2] for i in range(3))

    v_n = rotate(flat.vel)
    w_en = transport_rate_components(lat, h, v_n, sl, cl)
    a_n = tuple(ai - ci for ai, ci in zip(rotate(flat.acc), cross(w_en, v_n), strict=True))
    cols = tuple(rotate(axis) for axis in body0)  # columns of C_b^n
    C = tuple(tuple(cols[j][i] for j in range(3)) for i in range(3))  # C[i][j]
    w_nb_b = tuple(w_n0b_b[j] - dot(cols[j], w_en) for j in range(3))
    f_ib, w_ib = imu_from_components(lat, h, v_n, a_n, C, w_nb_b, sin_lat=sl, cos_lat=cl, w_en=w_en)
    return {
        "lat": lat, "lon": lon, "h": h, "pos": flat.pos, "v_n": v_n, "a_n": a_n, "C": C,
        "w_nb_b": w_nb_b, "f_ib": f_ib, "w_ib": w_ib,
    }  # fmt: skip


def quadrotor_trajectory(plan: QuadrotorPlan, t: ArrayLike) -> Trajectory:
    """Evaluate the flights at arbitrary times (whole episode at reset, or one step at a time).

    Computed on component arrays ``(B, T)`` throughout (no reductions over axes of length 3)
    and stacked into the :class:`~navgym.motion.trajectory.Trajectory` layout at the end.
    With ``M = C_e^n(lat, lon) C_e^{n0 T}`` the rotation from the home frame to the local NED
    frame: ``v^n = M v^{n0}``, ``dv^n/dt = M a^{n0} - omega_en^n x v^n``, ``C_b^n = M C_b^{n0}``,
    ``omega_nb^b = omega_{n0 b}^b - C_n^b omega_en^n`` (module docstring), and the ideal IMU
    outputs by :func:`~navgym.ins.inverse_mechanization.imu_from_components`.

    Args:
        plan: Flight plans of B episodes.
        t: Times [s]: scalar, ``(T,)`` shared, or ``(B, T)`` per episode.

    Returns:
        Truth :class:`~navgym.motion.trajectory.Trajectory` of shape ``(B, T, ...)``, with
        the ideal IMU outputs at those times.

    """
    t = query_times(t, plan.origin.shape[0])
    c = _truth_components(plan, t)

    def vec(v: Vec3) -> NDArray:
        return np.stack(v, axis=-1)

    C_b_n = np.stack([vec(row) for row in c["C"]], axis=-2)
    return Trajectory(
        t,
        c["lat"],
        c["lon"],
        c["h"],
        vec(c["pos"]),
        vec(c["v_n"]),
        vec(c["a_n"]),
        C_b_n,
        vec(c["w_nb_b"]),
        vec(c["f_ib"]),
        vec(c["w_ib"]),
        plan.origin,
    )


def quadrotor_imu(plan: QuadrotorPlan, t: ArrayLike) -> tuple[Vec3, Vec3]:
    """Ideal IMU outputs only: components of ``f_ib^b`` and ``omega_ib^b``, each ``(B, T)``.

    The same values as the ``specific_force`` and ``angular_rate`` of
    :func:`quadrotor_trajectory`, without stacking the rest of the truth (the IMU samples at
    reset, 20 per filter step, need nothing else).
    """
    c = _truth_components(plan, query_times(t, plan.origin.shape[0]))
    return c["f_ib"], c["w_ib"]


def quadrotor_positions(plan: QuadrotorPlan, t: ArrayLike) -> Vec3:
    """Positions in the home NED tangent frame [m] at times ``t``: (north, east, down), each ``(B, T)``.

    The flight plan's position alone (no attitude, no IMU), for callers that need only where the
    quadrotor is (e.g. :func:`home_gravity`).
    """
    return _design(plan, query_times(t, plan.origin.shape[0])).pos


def quadrotor_home_truth(plan: QuadrotorPlan, t: ArrayLike) -> tuple[Vec3, Vec3, Vec3]:
    """Position, velocity and attitude in the home NED tangent frame at times ``t``.

    The flight plan's flat outputs and the attitude ``C_b^{n0}`` by differential flatness
    (Mellinger & Kumar 2011), with no geodetic conversion: what :func:`quadrotor_trajectory`
    gives rotated back into the home frame (``v^{n0} = M^T v^n``, ``C_b^{n0} = M^T C_b^n``), to
    rounding. The attitude as 3-2-1 Euler angles of ``C_b^{n0}`` (Groves eq. 2.23, as
    :func:`navgym.ins.attitude.euler_from_dcm_entries`; ``C_ij`` is component i of body axis j).

    Returns:
        ``(position, velocity, (roll, pitch, yaw))``, each of three ``(B, T)`` arrays; yaw in
        (-pi, pi].
    """
    flat = _design(plan, query_times(t, plan.origin.shape[0]))
    (x_b, y_b, z_b), _ = _attitude_and_rate(flat)
    return flat.pos, flat.vel, euler_from_dcm_entries(x_b[0], x_b[1], x_b[2], y_b[2], z_b[2])


def quadrotor_leg_lengths(plan: QuadrotorPlan) -> NDArray[np.float64]:
    """Horizontal lengths of the three triangle sides HA, AB, BH [m], shape ``(B, 3)``."""
    v = plan.vertices[..., :2]
    return np.linalg.norm(v - np.roll(v, -1, axis=1), axis=-1)
