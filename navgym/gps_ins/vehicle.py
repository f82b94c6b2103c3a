"""Land vehicle or ship with heading and speed changes (Carvalho et al. 1997, §IV-D, §V), batched truth.

Carvalho et al. 1997 simulate "the vehicle movement" of a mobile whose steering direction Theta
(heading from north) is known to the INS (§IV-D) and whose longitude/latitude are corrupted by the INS
error model (eq. 12-14). Here an episode is a sequence of segments; within a segment the speed
goes from ``v_i`` to ``v_{i+1}`` and the heading from ``Theta_i`` to ``Theta_{i+1}`` along the
septic smootherstep (cruise segments keep both constant), so velocity, acceleration and turn rate
are continuous. Maneuver durations respect lateral and longitudinal acceleration limits.

The motion stays on the surface ``h = h_0`` of the ellipsoid (a ship at sea level, a car on flat
ground). Design arc lengths ``s_N(t) = int v cos(Theta)``, ``s_E(t) = int v sin(Theta)`` (by
16-point Gauss-Legendre quadrature within a segment, exact to rounding) map linearly to
latitude and longitude::

    lat = lat_0 + s_N / (R_M(lat_0) + h_0),   lon = lon_0 + s_E / ((R_N(lat_0) + h_0) cos lat_0)

and the truth velocity is the exact derivative of that position, ``v_N = (R_M(lat) + h) dlat/dt``,
``v_E = (R_N(lat) + h) cos(lat) dlon/dt`` (Groves eq. 2.111), so it differs from the design speed
by the relative change of the radii of curvature (below 1e-3 over 100 km). The body keeps zero
roll and pitch and its x axis along Theta; ``omega_nb^b = [0, 0, dTheta/dt]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo import E2, A, ecef_to_ned, geodetic_to_ecef, meridian_radius, normal_radius
from navgym.ins.attitude import yaw_to_dcm
from navgym.motion.profiles import (
    SMOOTHERSTEP_PEAK_RATE,
    gauss_legendre_partial,
    segment_index,
    smootherstep,
)
from navgym.motion.trajectory import Trajectory, make_trajectory, query_times
from navgym.scenarios.seeding import SeedsOrGenerators, as_generators
from navgym.scenarios.validation import (
    check_positive,
    check_probability,
    check_range,
)

__all__ = [
    "VehicleParams",
    "LAND_VEHICLE",
    "SHIP",
    "VehiclePlan",
    "sample_vehicle_plans",
    "vehicle_track",
    "vehicle_trajectory",
    "VehicleTrack",
]

_LONG = 1e7  # duration of the final cruise segment [s]


@dataclass(frozen=True)
class VehicleParams:
    """Distribution of vehicle/ship episodes.

    Attributes:
        duration: Episode length the plan must cover [s] (Carvalho et al. 1997, §V: 3600 s).
        speed: Range of the speed [m/s].
        cruise: Range of the cruise (straight, constant speed) segment durations [s].
        maneuver: Range of the maneuver segment durations before limits [s].
        turn_probability: Probability that a maneuver changes the heading.
        max_turn_deg: Largest heading change of one maneuver [deg].
        speed_change_probability: Probability that a maneuver changes the speed.
        max_lateral_accel: Lateral acceleration limit [m/s^2].
        max_longitudinal_accel: Longitudinal acceleration limit [m/s^2].
        origin_lat_deg: Range of the start latitude [deg].
        origin_lon_deg: Range of the start longitude [deg].
        origin_h: Range of the (constant) ellipsoidal height [m].

    """

    duration: float = 3600.0
    speed: tuple[float, float] = (5.0, 25.0)
    cruise: tuple[float, float] = (20.0, 120.0)
    maneuver: tuple[float, float] = (5.0, 20.0)
    turn_probability: float = 0.7
    max_turn_deg: float = 120.0
    speed_change_probability: float = 0.5
    max_lateral_accel: float = 3.0
    max_longitudinal_accel: float = 2.0
    origin_lat_deg: tuple[float, float] = (35.0, 60.0)
    origin_lon_deg: tuple[float, float] = (-10.0, 30.0)
    origin_h: tuple[float, float] = (0.0, 300.0)

    def __post_init__(self) -> None:
        check_positive("duration", self.duration)
        check_range("speed", self.speed, lower=0.0, lower_open=True)
        check_range("cruise", self.cruise, lower=0.0, lower_open=True)
        check_range("maneuver", self.maneuver, lower=0.0, lower_open=True)
        check_probability("turn_probability", self.turn_probability)
        if not 0.0 <= self.max_turn_deg <= 180.0:
            raise ValueError(f"max_turn_deg must lie in [0, 180], got {self.max_turn_deg!r}")
        check_probability("speed_change_probability", self.speed_change_probability)
        check_positive("max_lateral_accel", self.max_lateral_accel)
        check_positive("max_longitudinal_accel", self.max_longitudinal_accel)
        check_range("origin_lat_deg", self.origin_lat_deg, lower=-85.0, upper=85.0)
        check_range("origin_lon_deg", self.origin_lon_deg, lower=-180.0, upper=180.0)
        check_range("origin_h", self.origin_h, lower=-500.0, upper=9000.0)

    @property
    def max_segments(self) -> int:
        """Segments of every plan (padding included): fixed by the parameters, not the draw."""
        # cruise/maneuver pairs until the duration is covered, the final open segment, slack
        return 2 * int(np.ceil(self.duration / (self.cruise[0] + self.maneuver[0]))) + 3


#: Car on flat ground (5-25 m/s, 3 m/s^2 lateral).
LAND_VEHICLE = VehicleParams()
#: Ship at sea level (3-12 m/s, gentle turns).
SHIP = VehicleParams(
    speed=(3.0, 12.0),
    cruise=(60.0, 400.0),
    maneuver=(20.0, 90.0),
    max_turn_deg=90.0,
    max_lateral_accel=0.3,
    max_longitudinal_accel=0.1,
    origin_h=(0.0, 0.0),
)


class VehiclePlan(NamedTuple):
    """Sampled segment plans, batch axis first (``S = params.max_segments``).

    Attributes:
        origin: Start (lat [rad], lon [rad], h [m]), shape ``(B, 3)``.
        t_start: Segment start times [s] (``inf`` for padding), ``(B, S)``.
        duration: Segment durations [s], ``(B, S)``.
        speed_start: Speed at segment start [m/s], ``(B, S)``.
        speed_end: Speed at segment end, ``(B, S)``.
        heading_start: Heading at segment start [rad] (unwrapped), ``(B, S)``.
        heading_end: Heading at segment end, ``(B, S)``.
        arc_start: Design arc lengths (north, east) at segment start [m], ``(B, S, 2)``.

    """

    origin: NDArray[np.float64]
    t_start: NDArray[np.float64]
    duration: NDArray[np.float64]
    speed_start: NDArray[np.float64]
    speed_end: NDArray[np.float64]
    heading_start: NDArray[np.float64]
    heading_end: NDArray[np.float64]
    arc_start: NDArray[np.float64]


def _sample_one(rng: np.random.Generator, p: VehicleParams, n_seg: int) -> tuple:
    def uniform(lo: float, hi: float) -> float:
        # rng.uniform(lo, hi) bit for bit (NumPy draws lo + (hi - lo) * next_double), without
        # its per-call argument handling (most of the cost of a scalar draw)
        return lo + (hi - lo) * rng.random()

    lat0 = math.radians(uniform(*p.origin_lat_deg))
    lon0 = math.radians(uniform(*p.origin_lon_deg))
    h0 = uniform(*p.origin_h)
    heading = uniform(0.0, 2.0 * np.pi)
    speed = uniform(*p.speed)
    segs: list[tuple[float, float, float, float, float]] = []  # T, v0, v1, th0, th1
    t = 0.0
    while t < p.duration and len(segs) < n_seg - 1:
        d = uniform(*p.cruise)
        segs.append((d, speed, speed, heading, heading))
        t += d
        if t >= p.duration or len(segs) >= n_seg - 1:
            break
        new_heading = heading
        new_speed = speed
        if rng.random() < p.turn_probability:
            new_heading = heading + math.radians(uniform(-p.max_turn_deg, p.max_turn_deg))
        if rng.random() < p.speed_change_probability:
            new_speed = uniform(*p.speed)
        dv, dth = abs(new_speed - speed), abs(new_heading - heading)
        d = max(
            uniform(*p.maneuver),
            SMOOTHERSTEP_PEAK_RATE * dth * max(speed, new_speed) / p.max_lateral_accel,
            SMOOTHERSTEP_PEAK_RATE * dv / p.max_longitudinal_accel,
        )
        segs.append((d, speed, new_speed, heading, new_heading))
        t += d
        speed, heading = new_speed, new_heading
    segs.append((_LONG, speed, speed, heading, heading))
    n = len(segs)
    # padding segments: unit duration, final speed and heading, never started
    table = np.array(segs + [(1.0, speed, speed, heading, heading)] * (n_seg - n)).T  # (5, n_seg)
    t_start = np.full(n_seg, np.inf)
    t_start[0] = 0.0
    np.cumsum(table[0, : n - 1], out=t_start[1:n])
    return (np.array([lat0, lon0, h0]), t_start, *table)


def _speed_heading(plan_rows: tuple, tau_t: NDArray, order: int) -> tuple[NDArray, NDArray]:
    """Speed and heading (or their time derivatives for order 1) at local times ``tau_t``."""
    d, v0, v1, th0, th1 = plan_rows
    tau = tau_t / d
    s = smootherstep(tau, order)
    scale = 1.0 if order == 0 else 1.0 / d
    base_v = v0 if order == 0 else 0.0
    base_th = th0 if order == 0 else 0.0
    return base_v + (v1 - v0) * s * scale, base_th + (th1 - th0) * s * scale


#: Turning elements integrated per quadrature chunk in :func:`_arc` (keeps the
#: ``(chunk, 16)`` node arrays in cache).
_ARC_CHUNK = 1 << 12


def _arc(rows: tuple, elapsed: NDArray) -> NDArray:
    """Design arc lengths (north, east) covered ``elapsed`` seconds into the segments.

    ``s(t) = int_0^t v (cos th, sin th)``. Where the heading is constant over the segment
    (cruise, and maneuvers that only change the speed; most of an episode), it is closed form:
    ``v = v0 + (v1 - v0) S'(t / d)`` integrates to ``v0 t + (v1 - v0) d S(t / d)`` with the
    smootherstep antiderivative ``S`` (:func:`~navgym.motion.profiles.smootherstep`, order
    -1). Turning segments use 16-point Gauss-Legendre quadrature, which is exact to rounding for
    the polynomial case too (degree 8 < 32), evaluated in chunks so that the node arrays stay
    in cache.
    """
    elapsed = np.asarray(elapsed, np.float64)
    shape = elapsed.shape
    d, v0, v1, th0, th1 = (np.broadcast_to(r, shape).ravel() for r in rows)
    t = elapsed.ravel()
    dist = (v1 - v0) * d
    dist *= smootherstep(t / d, -1)
    dist += v0 * t
    out = np.stack([dist * np.cos(th0), dist * np.sin(th0)], axis=-1)  # (size, 2)
    turn = np.flatnonzero(th0 != th1)
    for k in range(0, turn.size, _ARC_CHUNK):
        i = turn[k : k + _ARC_CHUNK]
        out[i] = _arc_quadrature((d[i], v0[i], v1[i], th0[i], th1[i]), t[i])
    return out.reshape(*shape, 2)


def _arc_quadrature(rows: tuple, elapsed: NDArray) -> NDArray:
    """:func:`_arc` by quadrature for 1-D rows: ``(k, 2)``."""
    d, v0, v1, th0, th1 = (r[..., None] for r in rows)

    def integrand(x: NDArray) -> NDArray:
        v, th = _speed_heading((d, v0, v1, th0, th1), x, 0)
        return np.stack([v * np.cos(th), v * np.sin(th)], axis=0)  # (2, k, nodes)

    return np.moveaxis(gauss_legendre_partial(integrand, elapsed, leading=1), 0, -1)


def sample_vehicle_plans(
    seeds_or_rngs: SeedsOrGenerators, params: VehicleParams | None = None
) -> VehiclePlan:
    """Sample one segment plan per episode, each from its own generator.

    Args:
        seeds_or_rngs: Seeds or generators, one per episode.
        params: Distribution (defaults: :data:`LAND_VEHICLE`; :data:`SHIP` for a ship).

    Returns:
        The plans, batch axis first, padded to ``params.max_segments`` segments.

    """
    params = LAND_VEHICLE if params is None else params
    n_seg = params.max_segments
    rows = [_sample_one(rng, params, n_seg) for rng in as_generators(seeds_or_rngs)]
    origin, t_start, dur, v0, v1, th0, th1 = (np.stack([r[i] for r in rows]) for i in range(7))
    full = np.where(np.isfinite(t_start), dur, 0.0)
    full[np.arange(len(rows)), np.isfinite(t_start).sum(axis=1) - 1] = 0.0  # open last segment
    seg_arc = _arc((dur, v0, v1, th0, th1), full)
    arc_start = np.concatenate([np.zeros_like(seg_arc[:, :1]), np.cumsum(seg_arc, axis=1)[:, :-1]], 1)
    return VehiclePlan(origin, t_start, dur, v0, v1, th0, th1, arc_start)


def _radius_derivatives(lat: NDArray) -> tuple[NDArray, NDArray]:
    """dR_M/dlat and dR_N/dlat (from Groves eq. 2.105-2.106)."""
    s, c = np.sin(lat), np.cos(lat)
    den = 1.0 - E2 * s * s
    d_rm = 3.0 * A * (1.0 - E2) * E2 * s * c / den**2.5
    d_rn = A * E2 * s * c / den**1.5
    return d_rm, d_rn


def _track_geometry(plan: VehiclePlan, t: ArrayLike):
    """Times, segment rows, elapsed times, (lat, lon, h) and the origin terms of the plans at ``t``."""
    b = plan.origin.shape[0]
    t = query_times(t, b)
    i = segment_index(plan.t_start, t)

    def take(x: NDArray) -> NDArray:
        return np.take_along_axis(x, i, axis=1)

    rows = tuple(
        take(x)
        for x in (plan.duration, plan.speed_start, plan.speed_end, plan.heading_start, plan.heading_end)
    )
    elapsed = t - take(plan.t_start)
    arc = np.take_along_axis(plan.arc_start, i[..., None], axis=1) + _arc(rows, elapsed)
    lat0, lon0, h = (plan.origin[:, k : k + 1] for k in range(3))
    rm0 = meridian_radius(lat0) + h
    rn0c = (normal_radius(lat0) + h) * np.cos(lat0)
    lat = lat0 + arc[..., 0] / rm0
    lon = lon0 + arc[..., 1] / rn0c
    hh = np.broadcast_to(h, lat.shape)
    return t, rows, elapsed, (lat, lon, hh, h), (rm0, rn0c)


class VehicleTrack(NamedTuple):
    """What the GpsIns episodes use of the truth (:func:`vehicle_track`), shape ``(B, T, ...)``."""

    lat: NDArray[np.float64]  # [rad]
    lon: NDArray[np.float64]  # [rad]
    h: NDArray[np.float64]  # [m]
    heading: NDArray[np.float64]  # yaw of the body x axis [rad] in (-pi, pi]
    position_ned: NDArray[np.float64]  # (B, T, 3) from the origin [m]
    ecef: NDArray[np.float64]  # (B, T, 3) ECEF position [m]


def vehicle_track(plan: VehiclePlan, t: ArrayLike) -> VehicleTrack:
    """Position, heading and ECEF position of the plans at ``t``: :func:`vehicle_trajectory`'s values.

    ``lat``, ``lon``, ``h`` and ``position_ned`` are those of ``vehicle_trajectory(plan, t,
    imu=False)``, ``heading`` its ``trajectory_heading`` (``atan2`` of the attitude's ``sin`` and
    ``cos`` of the heading, the very numbers its DCM holds) and ``ecef`` the
    ``geodetic_to_ecef`` its NED position is formed from, bit for bit; without the velocity,
    acceleration, attitude matrices and turn rates the GpsIns episodes do not use (a third of
    the reset's trajectory time at B = 4096).
    """
    _, rows, elapsed, (lat, lon, hh, _), _ = _track_geometry(plan, t)
    _, th = _speed_heading(rows, elapsed, 0)
    heading = np.arctan2(np.sin(th), np.cos(th))
    ecef = geodetic_to_ecef(lat, lon, hh)
    o = plan.origin[:, None, :]
    position_ned = ecef_to_ned(ecef, o[..., 0], o[..., 1], o[..., 2])
    return VehicleTrack(lat, lon, hh, heading, position_ned, ecef)


def vehicle_trajectory(plan: VehiclePlan, t: ArrayLike, imu: bool = True) -> Trajectory:
    """Evaluate the vehicle truth at arbitrary times (whole episode or one step at a time).

    Args:
        plan: Plans of B episodes.
        t: Times [s]: scalar, ``(T,)`` shared, or ``(B, T)`` per episode.
        imu: Also compute the ideal IMU outputs (inverse mechanization); with False the
            trajectory's ``specific_force`` and ``angular_rate`` are None (the GpsIns
            environments simulate Carvalho et al. 1997's INS error model, not IMU samples).

    Returns:
        Truth :class:`~navgym.motion.trajectory.Trajectory`, shape ``(B, T, ...)``.

    """
    t, rows, elapsed, (lat, lon, hh, h), (rm0, rn0c) = _track_geometry(plan, t)
    v, th = _speed_heading(rows, elapsed, 0)
    vdot, thdot = _speed_heading(rows, elapsed, 1)

    c, s = np.cos(th), np.sin(th)
    sn_dot, se_dot = v * c, v * s
    sn_ddot = vdot * c - v * thdot * s
    se_ddot = vdot * s + v * thdot * c
    k_n = (meridian_radius(lat) + h) / rm0
    k_e = (normal_radius(lat) + h) * np.cos(lat) / rn0c
    d_rm, d_rn = _radius_derivatives(lat)
    lat_dot = sn_dot / rm0
    dk_n = d_rm / rm0 * lat_dot
    dk_e = (d_rn * np.cos(lat) - (normal_radius(lat) + h) * np.sin(lat)) / rn0c * lat_dot
    zeros = np.zeros_like(lat)
    v_ned = np.stack([sn_dot * k_n, se_dot * k_e, zeros], axis=-1)
    a_ned = np.stack([sn_ddot * k_n + sn_dot * dk_n, se_ddot * k_e + se_dot * dk_e, zeros], -1)
    C_b_n = yaw_to_dcm(c, s)  # level vehicle: roll = pitch = 0
    w_nb_b = np.stack([zeros, zeros, thdot], axis=-1)
    return make_trajectory(t, lat, lon, hh, None, v_ned, a_ned, C_b_n, w_nb_b, plan.origin, imu=imu)
