"""Coordinate frames: geodetic (lat, lon, h), ECEF and local NED, vectorized over leading axes.

All angles are radians, lengths metres, arrays float64. Every function broadcasts over any
leading axes ("...") so a batch ``(B,)``, a satellite grid ``(B, m)`` or particles ``(B, N)`` go
through the same code without Python loops.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.earth import normal_radius
from navgym.geo.wgs84 import E2, EP2, A, B

__all__ = [
    "geodetic_to_ecef",
    "ecef_to_geodetic",
    "ecef_to_geodetic_sincos",
    "ecef_to_ned_matrix",
    "north_east_axes",
    "ecef_to_ned",
    "ned_to_ecef",
    "elevation_azimuth",
    "up_axis",
    "up_vector",
]


def _as_xyz(xyz: ArrayLike, name: str) -> NDArray[np.float64]:
    arr = np.asarray(xyz, dtype=np.float64)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3), got {arr.shape}")
    return arr


def geodetic_to_ecef(lat: ArrayLike, lon: ArrayLike, h: ArrayLike) -> NDArray[np.float64]:
    """Convert geodetic latitude, longitude, height to ECEF position.

    Carvalho et al. 1997, §IV-D (coordinate change after eq. 15), Touil & Ghadi 2012, eq. 8::

        X = (N + h) cos(lat) cos(lon)
        Y = (N + h) cos(lat) sin(lon)
        Z = (N (1 - e^2) + h) sin(lat),   N = a / sqrt(1 - e^2 sin^2 lat)

    Args:
        lat: Geodetic latitude [rad], any shape.
        lon: Longitude [rad], broadcastable with ``lat``.
        h: Height above the ellipsoid [m], broadcastable with ``lat``.

    Returns:
        ECEF position [m], shape ``broadcast(lat, lon, h).shape + (3,)``.

    """
    lat, lon, h = np.broadcast_arrays(
        np.asarray(lat, np.float64), np.asarray(lon, np.float64), np.asarray(h, np.float64)
    )
    n = normal_radius(lat)
    cl = np.cos(lat)
    out = np.empty(lat.shape + (3,))
    out[..., 0] = (n + h) * cl * np.cos(lon)
    out[..., 1] = (n + h) * cl * np.sin(lon)
    out[..., 2] = (n * (1.0 - E2) + h) * np.sin(lat)
    return out


def ecef_to_geodetic(
    xyz: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Convert ECEF position to geodetic latitude, longitude and height (closed form).

    Heikkinen's exact closed-form solution (Heikkinen 1982; as given by Zhu, "Conversion of
    Earth-centered Earth-fixed coordinates to geodetic coordinates", IEEE T-AES 30(3), 1994),
    accurate to well below a millimetre from the Earth's surface to GNSS orbits::

        p = sqrt(x^2 + y^2),  F = 54 b^2 z^2,  G = p^2 + (1 - e^2) z^2 - e^2 (a^2 - b^2)
        c = e^4 F p^2 / G^3,  s = cbrt(1 + c + sqrt(c^2 + 2c)),  P = F / (3 (s + 1/s + 1)^2 G^2)
        Q = sqrt(1 + 2 e^4 P)
        r0 = -P e^2 p / (1 + Q) + sqrt(a^2/2 (1 + 1/Q) - P (1 - e^2) z^2 / (Q (1 + Q)) - P p^2/2)
        U = sqrt((p - e^2 r0)^2 + z^2),  V = sqrt((p - e^2 r0)^2 + (1 - e^2) z^2)
        h = U (1 - b^2 / (a V)),  lat = atan2(z + e'^2 b^2 z / (a V), p),  lon = atan2(y, x)

    Not valid within about 45 km of the Earth's centre (never met in navigation).

    Args:
        xyz: ECEF position [m], shape ``(..., 3)``.

    Returns:
        ``(lat, lon, h)`` [rad, rad, m], each of shape ``xyz.shape[:-1]``.

    Raises:
        ValueError: If ``xyz`` does not end with an axis of length 3.

    """
    xyz = _as_xyz(xyz, "xyz")
    p, zq, h = _heikkinen(xyz)
    lat = np.arctan2(zq, p)
    lon = np.arctan2(xyz[..., 1], xyz[..., 0])
    return lat, lon, h


