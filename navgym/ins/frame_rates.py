"""Navigation-frame rates and gravity of the local-level NED mechanization.

All functions broadcast over leading axes; ``v_ned`` has shape ``(..., 3)``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo import OMEGA_E, gravity, meridian_radius, normal_radius
from navgym.ins.vec3 import Vec3

__all__ = [
    "HomeFrame",
    "earth_rate_ned",
    "gravity_ned",
    "home_frame",
    "transport_rate_ned",
    "transport_rate_components",
]


def earth_rate_ned(lat: ArrayLike) -> NDArray[np.float64]:
    """Earth rotation rate resolved in NED, ``omega_ie^n = omega_e [cos lat, 0, -sin lat]``.

    Groves (2013) eq. 2.123.

    Args:
        lat: Geodetic latitude [rad], any shape.

    Returns:
        Rates [rad/s], shape ``lat.shape + (3,)``.

    """
    lat = np.asarray(lat, np.float64)
    out = np.zeros(lat.shape + (3,))
    out[..., 0] = OMEGA_E * np.cos(lat)
    out[..., 2] = -OMEGA_E * np.sin(lat)
    return out


def transport_rate_ned(lat: ArrayLike, h: ArrayLike, v_ned: ArrayLike) -> NDArray[np.float64]:
    """Transport rate of the NED frame over the ellipsoid, ``omega_en^n``.

    Groves (2013) eq. 5.44::

        omega_en^n = [ v_E / (R_N + h),  -v_N / (R_M + h),  -v_E tan(lat) / (R_N + h) ]

    Args:
        lat: Geodetic latitude [rad].
        h: Height [m], broadcastable with ``lat``.
        v_ned: NED velocity [m/s], shape ``(..., 3)``.

    Returns:
        Rates [rad/s], shape ``(..., 3)``.

    """
    v = np.asarray(v_ned, np.float64)
    comps = (v[..., 0], v[..., 1], v[..., 2])
    return np.stack(
        transport_rate_components(np.asarray(lat, np.float64), np.asarray(h, np.float64), comps), -1
    )


def transport_rate_components(
    lat: ArrayLike, h: ArrayLike, v: Vec3, sin_lat: ArrayLike | None = None, cos_lat: ArrayLike | None = None
) -> Vec3:
    """:func:`transport_rate_ned` on a component triple ``v = (v_N, v_E, v_D)``.

    ``sin_lat`` and ``cos_lat`` may be passed if the caller has them (then ``tan lat`` is their
    ratio and no trigonometric function is evaluated).
    """
    sl = np.sin(lat) if sin_lat is None else sin_lat
    cl = np.cos(lat) if cos_lat is None else cos_lat
    rn = normal_radius(lat, sl) + h
    return (v[1] / rn, -v[0] / (meridian_radius(lat, sl) + h), -v[1] * (sl / cl) / rn)


def gravity_ned(lat: ArrayLike, h: ArrayLike) -> NDArray[np.float64]:
    """Normal gravity vector in NED, ``g^n = [0, 0, gamma(lat, h)]``.

    WGS-84 Somigliana normal gravity from :func:`navgym.geo.gravity`; the small north
    component of the normal gravity vector above the ellipsoid (below 1e-6 g per km of height)
    is neglected, identically in the mechanization and the IMU simulator.

    Args:
        lat: Geodetic latitude [rad].
        h: Height [m], broadcastable with ``lat``.

    Returns:
        Gravity [m/s^2], shape ``broadcast(lat, h).shape + (3,)``.

    """
    g = gravity(lat, h)
    out = np.zeros(np.shape(g) + (3,))
    out[..., 2] = g
    return out


class HomeFrame(NamedTuple):
    """Gravity and Earth rate of a local tangent frame fixed at a home point, each ``(..., 3)``."""

    gravity: NDArray[np.float64]  #: ``[0, 0, gamma(lat0, h0)]`` (:func:`gravity_ned`)
    gradient: NDArray[np.float64]  #: diagonal of ``d g^n / d(N, E, D)`` at the home point
    earth_rate: NDArray[np.float64]  #: ``omega_ie^n`` at the home point (:func:`earth_rate_ned`)


def home_frame(lat0: ArrayLike, h0: ArrayLike) -> HomeFrame:
    """Gravity, its gradient and the Earth rate at the origin of a home tangent frame.

    The tangent-frame strapdown model of :mod:`navgym.quadrotor.models` (also the Pedestrian's and
    the replay's) linearizes normal gravity about the home point: moving north or east by ``d``
    turns the vertical by ``d / (R + h0)``, so the horizontal components of ``g^n`` change by
    ``-gamma / (R_M + h0)`` and ``-gamma / (R_N + h0)`` per metre (Groves 2013, §2.4.7, the
    meridian and normal radii of curvature), and the vertical one by ``-d gamma / dh`` per metre
    down (a central difference over +-1 m of :func:`navgym.geo.gravity`).

    Args:
        lat0: Geodetic latitude of the home point [rad], any shape.
        h0: Its height [m], the same shape.

    Returns:
        :class:`HomeFrame` with arrays of shape ``lat0.shape + (3,)``.
    """
    lat0, h0 = np.asarray(lat0, np.float64), np.asarray(h0, np.float64)
    g0 = gravity(lat0, h0)
    dg_dh = (gravity(lat0, h0 + 1.0) - gravity(lat0, h0 - 1.0)) / 2.0
    grav = np.zeros(np.shape(g0) + (3,))
    grav[..., 2] = g0
    grad = np.stack([-g0 / (meridian_radius(lat0) + h0), -g0 / (normal_radius(lat0) + h0), -dg_dh], axis=-1)
    return HomeFrame(grav, grad, earth_rate_ned(lat0))
