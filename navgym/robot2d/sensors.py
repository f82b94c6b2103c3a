"""Sensor schedules and measurement generators of the platforms (position fixes, compass, odometry).

In Benzerrouk 2014 (§2.7c) the robot fuses GPS at 10 Hz, GLONASS at 5 Hz and an electronic
compass at 5 Hz with a rear-wheel encoder. Schedules are defined on the step index ``k`` of a
fixed-step simulation (``k = 0`` at the episode start): a sensor of rate ``r`` reports at the
steps with ``k % (1 / (r dt)) == 0``, which requires ``1 / (r dt)`` to be an integer.

Measurement functions are pure: they take the standard normals as an argument (``noise``), so a
whole episode (normals from :func:`~navgym.scenarios.seeding.standard_normal_batch`) and one step
at a time (normals from a :class:`~navgym.scenarios.seeding.NormalStream`) give the same numbers.
Noise levels are not given in Benzerrouk 2014; the defaults of :class:`RobotSensorNoise` are
typical values (stand-alone GNSS a few metres, MEMS compass a few degrees) and are arguments.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.robot2d.robot import RobotGeometry, RobotTrajectory, encoder_speed
from navgym.scenarios.seeding import standard_normal_batch
from navgym.scenarios.validation import check_nonnegative, check_positive

__all__ = [
    "GPS_RATE_HZ",
    "GLONASS_RATE_HZ",
    "COMPASS_RATE_HZ",
    "schedule_stride",
    "measurement_schedule",
    "is_measurement_step",
    "position_fixes",
    "RobotSensorNoise",
    "RobotMeasurements",
    "ROBOT_NOISE_WIDTH",
    "robot_measurements",
    "simulate_robot_measurements",
]

#: Sensor rates of Benzerrouk 2014, §2.7c [Hz].
GPS_RATE_HZ = 10.0
GLONASS_RATE_HZ = 5.0
COMPASS_RATE_HZ = 5.0


def schedule_stride(dt: float, rate_hz: float) -> int:
    """Steps between two reports of a sensor of rate ``rate_hz`` in a simulation of step ``dt``.

    Raises:
        ValueError: If ``1 / (rate_hz dt)`` is not a positive integer.

    """
    dt = check_positive("dt", dt)
    rate_hz = check_positive("rate_hz", rate_hz)
    stride = 1.0 / (rate_hz * dt)
    k = int(round(stride))
    if k < 1 or abs(stride - k) > 1e-9 * stride:
        raise ValueError(f"rate_hz must divide the simulation rate 1/dt = {1.0 / dt:g} Hz, got {rate_hz:g}")
    return k


def measurement_schedule(n_steps: int, dt: float, rate_hz: float) -> NDArray[np.bool_]:
    """Boolean schedule ``(n_steps,)``: True at the steps where the sensor reports."""
    if int(n_steps) < 0:
        raise ValueError(f"n_steps must be >= 0, got {n_steps!r}")
    return np.arange(int(n_steps)) % schedule_stride(dt, rate_hz) == 0


def is_measurement_step(step: ArrayLike, dt: float, rate_hz: float) -> NDArray[np.bool_]:
    """Whether a sensor reports at step index ``step`` (any integer array, e.g. ``(B,)``)."""
    return np.asarray(step) % schedule_stride(dt, rate_hz) == 0


def position_fixes(position: ArrayLike, sigma: ArrayLike, noise: ArrayLike) -> NDArray[np.float64]:
    """Position fixes ``z = p + sigma n`` (loosely coupled GNSS output; Benzerrouk 2014, eq. 12/14).

    Args:
        position: True positions, shape ``(B, T, d)``.
        sigma: Noise standard deviation [m], broadcastable to ``(B, T)`` (e.g. a per-step
            scale from a scenario's noise regime).
        noise: Standard normals, shape ``(B, T, d)``.

    Returns:
        Noisy positions, shape ``(B, T, d)``.

    """
    p = np.asarray(position, np.float64)
    n = np.asarray(noise, np.float64)
    if n.shape != p.shape:
        raise ValueError(f"noise must have shape {p.shape}, got {n.shape}")
    s = np.asarray(sigma, np.float64)
    if np.any(s < 0) or not np.all(np.isfinite(s)):
        raise ValueError("sigma must be finite and non-negative")
    return p + np.broadcast_to(s, p.shape[:-1])[..., None] * n


@dataclass(frozen=True)
class RobotSensorNoise:
    """1-sigma noise of the robot's sensors (assumed values; Benzerrouk 2014 gives none).

    Attributes:
        gps: GPS position noise per axis [m].
        glonass: GLONASS position noise per axis [m].
        compass_deg: Compass heading noise [deg].
        encoder: Wheel-encoder speed noise [m/s].
        steering_deg: Steering-angle sensor noise [deg].

    """

    gps: float = 3.0
    glonass: float = 5.0
    compass_deg: float = 2.0
    encoder: float = 0.05
    steering_deg: float = 0.5

    def __post_init__(self) -> None:
        for name in ("gps", "glonass", "compass_deg", "encoder", "steering_deg"):
            check_nonnegative(name, getattr(self, name))


class RobotMeasurements(NamedTuple):
    """Robot sensor outputs at each step with their availability, batch axis first.

    Attributes:
        gps: GPS fix of point L (x north, y east) [m], ``(B, T, 2)``.
        gps_mask: Whether the GPS reported, ``(B, T)``.
        glonass: GLONASS fix [m], ``(B, T, 2)``.
        glonass_mask: ``(B, T)``.
        compass: Heading [rad] wrapped to [-pi, pi), ``(B, T)``.
        compass_mask: ``(B, T)``.
        encoder: Rear-right wheel speed [m/s] (every step), ``(B, T)``: Benzerrouk 2014's "back
            left" wheel, named in Guivant & Nebot's mirrored frame (see
            :func:`~navgym.robot2d.robot.encoder_speed`).
        steering: Steering angle [rad] (every step), ``(B, T)``.

    """

    gps: NDArray[np.float64]
    gps_mask: NDArray[np.bool_]
    glonass: NDArray[np.float64]
    glonass_mask: NDArray[np.bool_]
    compass: NDArray[np.float64]
    compass_mask: NDArray[np.bool_]
    encoder: NDArray[np.float64]
    steering: NDArray[np.float64]


#: Standard normals per step and episode: gps (2), glonass (2), compass, encoder, steering.
ROBOT_NOISE_WIDTH = 7


def robot_measurements(
    traj: RobotTrajectory,
    step: ArrayLike,
    noise: ArrayLike,
    dt: float,
    *,
    geometry: RobotGeometry | None = None,
    sensors: RobotSensorNoise | None = None,
    rates_hz: tuple[float, float, float] = (GPS_RATE_HZ, GLONASS_RATE_HZ, COMPASS_RATE_HZ),
) -> RobotMeasurements:
    """Robot measurements at given steps from given standard normals (pure).

    Args:
        traj: Robot truth, shape ``(B, T)``.
        step: Step indices since the episode start, broadcastable to ``(B, T)``.
        noise: Standard normals ``(B, T, 7)`` (order as :data:`ROBOT_NOISE_WIDTH` says).
        dt: Simulation step [s].
        geometry: Vehicle geometry (for the encoder).
        sensors: Noise levels.
        rates_hz: GPS, GLONASS and compass rates (Benzerrouk 2014: 10, 5, 5 Hz).

    Returns:
        :class:`RobotMeasurements`; values are produced at every step, masks say which ones a
        real sensor would deliver.

    """
    sensors = RobotSensorNoise() if sensors is None else sensors
    z = np.asarray(noise, np.float64)
    shape = traj.heading.shape
    if z.shape != shape + (ROBOT_NOISE_WIDTH,):
        raise ValueError(f"noise must have shape {shape + (ROBOT_NOISE_WIDTH,)}, got {z.shape}")
    k = np.broadcast_to(np.asarray(step), shape)
    deg = np.pi / 180.0
    compass = traj.heading + sensors.compass_deg * deg * z[..., 4]
    return RobotMeasurements(
        gps=position_fixes(traj.position, sensors.gps, z[..., 0:2]),
        gps_mask=is_measurement_step(k, dt, rates_hz[0]),
        glonass=position_fixes(traj.position, sensors.glonass, z[..., 2:4]),
        glonass_mask=is_measurement_step(k, dt, rates_hz[1]),
        compass=np.mod(compass + np.pi, 2.0 * np.pi) - np.pi,
        compass_mask=is_measurement_step(k, dt, rates_hz[2]),
        encoder=encoder_speed(traj.v_c, traj.alpha, geometry) + sensors.encoder * z[..., 5],
        steering=traj.alpha + sensors.steering_deg * deg * z[..., 6],
    )


def simulate_robot_measurements(
    traj: RobotTrajectory,
    dt: float,
    rngs: Sequence[np.random.Generator],
    *,
    geometry: RobotGeometry | None = None,
    sensors: RobotSensorNoise | None = None,
) -> RobotMeasurements:
    """Measurements of whole episodes sampled at ``traj.t = k dt`` (k = 0..T-1).

    Args:
        traj: Robot truth at the simulation steps, shape ``(B, T)``.
        dt: Simulation step [s].
        rngs: One generator per episode; each draws ``(T, 7)`` standard normals.
        geometry: Vehicle geometry.
        sensors: Noise levels.

    Returns:
        :class:`RobotMeasurements`.

    """
    b, n = traj.heading.shape
    if len(rngs) != b:
        raise ValueError(f"rngs must hold {b} generators, got {len(rngs)}")
    noise = standard_normal_batch(rngs, (n, ROBOT_NOISE_WIDTH))
    return robot_measurements(traj, np.arange(n)[None, :], noise, dt, geometry=geometry, sensors=sensors)
