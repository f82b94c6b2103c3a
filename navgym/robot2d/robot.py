"""Car-like robot of Benzerrouk 2014, §2.7b-c, eq. 77: kinematic model, exact transition, truth generator.

Eq. 77 of Benzerrouk 2014 gives the motion of a point L of a car-like robot (Fig. 18) driven by
the speed ``v_c`` of the rear-axle centre and the steering angle ``alpha``, with wheelbase ``L``
and the point's offsets ``a`` (forward) and ``b`` (lateral) from the rear axle::

    dx_L/dt = v_c cos(phi) - v_c / L (a sin(phi) + b cos(phi)) tan(alpha)
    dy_L/dt = v_c sin(phi) + v_c / L (a cos(phi) - b sin(phi)) tan(alpha)
    dphi/dt = v_c / L tan(alpha)

This is the rigid-body form of Guivant & Nebot (IEEE T-RA 17(3), 2001, the Victoria Park car),
from which the model is taken. Benzerrouk 2014's transcription prints the second row as
``v_c sin(phi) - v_c / L (a cos(phi) + b sin(phi)) tan(alpha)``, which is not the velocity of a
point fixed to the body; it is available with ``as_printed=True``. Either way the point is
``L = c + offset(phi)``, with ``c`` the rear-axle centre (``dc/dt = v_c [cos phi, sin phi]``), so
constant inputs over a step integrate exactly along a circular arc (:func:`robot_transition`).

Axes: ``x`` north, ``y`` east, ``phi`` heading from north (clockwise seen from above), so the
compass measures ``phi``; positive steering ``alpha`` turns right. The wheel encoder sits at a
half-track ``H`` from the axle centre and measures ``v_e = v_c (1 - H tan(alpha) / L)``
(Guivant & Nebot 2001). In these axes that is the speed of the rear-right wheel, the inner wheel
of a right turn (the rear-left wheel runs at ``v_c (1 + H tan(alpha) / L)``). Benzerrouk 2014 (§2.7c)
says "back left wheel" after Guivant & Nebot, whose frame is the mirror image (``x`` east, ``y``
north, heading counter-clockwise, positive steering turns left), where the same formula is the
left, inner wheel. The formula is kept; only the wheel's name changes with the frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.motion.profiles import segment_index
from navgym.motion.trajectory import query_times
from navgym.scenarios.seeding import SeedsOrGenerators, as_generators
from navgym.scenarios.validation import check_positive, check_range

__all__ = [
    "RobotGeometry",
    "RobotParams",
    "RobotPlan",
    "RobotTrajectory",
    "robot_derivative",
    "robot_transition",
    "encoder_speed",
    "sample_robot_plans",
    "robot_trajectory",
]


@dataclass(frozen=True)
class RobotGeometry:
    """Geometry of eq. 77 (defaults: the Victoria Park car of Guivant & Nebot 2001).

    Attributes:
        wheelbase: L [m].
        a: Forward offset of the tracked point from the rear axle [m].
        b: Lateral offset of the tracked point [m].
        encoder_offset: Half-track H from the axle centre to the encoder wheel [m].

    """

    wheelbase: float = 2.83
    a: float = 3.78
    b: float = 0.50
    encoder_offset: float = 0.76

    def __post_init__(self) -> None:
        check_positive("wheelbase", self.wheelbase)
        for name in ("a", "b", "encoder_offset"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)!r}")


def _offset(phi: NDArray, g: RobotGeometry, as_printed: bool) -> NDArray:
    c, s = np.cos(phi), np.sin(phi)
    y = (-g.a * s + g.b * c) if as_printed else (g.a * s + g.b * c)
    return np.stack([g.a * c - g.b * s, y], axis=-1)


def robot_derivative(
    state: ArrayLike,
    v_c: ArrayLike,
    alpha: ArrayLike,
    geometry: RobotGeometry | None = None,
    *,
    as_printed: bool = False,
) -> NDArray[np.float64]:
    """Right-hand side of Benzerrouk 2014's eq. 77, ``d[x_L, y_L, phi]/dt``.

    Args:
        state: ``[x_L, y_L, phi]``, shape ``(..., 3)`` (only phi is used).
        v_c: Rear-axle speed [m/s], broadcastable with ``state[..., 0]``.
        alpha: Steering angle [rad].
        geometry: Vehicle geometry.
        as_printed: Use Benzerrouk 2014's printed second row instead of the rigid-body one.

    Returns:
        Derivatives, shape ``(..., 3)``.

    """
    g = RobotGeometry() if geometry is None else geometry
    phi = np.asarray(state, np.float64)[..., 2]
    v = np.asarray(v_c, np.float64)
    w = v / g.wheelbase * np.tan(np.asarray(alpha, np.float64))
    c, s = np.cos(phi), np.sin(phi)
    dx = v * c - w * (g.a * s + g.b * c)
    dy = v * s - w * (g.a * c + g.b * s) if as_printed else v * s + w * (g.a * c - g.b * s)
    return np.stack(np.broadcast_arrays(dx, dy, w * np.ones_like(phi)), axis=-1)


def robot_transition(
    state: ArrayLike,
    u: ArrayLike,
    dt: float,
    geometry: RobotGeometry | None = None,
    *,
    as_printed: bool = False,
) -> NDArray[np.float64]:
    """Exact discrete-time eq. 77 for inputs held constant over ``dt`` (a filter's ``f(x, u, dt)``).

    ``phi+ = phi + w dt``, ``c+ = c + v dt sinc(w dt / 2) [cos, sin](phi + w dt / 2)`` with
    ``w = v tan(alpha) / L`` and ``L_point = c + offset(phi)``. Broadcasts over leading axes, so
    sigma points ``(B, S, 3)`` and particles ``(B, N, 3)`` go through unchanged.

    Args:
        state: ``[x_L, y_L, phi]``, shape ``(..., 3)``.
        u: ``[v_c, alpha]``, shape ``(..., 2)`` broadcastable with the state.
        dt: Step [s].
        geometry: Vehicle geometry.
        as_printed: See :func:`robot_derivative`.

    Returns:
        Next state, shape ``(..., 3)``.

    """
    g = RobotGeometry() if geometry is None else geometry
    dt = check_positive("dt", dt)
    x = np.asarray(state, np.float64)
    u = np.asarray(u, np.float64)
    if x.shape[-1] != 3 or u.shape[-1] != 2:
        raise ValueError(f"state must be (..., 3) and u (..., 2), got {x.shape} and {u.shape}")
    phi, v = x[..., 2], u[..., 0]
    w = v / g.wheelbase * np.tan(u[..., 1])
    half = 0.5 * w * dt
    step = v * dt * np.sinc(half / np.pi)
    mid = phi + half
    phi_new = phi + w * dt
    c = x[..., :2] - _offset(phi, g, as_printed)
    c_new = c + step[..., None] * np.stack([np.cos(mid), np.sin(mid)], axis=-1)
    p_new = c_new + _offset(phi_new, g, as_printed)
    return np.concatenate([p_new, phi_new[..., None]], axis=-1)


def encoder_speed(
    v_c: ArrayLike, alpha: ArrayLike, geometry: RobotGeometry | None = None
) -> NDArray[np.float64]:
    """Speed seen by the wheel encoder, ``v_e = v_c (1 - H tan(alpha) / L)``.

    In this module's axes (``x`` north, ``y`` east, clockwise heading, ``alpha > 0`` turns right)
    this is the rear-right wheel; Benzerrouk 2014's "back left wheel" is the same wheel in Guivant &
    Nebot's mirrored frame (see the module docstring).
    """
    g = RobotGeometry() if geometry is None else geometry
    return np.asarray(v_c, np.float64) * (
        1.0 - g.encoder_offset * np.tan(np.asarray(alpha, np.float64)) / g.wheelbase
    )


@dataclass(frozen=True)
class RobotParams:
    """Distribution of robot drives (piecewise-constant speed and steering commands).

    Attributes:
        duration: Episode length the plan must cover [s].
        speed: Range of the commanded rear-axle speed [m/s].
        steering_deg: Range of the steering angle [deg].
        straight_probability: Probability that a command segment drives straight.
        segment: Range of command durations [s].
        geometry: Vehicle geometry.
        origin_lat_deg: Range of the local frame's origin latitude [deg].
        origin_lon_deg: Range of its longitude [deg].
        origin_h: Range of its ellipsoidal height [m].

    """

    duration: float = 300.0
    speed: tuple[float, float] = (0.5, 3.0)
    steering_deg: tuple[float, float] = (-25.0, 25.0)
    straight_probability: float = 0.3
    segment: tuple[float, float] = (2.0, 10.0)
    geometry: RobotGeometry = field(default_factory=RobotGeometry)
    origin_lat_deg: tuple[float, float] = (35.0, 60.0)
    origin_lon_deg: tuple[float, float] = (-10.0, 30.0)
    origin_h: tuple[float, float] = (0.0, 300.0)

    def __post_init__(self) -> None:
        check_positive("duration", self.duration)
        check_range("speed", self.speed, lower=0.0)
        check_range("steering_deg", self.steering_deg, lower=-80.0, upper=80.0)
        if not 0.0 <= self.straight_probability <= 1.0:
            raise ValueError(
                f"straight_probability must be a probability in [0, 1], got {self.straight_probability!r}"
            )
        check_range("segment", self.segment, lower=0.0, lower_open=True)
        check_range("origin_lat_deg", self.origin_lat_deg, lower=-89.0, upper=89.0)
        check_range("origin_lon_deg", self.origin_lon_deg, lower=-180.0, upper=180.0)
        check_range("origin_h", self.origin_h, lower=-500.0, upper=9000.0)

    @property
    def max_segments(self) -> int:
        """Command segments of every plan (fixed by the parameters)."""
        return int(np.ceil(self.duration / self.segment[0])) + 2


class RobotPlan(NamedTuple):
    """Piecewise-constant commands, batch axis first (``S = params.max_segments``).

    Attributes:
        origin: Origin of the local (x north, y east) frame: lat, lon [rad], h [m], ``(B, 3)``.
        t_start: Command start times [s] (the last one stays active), ``(B, S)``.
        v_c: Rear-axle speed [m/s], ``(B, S)``.
        alpha: Steering angle [rad], ``(B, S)``.
        c_start: Rear-axle centre at command start [m], ``(B, S, 2)``.
        phi_start: Heading at command start [rad], ``(B, S)``.

    """

    origin: NDArray[np.float64]
    t_start: NDArray[np.float64]
    v_c: NDArray[np.float64]
    alpha: NDArray[np.float64]
    c_start: NDArray[np.float64]
    phi_start: NDArray[np.float64]


class RobotTrajectory(NamedTuple):
    """Robot truth, batch axis first.

    Attributes:
        t: Times [s], ``(B, T)``.
        position: Point L (x north, y east) [m], ``(B, T, 2)``.
        heading: phi [rad] (unwrapped), ``(B, T)``.
        v_c: Rear-axle speed command in effect [m/s], ``(B, T)``.
        alpha: Steering angle in effect [rad], ``(B, T)``.
        origin: Local frame origin (lat, lon, h), ``(B, 3)``.

    """

    t: NDArray[np.float64]
    position: NDArray[np.float64]
    heading: NDArray[np.float64]
    v_c: NDArray[np.float64]
    alpha: NDArray[np.float64]
    origin: NDArray[np.float64]


def _arc(v: NDArray, w: NDArray, phi: NDArray, tau: NDArray) -> NDArray:
    """Rear-axle displacement after ``tau`` seconds at constant speed ``v`` and yaw rate ``w``."""
    half = 0.5 * w * tau
    step = v * tau * np.sinc(half / np.pi)
    return step[..., None] * np.stack([np.cos(phi + half), np.sin(phi + half)], axis=-1)


def sample_robot_plans(seeds_or_rngs: SeedsOrGenerators, params: RobotParams | None = None) -> RobotPlan:
    """Sample one command sequence per episode, each from its own generator.

    The robot starts at the origin of its local frame (rear-axle centre at ``-offset(phi_0)``
    so that the tracked point L is at (0, 0)) with a uniform heading.

    Args:
        seeds_or_rngs: Seeds or generators, one per episode.
        params: Distribution (defaults: :class:`RobotParams`).

    Returns:
        The plans, batch axis first.

    """
    p = RobotParams() if params is None else params
    n = p.max_segments
    rows = []
    for rng in as_generators(seeds_or_rngs):
        origin = np.array(
            [
                np.deg2rad(rng.uniform(*p.origin_lat_deg)),
                np.deg2rad(rng.uniform(*p.origin_lon_deg)),
                rng.uniform(*p.origin_h),
            ]
        )
        phi0 = rng.uniform(-np.pi, np.pi)
        dur = rng.uniform(*p.segment, size=n)
        v = rng.uniform(*p.speed, size=n)
        alpha = np.deg2rad(rng.uniform(*p.steering_deg, size=n))
        alpha[rng.uniform(size=n) < p.straight_probability] = 0.0
        rows.append((origin, phi0, dur, v, alpha))
    origin = np.stack([r[0] for r in rows])
    phi0 = np.array([r[1] for r in rows])
    dur, v, alpha = (np.stack([r[k] for r in rows]) for k in (2, 3, 4))
    g = p.geometry
    w = v / g.wheelbase * np.tan(alpha)
    t_start = np.concatenate([np.zeros((len(rows), 1)), np.cumsum(dur[:, :-1], axis=1)], axis=1)
    phi_start = phi0[:, None] + np.concatenate(
        [np.zeros((len(rows), 1)), np.cumsum(w[:, :-1] * dur[:, :-1], axis=1)], axis=1
    )
    c0 = -_offset(phi0, g, False)
    steps = _arc(v[:, :-1], w[:, :-1], phi_start[:, :-1], dur[:, :-1])
    c_start = c0[:, None, :] + np.concatenate([np.zeros((len(rows), 1, 2)), np.cumsum(steps, axis=1)], axis=1)
    return RobotPlan(origin, t_start, v, alpha, c_start, phi_start)


def robot_trajectory(
    plan: RobotPlan,
    t: ArrayLike,
    geometry: RobotGeometry | None = None,
    *,
    as_printed: bool = False,
) -> RobotTrajectory:
    """Evaluate the robot truth at arbitrary times (exact solution of eq. 77).

    Args:
        plan: Command plans of B episodes.
        t: Times [s]: scalar, ``(T,)`` shared, or ``(B, T)`` per episode.
        geometry: Vehicle geometry (must be the one the plan was sampled with).
        as_printed: Track the point of Benzerrouk 2014's printed eq. 77 (see the module docstring).

    Returns:
        :class:`RobotTrajectory` of shape ``(B, T, ...)``.

    """
    g = RobotGeometry() if geometry is None else geometry
    b = plan.origin.shape[0]
    t = query_times(t, b)
    i = segment_index(plan.t_start, t)

    def take(x: NDArray) -> NDArray:
        return np.take_along_axis(x, i, axis=1)

    v, alpha, phi0 = take(plan.v_c), take(plan.alpha), take(plan.phi_start)
    tau = t - take(plan.t_start)
    w = v / g.wheelbase * np.tan(alpha)
    c = np.take_along_axis(plan.c_start, i[..., None], axis=1) + _arc(v, w, phi0, tau)
    phi = phi0 + w * tau
    # the plan stores the rigid-body rear-axle track; the printed variant differs only in the
    # point attached to it, and both start from L = (0, 0) up to that constant
    pos = c + _offset(phi, g, as_printed)
    if as_printed:
        p0 = plan.phi_start[:, :1]
        pos = pos - (-_offset(p0, g, False) + _offset(p0, g, True))
    return RobotTrajectory(t, pos, phi, v, alpha, plan.origin)
