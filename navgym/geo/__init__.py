"""Geodesy on the WGS-84 ellipsoid (Carvalho et al. 1997, §IV-A), vectorized over any leading axes.

Public API (angles in radians, lengths in metres, float64):

* constants: ``A``, ``B``, ``F``, ``E2``, ``EP2``, ``OMEGA_E``, ``GM``, ``C_LIGHT``
* ``geodetic_to_ecef(lat, lon, h) -> (..., 3)``
* ``ecef_to_geodetic(xyz) -> (lat, lon, h)``; ``ecef_to_geodetic_sincos`` adds their sines and cosines
* ``ecef_to_ned_matrix(lat, lon) -> (..., 3, 3)``; ``north_east_axes(lat, lon)``, its first two rows
* ``ecef_to_ned(xyz, ref_lat, ref_lon, ref_h) -> (..., 3)``
* ``ned_to_ecef(ned, ref_lat, ref_lon, ref_h) -> (..., 3)``
* ``elevation_azimuth(rx_ecef, sat_ecef) -> (el, az)``
* ``up_vector(xyz) -> (..., 3)`` unit ellipsoid normal; ``up_axis(lat, lon)`` the same from geodetic
* ``meridian_radius(lat)``, ``normal_radius(lat)``, ``gravity(lat, h)``
"""

from navgym.geo.earth import gravity, meridian_radius, normal_radius
from navgym.geo.frames import (
    ecef_to_geodetic,
    ecef_to_geodetic_sincos,
    ecef_to_ned,
    ecef_to_ned_matrix,
    elevation_azimuth,
    geodetic_to_ecef,
    ned_to_ecef,
    north_east_axes,
    up_axis,
    up_vector,
)
from navgym.geo.wgs84 import C_LIGHT, E2, EP2, GM, OMEGA_E, R_MEAN, A, B, F

__all__ = [
    "A",
    "B",
    "F",
    "E2",
    "EP2",
    "OMEGA_E",
    "GM",
    "C_LIGHT",
    "R_MEAN",
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
    "meridian_radius",
    "normal_radius",
    "gravity",
]
