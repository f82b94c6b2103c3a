"""The Iridium constellation: circular orbits, and which satellites a vehicle sees (Benzerrouk 2014, §2.7d).

Benzerrouk 2014 (§2.7d, "Iridium satellite based positioning system") describes the
constellation: 66 space vehicles in 6 near-circular orbital planes at 86.4 deg inclination and
780 km altitude, co-rotating planes 31.6 deg apart and the two planes at the seam (where the
satellites counter-rotate) 22 deg apart, an orbital period of 100 min 28 s, about 10 min in view
of a place. This module is the simple model of it that decides when an Iridium geolocation fix
can arrive (a satellite above the elevation mask) and how good it is (the serving satellite's
elevation):

* **Orbits**: 6 planes of 11 satellites, circular (radius ``a = R_E + 780 km`` with the WGS-84
  equatorial radius ``R_E``), inclination ``i = 86.4 deg``; plane ``p`` (0-5) has the right
  ascension ``Omega_p = Omega_0 + 31.6 deg p`` (so plane 5 and plane 0, the seam, are 180 - 158 =
  22 deg apart on the other side), satellite ``s`` (0-10) of it the argument of latitude
  ``u_ps(t) = u_0 + 360 deg s / 11 + 180 deg p / 11 + n t`` (adjacent planes staggered by half
  a slot), with the mean motion ``n = 2 pi / T`` of the source's period ``T = 6028 s`` (a
  Keplerian orbit at 780 km would take 6027 s). ``Omega_0`` and ``u_0`` are drawn per episode
  (where the constellation stands when it starts). No perturbations: J2 precession moves the
  planes by under 0.1 deg in an hour-long episode.
* **Earth-fixed position** (ECEF), the Earth turning at ``OMEGA_E`` under the inertial planes::

      r = a [cos W cos u - sin W sin u cos i,  sin W cos u + cos W sin u cos i,  sin u sin i],
      W = Omega_p - OMEGA_E t

* **Visibility**: the elevation of each satellite above the vehicle's local horizon
  (:func:`navgym.geo.frames.elevation_azimuth`, the vehicle on the WGS-84 ellipsoid); a
  satellite is in view above the elevation mask (Iridium's 8.2 deg by default, the scenario's
  ``mask_deg`` in the environments). A fix needs one satellite in view; the highest one serves
  it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.frames import elevation_azimuth, geodetic_to_ecef
from navgym.geo.wgs84 import OMEGA_E
from navgym.geo.wgs84 import A as EARTH_RADIUS

__all__ = [
    "ALTITUDE_M",
    "INCLINATION_DEG",
    "N_PLANES",
    "PER_PLANE",
    "PLANE_SPACING_DEG",
    "PERIOD_S",
    "IRIDIUM_MASK_DEG",
    "satellite_ecef",
    "elevations",
    "serving_satellite",
]

#: Benzerrouk 2014, §2.7d: 66 satellites in 6 planes (11 per plane).
N_PLANES = 6
PER_PLANE = 11
#: Benzerrouk 2014, §2.7d: inclination [deg], altitude [m], co-rotating plane spacing [deg],
#: period (100 min 28 s) [s].
INCLINATION_DEG = 86.4
ALTITUDE_M = 780e3
PLANE_SPACING_DEG = 31.6
PERIOD_S = 100 * 60 + 28.0
#: Iridium's minimum elevation angle [deg] (the constellation is laid out for it).
IRIDIUM_MASK_DEG = 8.2


def satellite_ecef(t: ArrayLike, raan0: ArrayLike = 0.0, u0: ArrayLike = 0.0) -> NDArray[np.float64]:
    """ECEF positions [m] of the 66 satellites at times ``t`` [s] (module docstring).

    Args:
        t: Times [s], any shape ``S``.
        raan0: Right ascension of plane 0 at ``t = 0`` [rad], broadcastable to ``S``.
        u0: Argument of latitude of satellite 0 of plane 0 at ``t = 0`` [rad], broadcastable to ``S``.

    Returns:
        ``S + (66, 3)``: plane-major (satellite ``s`` of plane ``p`` at ``11 p + s``).

    """
    t = np.asarray(t, np.float64)[..., None]
    raan0 = np.asarray(raan0, np.float64)[..., None]
    u0 = np.asarray(u0, np.float64)[..., None]
    p = np.repeat(np.arange(N_PLANES), PER_PLANE)
    s = np.tile(np.arange(PER_PLANE), N_PLANES)
    a = EARTH_RADIUS + ALTITUDE_M
    inc = np.deg2rad(INCLINATION_DEG)
    W = raan0 + np.deg2rad(PLANE_SPACING_DEG) * p - OMEGA_E * t
    u = u0 + 2.0 * np.pi * (s + 0.5 * p) / PER_PLANE + 2.0 * np.pi / PERIOD_S * t
    cW, sW, cu, su = np.cos(W), np.sin(W), np.cos(u), np.sin(u)
    ci, si = np.cos(inc), np.sin(inc)
    return a * np.stack([cW * cu - sW * su * ci, sW * cu + cW * su * ci, su * si], axis=-1)


def elevations(
    lat: ArrayLike, lon: ArrayLike, t: ArrayLike, raan0: ArrayLike = 0.0, u0: ArrayLike = 0.0
) -> NDArray[np.float64]:
    """Elevation [rad] of every satellite seen from ``(lat, lon)`` [rad] on the ellipsoid at ``t`` [s].

    ``lat``, ``lon``, ``t``, ``raan0`` and ``u0`` broadcast to a shape ``S``; returns ``S + (66,)``.
    """
    lat, lon, t, raan0, u0 = np.broadcast_arrays(
        *(np.asarray(v, np.float64) for v in (lat, lon, t, raan0, u0))
    )
    rx = geodetic_to_ecef(lat, lon, np.zeros_like(lat))[..., None, :]
    el, _ = elevation_azimuth(rx, satellite_ecef(t, raan0, u0))
    return el


def serving_satellite(
    elevation: ArrayLike, mask_deg: ArrayLike = IRIDIUM_MASK_DEG
) -> tuple[NDArray, NDArray]:
    """Satellites in view and the highest elevation, from elevations ``(..., 66)`` [rad].

    Returns:
        ``(count, best)``: the number of satellites above ``mask_deg`` (broadcast against the
        leading axes) and the highest elevation [rad] (NaN where none is in view).

    """
    el = np.asarray(elevation, np.float64)
    mask = np.deg2rad(np.asarray(mask_deg, np.float64))[..., None]
    above = el >= mask
    best = np.where(above.any(axis=-1), el.max(axis=-1), np.nan)
    return above.sum(axis=-1), best
