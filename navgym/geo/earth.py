"""Earth radii of curvature and normal gravity on the WGS-84 ellipsoid."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.wgs84 import E2, GAMMA_E, GRAVITY_M, SOMIGLIANA_K, A, F

__all__ = ["meridian_radius", "normal_radius", "gravity"]


def meridian_radius(lat: ArrayLike, sin_lat: ArrayLike | None = None) -> NDArray[np.float64]:
    """Meridian radius of curvature R_M (north-south).

    ``R_M = a (1 - e^2) / (1 - e^2 sin^2 lat)^(3/2)`` (Groves 2nd ed. eq. 2.105).

    Args:
        lat: Geodetic latitude [rad], any shape.
        sin_lat: ``sin(lat)`` if the caller has it (saves the sine; ``lat`` is then unused).

    Returns:
        R_M [m], same shape as ``lat``.

    """
    s = np.sin(np.asarray(lat, np.float64)) if sin_lat is None else np.asarray(sin_lat, np.float64)
    return A * (1.0 - E2) / (1.0 - E2 * s * s) ** 1.5


def normal_radius(lat: ArrayLike, sin_lat: ArrayLike | None = None) -> NDArray[np.float64]:
    """Prime-vertical (transverse) radius of curvature R_N = N.

    ``R_N = a / sqrt(1 - e^2 sin^2 lat)`` (Carvalho et al. 1997, §IV-D, R_p; Touil & Ghadi 2012,
    after eq. 10; Groves eq. 2.106).

    Args:
        lat: Geodetic latitude [rad], any shape.
        sin_lat: ``sin(lat)`` if the caller has it (saves the sine; ``lat`` is then unused).

    Returns:
        R_N [m], same shape as ``lat``.

    """
    s = np.sin(np.asarray(lat, np.float64)) if sin_lat is None else np.asarray(sin_lat, np.float64)
    return A / np.sqrt(1.0 - E2 * s * s)


def gravity(lat: ArrayLike, h: ArrayLike = 0.0, sin_lat: ArrayLike | None = None) -> NDArray[np.float64]:
    """Magnitude of WGS-84 normal gravity at geodetic latitude and height.

    Somigliana's formula on the ellipsoid (NIMA TR8350.2 eq. 4-1)::

        gamma_0 = gamma_e (1 + k sin^2 lat) / sqrt(1 - e^2 sin^2 lat)

    with the second-order free-air height correction (TR8350.2 eq. 4-3)::

        gamma_h = gamma_0 (1 - 2/a (1 + f + m - 2 f sin^2 lat) h + 3 h^2 / a^2)

    Args:
        lat: Geodetic latitude [rad].
        h: Height above the ellipsoid [m], broadcastable with ``lat`` (valid up to ~20 km).
        sin_lat: ``sin(lat)`` if the caller has it (saves the sine; ``lat`` is then unused).

    Returns:
        Normal gravity [m/s^2] pointing down the ellipsoid normal, broadcast shape.

    """
    h = np.asarray(h, np.float64)
    s = np.sin(np.asarray(lat, np.float64)) if sin_lat is None else np.asarray(sin_lat, np.float64)
    s2 = s * s
    g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * s2) / np.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A * (1.0 + F + GRAVITY_M - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))