def ecef_to_geodetic_sincos(xyz: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    """:func:`ecef_to_geodetic` plus the sines and cosines of latitude and longitude.

    The trigonometric functions come from the same closed form without evaluating them:
    ``(sin lat, cos lat) = (zq, p) / hypot(zq, p)`` with ``tan lat = zq / p`` of Heikkinen's
    solution, and ``(sin lon, cos lon) = (y, x) / p``; they agree with ``np.sin(lat)`` etc. to
    rounding (a few 1e-16). Not valid on the polar axis (``p = 0``).

    Args:
        xyz: ECEF position [m], shape ``(..., 3)``.

    Returns:
        ``(lat, lon, h, sin_lat, cos_lat, sin_lon, cos_lon)``, each of shape ``xyz.shape[:-1]``.

    Raises:
        ValueError: If ``xyz`` does not end with an axis of length 3.
    """
    xyz = _as_xyz(xyz, "xyz")
    p, zq, h = _heikkinen(xyz)
    x, y = xyz[..., 0], xyz[..., 1]
    inv_hyp = 1.0 / np.sqrt(zq * zq + p * p)
    inv_p = 1.0 / p
    return np.arctan2(zq, p), np.arctan2(y, x), h, zq * inv_hyp, p * inv_hyp, y * inv_p, x * inv_p


def _heikkinen(
    xyz: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Core of :func:`ecef_to_geodetic`: ``(p, z + e'^2 z0, h)`` with tan(lat) = zq / p."""
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p2 = x * x + y * y
    p = np.sqrt(p2)
    z2 = z * z
    f_ = 54.0 * B * B * z2
    g = p2 + (1.0 - E2) * z2 - E2 * (A * A - B * B)
    c = E2 * E2 * f_ * p2 / (g * g * g)
    s = np.cbrt(1.0 + c + np.sqrt(c * c + 2.0 * c))
    k = s + 1.0 + 1.0 / s
    pp = f_ / (3.0 * k * k * g * g)
    q = np.sqrt(1.0 + 2.0 * E2 * E2 * pp)
    r0 = -pp * E2 * p / (1.0 + q) + np.sqrt(
        np.maximum(
            0.5 * A * A * (1.0 + 1.0 / q) - pp * (1.0 - E2) * z2 / (q * (1.0 + q)) - 0.5 * pp * p2,
            0.0,
        )
    )
    t = p - E2 * r0
    u = np.sqrt(t * t + z2)
    v = np.sqrt(t * t + (1.0 - E2) * z2)
    bav = B * B / (A * v)
    return p, z + EP2 * bav * z, u * (1.0 - bav)


def up_vector(xyz: ArrayLike) -> NDArray[np.float64]:
    """Unit outward ellipsoid normal (local "up", minus NED's down axis) at ECEF points.

    ``u = (cos lat cos lon, cos lat sin lon, sin lat)`` without trigonometric functions, by two
    iterations of Bowring's formula on the parametric latitude beta (Bowring, "Transformation
    from spatial to geographical coordinates", Survey Review 23(181), 1976)::

        tan beta_0 = a z / (b p),   tan lat = (z + e'^2 b sin^3 beta) / (p - e^2 a cos^3 beta),
        tan beta = (b / a) tan lat

    accurate to 1e-15 rad from the surface to GNSS orbits. On the polar axis (x = y = 0) it
    returns ``(0, 0, sign z)``.

    Args:
        xyz: ECEF positions [m], ``(..., 3)``.

    Returns:
        Unit vectors, ``(..., 3)``.

    Raises:
        ValueError: If ``xyz`` does not end with an axis of length 3.
    """
    xyz = _as_xyz(xyz, "xyz")
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.sqrt(x * x + y * y)
    sb, cb = A * z, B * p
    for _ in range(2):
        n = np.sqrt(sb * sb + cb * cb)
        sb, cb = sb / n, cb / n
        num = z + EP2 * B * sb * sb * sb
        den = p - E2 * A * cb * cb * cb
        sb, cb = B * num, A * den
    hyp = np.sqrt(num * num + den * den)
    scale = np.where(p > 0, den / (np.where(p > 0, p, 1.0) * hyp), 0.0)
    out = np.empty(xyz.shape)
    out[..., 0] = x * scale
    out[..., 1] = y * scale
    out[..., 2] = np.where(p > 0, num / hyp, np.sign(z))
    return out


def ecef_to_ned_matrix(lat: ArrayLike, lon: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix C_e^n from ECEF to local North-East-Down axes.

    Groves, "Principles of GNSS, Inertial, and Multisensor Integrated Navigation Systems",
    2nd ed., eq. 2.150::

        C_e^n = [[-sin(lat) cos(lon), -sin(lat) sin(lon),  cos(lat)],
                 [-sin(lon),           cos(lon),           0       ],
                 [-cos(lat) cos(lon), -cos(lat) sin(lon), -sin(lat)]]

    Args:
        lat: Geodetic latitude [rad], any shape.
        lon: Longitude [rad], broadcastable with ``lat``.

    Returns:
        Rotation matrices, shape ``broadcast(lat, lon).shape + (3, 3)``; ``v_ned = C @ v_ecef``.

    """
    return np.stack(_ned_axes(lat, lon, down=True), axis=-2)


def north_east_axes(lat: ArrayLike, lon: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The local north and east unit vectors in ECEF: rows 0 and 1 of :func:`ecef_to_ned_matrix`.

    ``north = (-sin lat cos lon, -sin lat sin lon, cos lat)``, ``east = (-sin lon, cos lon, 0)``
    (Groves eq. 2.150), the same values without forming the 3 x 3 matrices.

    Returns:
        ``(north, east)``, each of shape ``broadcast(lat, lon).shape + (3,)``.
    """
    return _ned_axes(lat, lon, down=False)


def up_axis(lat: ArrayLike, lon: ArrayLike) -> NDArray[np.float64]:
    """The ellipsoid normal ``(cos lat cos lon, cos lat sin lon, sin lat)`` at geodetic coordinates.

    Minus the down row of :func:`ecef_to_ned_matrix` (Groves eq. 2.150); :func:`up_vector`
    gives the same from ECEF positions.

    Returns:
        Unit vectors, shape ``broadcast(lat, lon).shape + (3,)``.
    """
    lat, lon = np.broadcast_arrays(np.asarray(lat, np.float64), np.asarray(lon, np.float64))
    cl = np.cos(lat)
    out = np.empty(lat.shape + (3,))
    np.multiply(cl, np.cos(lon), out=out[..., 0])
    np.multiply(cl, np.sin(lon), out=out[..., 1])
    np.sin(lat, out=out[..., 2])
    return out


def _ned_axes(lat: ArrayLike, lon: ArrayLike, down: bool) -> tuple[NDArray[np.float64], ...]:
    """The rows of C_e^n (Groves eq. 2.150) as ECEF unit vectors: north, east (and down)."""
    lat, lon = np.broadcast_arrays(np.asarray(lat, np.float64), np.asarray(lon, np.float64))
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    north = np.stack([-sl * co, -sl * so, cl], axis=-1)
    east = np.stack([-so, co, np.zeros_like(so)], axis=-1)
    if not down:
        return north, east
    return north, east, np.stack([-cl * co, -cl * so, -sl], axis=-1)


def ecef_to_ned(
    xyz: ArrayLike, ref_lat: ArrayLike, ref_lon: ArrayLike, ref_h: ArrayLike
) -> NDArray[np.float64]:
    """Express ECEF points as North-East-Down offsets from a geodetic reference point.

    ``ned = C_e^n(ref_lat, ref_lon) (xyz - r_e(ref))`` (Groves eq. 2.150/2.151).

    Args:
        xyz: ECEF positions [m], shape ``(..., 3)``.
        ref_lat: Reference latitude [rad], broadcastable with ``xyz.shape[:-1]``.
        ref_lon: Reference longitude [rad].
        ref_h: Reference height [m].

    Returns:
        NED offsets [m], shape ``broadcast(...) + (3,)``.

    Raises:
        ValueError: If ``xyz`` does not end with an axis of length 3.

    """
    xyz = _as_xyz(xyz, "xyz")
    ref = geodetic_to_ecef(ref_lat, ref_lon, ref_h)
    c = ecef_to_ned_matrix(ref_lat, ref_lon)
    return np.einsum("...ij,...j->...i", c, xyz - ref)


def ned_to_ecef(
    ned: ArrayLike, ref_lat: ArrayLike, ref_lon: ArrayLike, ref_h: ArrayLike
) -> NDArray[np.float64]:
    """Convert North-East-Down offsets from a geodetic reference point to ECEF positions.

    ``xyz = r_e(ref) + (C_e^n)^T ned`` (inverse of :func:`ecef_to_ned`).

    Args:
        ned: NED offsets [m], shape ``(..., 3)``.
        ref_lat: Reference latitude [rad], broadcastable with ``ned.shape[:-1]``.
        ref_lon: Reference longitude [rad].
        ref_h: Reference height [m].

    Returns:
        ECEF positions [m], shape ``broadcast(...) + (3,)``.

    Raises:
        ValueError: If ``ned`` does not end with an axis of length 3.

    """
    ned = _as_xyz(ned, "ned")
    ref = geodetic_to_ecef(ref_lat, ref_lon, ref_h)
    c = ecef_to_ned_matrix(ref_lat, ref_lon)
    return ref + np.einsum("...ji,...j->...i", c, ned)


def elevation_azimuth(
    rx_ecef: ArrayLike, sat_ecef: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Elevation and azimuth of satellites seen from receivers (geodetic local horizon).

    The line of sight ``u = C_e^n(lat_rx, lon_rx) (r_sat - r_rx)`` gives
    ``el = atan2(-u_D, sqrt(u_N^2 + u_E^2))`` and ``az = atan2(u_E, u_N)`` in [0, 2 pi)
    (Carvalho et al. 1997, §IV-C-1 "visible satellites", with the geodetic instead of the geocentric
    vertical of the theta_i formula after Carvalho et al. 1997, eq. 15).

    The receiver's geodetic coordinates are computed on ``rx_ecef`` *before* broadcasting, so
    pass receivers as ``(B, 1, 3)`` against satellites ``(B, m, 3)`` (or ``(m, 3)``) to convert
    each receiver once.

    Args:
        rx_ecef: Receiver ECEF positions [m], shape ``(..., 3)``.
        sat_ecef: Satellite ECEF positions [m], shape broadcastable with ``rx_ecef``.

    Returns:
        ``(elevation, azimuth)`` [rad], each of the broadcast shape without the last axis.

    Raises:
        ValueError: If an argument does not end with an axis of length 3.

    """
    rx = _as_xyz(rx_ecef, "rx_ecef")
    sat = _as_xyz(sat_ecef, "sat_ecef")
    lat, lon, _ = ecef_to_geodetic(rx)
    d = sat - rx
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
    t = co * dx + so * dy
    north = -sl * t + cl * dz
    east = -so * dx + co * dy
    down = -cl * t - sl * dz
    el = np.arctan2(-down, np.hypot(north, east))
    az = np.mod(np.arctan2(east, north), 2.0 * np.pi)
    return el, az
