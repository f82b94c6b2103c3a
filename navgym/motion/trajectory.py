"""The truth container shared by the 3-D platforms and helpers to use it step by step."""

from __future__ import annotations

from typing import NamedTuple, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo import ecef_to_ned, geodetic_to_ecef
from navgym.ins.attitude import dcm_to_yaw
from navgym.ins.inverse_mechanization import imu_from_kinematics
from navgym.ins.types import ImuSample, NavState

__all__ = [
    "Trajectory",
    "make_trajectory",
    "query_times",
    "midpoint_times",
    "trajectory_heading",
    "trajectory_ecef",
    "nav_state_at",
    "ideal_imu",
    "replace_episodes",
]


class Trajectory(NamedTuple):
    """Truth kinematics of B episodes at T times (batch axis first, SI units, radians).

    Attributes:
        t: Times [s] since the episode start, shape ``(B, T)``.
        lat: Geodetic latitude, shape ``(B, T)``.
        lon: Longitude, shape ``(B, T)``.
        h: Height above the WGS-84 ellipsoid [m], shape ``(B, T)``.
        position_ned: Offset from the episode's origin in the origin's local NED tangent frame
            [m], shape ``(B, T, 3)``.
        v_ned: Velocity over the Earth in local NED axes [m/s], shape ``(B, T, 3)``.
        a_ned: Time derivative of ``v_ned`` [m/s^2], shape ``(B, T, 3)``.
        C_b_n: Body-to-local-NED DCM, shape ``(B, T, 3, 3)``.
        omega_nb_b: Body rate relative to local NED, body axes [rad/s], shape ``(B, T, 3)``.
        specific_force: Error-free accelerometer output f_ib^b [m/s^2], shape ``(B, T, 3)``.
        angular_rate: Error-free gyro output omega_ib^b [rad/s], shape ``(B, T, 3)``.
        origin: Episode origin (lat [rad], lon [rad], h [m]), shape ``(B, 3)``.

    """

    t: NDArray[np.float64]
    lat: NDArray[np.float64]
    lon: NDArray[np.float64]
    h: NDArray[np.float64]
    position_ned: NDArray[np.float64]
    v_ned: NDArray[np.float64]
    a_ned: NDArray[np.float64]
    C_b_n: NDArray[np.float64]
    omega_nb_b: NDArray[np.float64]
    specific_force: NDArray[np.float64]
    angular_rate: NDArray[np.float64]
    origin: NDArray[np.float64]


def query_times(t: ArrayLike, batch: int) -> NDArray[np.float64]:
    """Broadcast query times to ``(B, T)``: a scalar, ``(T,)`` shared, or ``(B, T)`` per episode.

    Raises:
        ValueError: If ``t`` is not finite or cannot be broadcast to the batch.

    """
    t = np.asarray(t, np.float64)
    if t.ndim == 0:
        t = t.reshape(1, 1)
    elif t.ndim == 1:
        t = t[None, :]
    if t.ndim != 2 or t.shape[0] not in (1, batch):
        raise ValueError(f"t must be a scalar, (T,) or ({batch}, T), got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("t must be finite")
    return np.broadcast_to(t, (batch, t.shape[1]))


def midpoint_times(n_steps: int, dt: float, t0: float = 0.0) -> NDArray[np.float64]:
    """Mid-interval times ``t0 + (k + 1/2) dt``, k = 0..n_steps-1, where IMU samples are taken."""
    return t0 + (np.arange(int(n_steps)) + 0.5) * float(dt)


def make_trajectory(
    t: NDArray,
    lat: NDArray,
    lon: NDArray,
    h: NDArray,
    position_ned: NDArray | None,
    v_ned: NDArray,
    a_ned: NDArray,
    C_b_n: NDArray,
    omega_nb_b: NDArray,
    origin: NDArray,
    imu: bool = True,
) -> Trajectory:
    """Assemble a :class:`Trajectory`, adding the ideal IMU outputs (inverse mechanization).

    ``position_ned=None`` computes it from (lat, lon, h) and the origin through ECEF.
    ``imu=False`` skips the inverse mechanization (``specific_force`` and ``angular_rate``
    are None).
    """
    if position_ned is None:
        o = origin[:, None, :]
        position_ned = ecef_to_ned(geodetic_to_ecef(lat, lon, h), o[..., 0], o[..., 1], o[..., 2])
    f_ib = w_ib = None
    if imu:
        out = imu_from_kinematics(lat, h, v_ned, a_ned, C_b_n, omega_nb_b)
        f_ib, w_ib = out.specific_force, out.angular_rate
    return Trajectory(t, lat, lon, h, position_ned, v_ned, a_ned, C_b_n, omega_nb_b, f_ib, w_ib, origin)


def trajectory_heading(traj: Trajectory) -> NDArray[np.float64]:
    """Yaw (heading from north) of the body x axis [rad], shape ``(B, T)``."""
    return dcm_to_yaw(traj.C_b_n)


def trajectory_ecef(traj: Trajectory) -> NDArray[np.float64]:
    """ECEF positions [m], shape ``(B, T, 3)``."""
    return geodetic_to_ecef(traj.lat, traj.lon, traj.h)


def nav_state_at(traj: Trajectory, k: int = 0) -> NavState:
    """The true :class:`~navgym.ins.types.NavState` at time index ``k`` (e.g. to start an INS)."""
    return NavState(
        traj.lat[:, k].copy(),
        traj.lon[:, k].copy(),
        traj.h[:, k].copy(),
        traj.v_ned[:, k].copy(),
        traj.C_b_n[:, k].copy(),
    )


def ideal_imu(traj: Trajectory) -> ImuSample:
    """The error-free IMU samples of a trajectory evaluated at interval midpoints."""
    return ImuSample(traj.specific_force, traj.angular_rate)


_T = TypeVar("_T", bound=tuple)


def replace_episodes(batch: _T, index: ArrayLike, new: _T) -> _T:
    """Return ``batch`` with the episodes ``index`` replaced by the rows of ``new``.

    Works for any NamedTuple of batch-first arrays (plans, scenario batches), e.g. to resample
    the finished sub-environments of a vector environment on autoreset.

    Args:
        batch: NamedTuple whose array fields have the batch axis first.
        index: Episode indices, shape ``(n,)``.
        new: NamedTuple of the same type with ``n`` episodes.

    Returns:
        A new NamedTuple (inputs are not modified).

    """
    idx = np.asarray(index, dtype=np.intp)
    fields = {}
    for name, old, repl in zip(batch._fields, batch, new, strict=True):
        if isinstance(old, np.ndarray):
            arr = old.copy()
            arr[idx] = repl
            fields[name] = arr
        else:
            fields[name] = old
    return type(batch)(**fields)
