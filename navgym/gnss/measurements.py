"""GNSS measurement models: pseudo-range and delta-range (range rate), batched.

Shapes: receivers ``(B, 3)`` (or ``(B, 1, 3)``), satellites ``(B, m, 3)``; results ``(B, m)``.
All functions are pure and vectorized (also over particles/sigma points: any leading axes).

Earth rotation (Sagnac) handling. Satellite states are evaluated at the *receive* time t in
the ECEF frame of t. The signal left the satellite at ``t - tau`` (tau = rho / c, ~70 ms),
when the satellite was at ``r_s(t) - v_s tau`` in the ECEF frame of ``t - tau``; during the
flight the Earth turned by ``omega_e tau``. Rotating that position into the ECEF frame of t
adds, to first order, ``omega_e (x_s y - y_s x) / c`` to the range (IS-GPS-200 §20.3.3.4.3.3.2;
Kaplan & Hegarty 2nd ed. §7.2.2.4; RTKLIB ``geodist``). Together these terms are up to ~300 m
(light time) and ~30 m (Sagnac); the first-order light-time step leaves below 1 mm.
Receivers that compute satellite positions at transmit time (as :mod:`navgym.gnss.spp`
does) add only the Sagnac term, see :func:`sagnac_correction`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.wgs84 import C_LIGHT, OMEGA_E
from navgym.gnss.orbit import ecef_acceleration

__all__ = [
    "sagnac_correction",
    "geometric_range",
    "pseudorange",
    "range_rate",
    "delta_range",
    "range_and_rate",
]


def _xyz(a: ArrayLike, name: str) -> NDArray[np.float64]:
    """Component-first view ``(3, ...)`` of an ``(..., 3)`` array (no copy)."""
    arr = np.asarray(a, np.float64)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3), got {arr.shape}")
    return np.moveaxis(arr, -1, 0)


def _norm(dx, dy, dz):
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def sagnac_correction(rx_ecef: ArrayLike, sat_ecef: ArrayLike) -> NDArray[np.float64]:
    """Earth-rotation (Sagnac) range correction ``omega_e (x_s y_r - y_s x_r) / c`` [m].

    Args:
        rx_ecef: Receiver ECEF position(s) [m], ``(..., 3)``.
        sat_ecef: Satellite ECEF position(s) at transmission time [m], ``(..., 3)``.

    Returns:
        Correction to add to ``|r_s - r|``, broadcast shape without the last axis.
    """
    r = _xyz(rx_ecef, "rx_ecef")
    s = _xyz(sat_ecef, "sat_ecef")
    return OMEGA_E / C_LIGHT * (s[0] * r[1] - s[1] * r[0])


def geometric_range(
    rx_ecef: ArrayLike,
    sat_pos: ArrayLike,
    sat_vel: ArrayLike | None = None,
    earth_rotation: bool = True,
) -> NDArray[np.float64]:
    """Range from satellite (at signal transmission) to receiver (at reception) [m].

    Carvalho et al. 1997, eq. 10 / eq. 15 ``h``, Touil & Ghadi 2012, eq. 5: ``|r_s - r|``; with
    ``earth_rotation`` (default) the satellite is moved back by the light time,
    ``r_s - v_s |r_s - r| / c``, and the Sagnac term is added (see the module docstring).
    ``earth_rotation=False`` gives the papers' plain Euclidean distance between simultaneous
    positions.

    Args:
        rx_ecef: Receiver ECEF position [m], ``(..., 3)`` (e.g. ``(B, 1, 3)``).
        sat_pos: Satellite ECEF position at the receive time [m], ``(..., 3)`` (``(B, m, 3)``).
        sat_vel: Satellite ECEF velocity [m/s], like ``sat_pos`` (needed for the light time).
        earth_rotation: Apply light-time and Sagnac terms.

    Returns:
        Ranges [m], broadcast shape without the last axis.
    """
    r = _xyz(rx_ecef, "rx_ecef")
    s = _xyz(sat_pos, "sat_pos")
    rho = _norm(s[0] - r[0], s[1] - r[1], s[2] - r[2])
    if not earth_rotation:
        return rho
    if sat_vel is None:
        raise ValueError("sat_vel is required with earth_rotation=True")
    v = _xyz(sat_vel, "sat_vel")
    tau = rho / C_LIGHT
    sx, sy, sz = s[0] - v[0] * tau, s[1] - v[1] * tau, s[2] - v[2] * tau
    return _norm(sx - r[0], sy - r[1], sz - r[2]) + OMEGA_E / C_LIGHT * (sx * r[1] - sy * r[0])


def pseudorange(
    rx_ecef: ArrayLike,
    sat_pos: ArrayLike,
    sat_vel: ArrayLike | None,
    clock_bias_m: ArrayLike,
    atmosphere_m: ArrayLike = 0.0,
    earth_rotation: bool = True,
) -> NDArray[np.float64]:
    """Noise-free pseudo-range (Carvalho et al. 1997, eq. 10; Touil & Ghadi 2012, eq. 5).

    ``rho_i = |r_s,i - r| + c dtau + Delta_atm,i`` with the range of :func:`geometric_range`.
    The satellite clock error is taken as corrected from the navigation message (Carvalho et al.
    1997, §IV-C-2). Carvalho et al. 1997, eq. 15 write the receiver clock with the opposite sign
    (``- c delta``); here ``clock_bias_m`` is ``+c dtau``.

    Args:
        rx_ecef: Receiver ECEF position [m], ``(B, 1, 3)`` or ``(..., 3)``.
        sat_pos: Satellite positions at receive time [m], ``(B, m, 3)``.
        sat_vel: Satellite velocities [m/s], ``(B, m, 3)`` (None if ``earth_rotation=False``).
        clock_bias_m: Receiver clock bias c dtau [m], broadcastable (``(B, 1)``).
        atmosphere_m: Atmospheric delay Delta_atm [m], broadcastable (``(B, m)``).
        earth_rotation: See :func:`geometric_range`.

    Returns:
        Pseudo-ranges [m], ``(B, m)``.
    """
    rho = geometric_range(rx_ecef, sat_pos, sat_vel, earth_rotation)
    return rho + np.asarray(clock_bias_m, np.float64) + np.asarray(atmosphere_m, np.float64)


def range_rate(
    rx_ecef: ArrayLike,
    rx_vel: ArrayLike,
    sat_pos: ArrayLike,
    sat_vel: ArrayLike,
    earth_rotation: bool = True,
) -> NDArray[np.float64]:
    """Range rate R_i between satellite and receiver [m/s] (Touil & Ghadi 2012, eq. 7).

    ``R_i = (r_s - r) . (v_s - v) / |r_s - r|`` with ECEF positions and velocities; this is
    ``earth_rotation=False``. With ``earth_rotation`` (default) it is the time derivative of
    :func:`geometric_range`: the satellite state is taken at transmission,
    ``r_s - v_s tau`` and ``v_s - a_s tau`` with the ECEF acceleration
    ``a_s = -mu r_s / |r_s|^3 - 2 Omega x v_s - Omega x (Omega x r_s)``, both are rotated by
    ``omega_e tau`` into the receive-time frame, and the rate of the flight time
    ``tau_dot = R_i / c`` enters as ``R_i (1 + (u.v_s - omega_e u.(y_s, -x_s, 0)) / c) =
    u.(v_s - v)`` (these terms reach a few cm/s).

    Args:
        rx_ecef: Receiver position [m], ``(..., 3)``.
        rx_vel: Receiver ECEF velocity [m/s], like ``rx_ecef``.
        sat_pos: Satellite position at the receive time [m], ``(..., 3)``.
        sat_vel: Satellite ECEF velocity at the receive time [m/s], like ``sat_pos``.
        earth_rotation: Light-time and Earth-rotation terms as above.

    Returns:
        Range rates [m/s], broadcast shape without the last axis.
    """
    r = _xyz(rx_ecef, "rx_ecef")
    v = _xyz(rx_vel, "rx_vel")
    sx, sy, sz = _xyz(sat_pos, "sat_pos")
    vx, vy, vz = _xyz(sat_vel, "sat_vel")
    if earth_rotation:
        tau = _norm(sx - r[0], sy - r[1], sz - r[2]) / C_LIGHT
        ax, ay, az = np.moveaxis(ecef_acceleration(np.asarray(sat_pos), np.asarray(sat_vel)), -1, 0)
        sx, sy, sz = sx - vx * tau, sy - vy * tau, sz - vz * tau
        vx, vy, vz = vx - ax * tau, vy - ay * tau, vz - az * tau
        th = OMEGA_E * tau
        sx, sy = sx + th * sy, sy - th * sx
        vx, vy = vx + th * vy, vy - th * vx
        dx, dy, dz = sx - r[0], sy - r[1], sz - r[2]
        rho = _norm(dx, dy, dz)
        # d rho/dt = u.(v_s (1 - tau_dot) + omega_e tau_dot (y_s, -x_s, 0) - v), tau_dot = rate/c
        a_sat = (dx * vx + dy * vy + dz * vz) / rho
        a_rx = (dx * v[0] + dy * v[1] + dz * v[2]) / rho
        c_rot = OMEGA_E * (dx * sy - dy * sx) / rho
        return (a_sat - a_rx) / (1.0 + (a_sat - c_rot) / C_LIGHT)
    dx, dy, dz = sx - r[0], sy - r[1], sz - r[2]
    return (dx * (vx - v[0]) + dy * (vy - v[1]) + dz * (vz - v[2])) / _norm(dx, dy, dz)


def delta_range(
    rx_ecef: ArrayLike,
    rx_vel: ArrayLike,
    sat_pos: ArrayLike,
    sat_vel: ArrayLike,
    clock_drift_mps: ArrayLike,
    earth_rotation: bool = True,
) -> NDArray[np.float64]:
    """Noise-free delta-range (Doppler) measurement (Touil & Ghadi 2012, eq. 6).

    ``Delta rho_i = R_i + b_dot`` with R_i from :func:`range_rate` and the receiver clock
    drift ``b_dot = c d(dtau)/dt`` [m/s]; the L1 Doppler is ``-Delta rho / lambda_L1``.

    Args:
        rx_ecef: Receiver position [m], ``(..., 3)``.
        rx_vel: Receiver ECEF velocity [m/s].
        sat_pos: Satellite position [m].
        sat_vel: Satellite ECEF velocity [m/s].
        clock_drift_mps: Receiver clock drift times c [m/s], broadcastable (``(B, 1)``).
        earth_rotation: Include the Sagnac rate.

    Returns:
        Delta-ranges [m/s], ``(B, m)``.
    """
    return range_rate(rx_ecef, rx_vel, sat_pos, sat_vel, earth_rotation) + np.asarray(
        clock_drift_mps, np.float64
    )


def range_and_rate(
    rx_ecef: ArrayLike,
    rx_vel: ArrayLike,
    sat_pos: ArrayLike,
    sat_vel: ArrayLike,
    sat_acc: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`geometric_range` and :func:`range_rate` (``earth_rotation=True``) in one pass.

    The two share the flight time and the transmit-time satellite position; a simulator step
    needs both (Carvalho et al. 1997, eq. 10, Touil & Ghadi 2012, eq. 5-7).

    Args:
        rx_ecef: Receiver position [m], ``(..., 3)``.
        rx_vel: Receiver ECEF velocity [m/s].
        sat_pos: Satellite position at the receive time [m].
        sat_vel: Satellite ECEF velocity at the receive time [m/s].
        sat_acc: Satellite ECEF acceleration [m/s^2]
            (:func:`~navgym.gnss.orbit.ecef_acceleration`, computed if None).

    Returns:
        ``(range [m], range_rate [m/s])``, each of the broadcast shape without the last axis.
    """
    rx, ry, rz = _xyz(rx_ecef, "rx_ecef")
    ux, uy, uz = _xyz(rx_vel, "rx_vel")
    if sat_acc is None:
        sat_acc = ecef_acceleration(np.asarray(sat_pos), np.asarray(sat_vel))
    sx, sy, sz = _xyz(sat_pos, "sat_pos")
    vx, vy, vz = _xyz(sat_vel, "sat_vel")
    ax, ay, az = _xyz(sat_acc, "sat_acc")
    tau = _norm(sx - rx, sy - ry, sz - rz) / C_LIGHT
    sx, sy, sz = sx - vx * tau, sy - vy * tau, sz - vz * tau
    # Range: first-order Sagnac term on the transmit-time position (as geometric_range).
    dz = sz - rz
    rng = _norm(sx - rx, sy - ry, dz) + OMEGA_E / C_LIGHT * (sx * ry - sy * rx)
    # Rate: transmit-time velocity, both rotated by omega_e tau (as range_rate).
    vx, vy, vz = vx - ax * tau, vy - ay * tau, vz - az * tau
    th = OMEGA_E * tau
    sx, sy = sx + th * sy, sy - th * sx
    vx, vy = vx + th * vy, vy - th * vx
    dx, dy = sx - rx, sy - ry
    inv_rho = 1.0 / _norm(dx, dy, dz)
    a_sat = (dx * vx + dy * vy + dz * vz) * inv_rho
    a_rx = (dx * ux + dy * uy + dz * uz) * inv_rho
    c_rot = OMEGA_E * (dx * sy - dy * sx) * inv_rho
    return rng, (a_sat - a_rx) / (1.0 + (a_sat - c_rot) / C_LIGHT)
