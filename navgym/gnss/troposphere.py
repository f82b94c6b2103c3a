"""Tropospheric delay models: Carvalho et al. 1997's simplified Goad-Goodman and Saastamoinen.

All functions take elevation angles in radians of any shape and return the slant delay in
metres of the same (broadcast) shape.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.wgs84 import R_MEAN

__all__ = [
    "GOAD_GOODMAN_PRESSURE_HPA",
    "GOAD_GOODMAN_TEMPERATURE_K",
    "GOAD_GOODMAN_VAPOUR_HPA",
    "GOAD_GOODMAN_WET_HEIGHT_M",
    "TROPO_NOISE_FRACTION",
    "goad_goodman_delay",
    "goad_goodman_coefficients",
    "goad_goodman_delay_from_sine",
    "saastamoinen_delay",
]

#: Local pressure P [hPa = mbar] (Carvalho et al. 1997, §IV-C-3).
GOAD_GOODMAN_PRESSURE_HPA: float = 1013.0
#: Local temperature T [K] (Carvalho et al. 1997, §IV-C-3).
GOAD_GOODMAN_TEMPERATURE_K: float = 298.0
#: Partial pressure of water vapour e [hPa] (Carvalho et al. 1997, §IV-C-3).
GOAD_GOODMAN_VAPOUR_HPA: float = 34.0
#: Height of the wet layer h_w [m] (Carvalho et al. 1997, §IV-C-3).
GOAD_GOODMAN_WET_HEIGHT_M: float = 11000.0
#: Standard deviation of the model error as a fraction of the delay (Carvalho et al. 1997, §IV-C-3, eq. 15).
TROPO_NOISE_FRACTION: float = 0.05


def goad_goodman_delay(
    elevation: ArrayLike,
    pressure_hpa: float = GOAD_GOODMAN_PRESSURE_HPA,
    temperature_k: float = GOAD_GOODMAN_TEMPERATURE_K,
    vapour_hpa: float = GOAD_GOODMAN_VAPOUR_HPA,
    earth_radius: float = R_MEAN,
    quartic_profile: bool = False,
) -> NDArray[np.float64]:
    """Simplified Goad-Goodman tropospheric delay (Carvalho et al. 1997, §IV-C-3, Fig. 9).

    ::

        Delta_tropo(theta) = 1e-6 { N_d0 (sqrt((R + h_d)^2 - R^2 cos^2 theta) - R sin theta)
                                  + N_w0 (sqrt((R + h_w)^2 - R^2 cos^2 theta) - R sin theta) }
        h_d = 40136 + 148.72 (T - 273.16) m,   h_w = 11 km
        N_d0 = 77.64 P / T,   N_w0 = -12.96 e / T + 3.718e5 e / T^2

    with P = 1013 mbar, T = 298 K, e = 34 mbar. As printed in Carvalho et al. 1997 the refractivity is
    constant through each layer, which gives about 13 m at zenith. Hopfield's quartic
    refractivity profile (which Goad & Goodman 1974 build on) integrates to 1/5 of that,
    about 2.6 m at zenith, close to real delays; ``quartic_profile=True`` applies that factor.

    Args:
        elevation: Elevation angle theta [rad], any shape.
        pressure_hpa: Pressure P [hPa].
        temperature_k: Temperature T [K].
        vapour_hpa: Water-vapour partial pressure e [hPa].
        earth_radius: Earth radius R [m].
        quartic_profile: Multiply by 1/5 (Hopfield quartic profile) instead of using the
            constant-refractivity layers of Carvalho et al. 1997.

    Returns:
        Slant delay [m], same shape as ``elevation``.
    """
    el = np.asarray(elevation, np.float64)
    return goad_goodman_delay_from_sine(
        np.sin(el), pressure_hpa, temperature_k, vapour_hpa, earth_radius, quartic_profile
    )


def goad_goodman_delay_from_sine(
    sin_elevation: ArrayLike,
    pressure_hpa: float = GOAD_GOODMAN_PRESSURE_HPA,
    temperature_k: float = GOAD_GOODMAN_TEMPERATURE_K,
    vapour_hpa: float = GOAD_GOODMAN_VAPOUR_HPA,
    earth_radius: float = R_MEAN,
    quartic_profile: bool = False,
) -> NDArray[np.float64]:
    """:func:`goad_goodman_delay` from ``sin(theta)`` (no trigonometric calls: hot paths)."""
    se = np.asarray(sin_elevation, np.float64)
    kd, ad, kw, aw, r = goad_goodman_coefficients(pressure_hpa, temperature_k, vapour_hpa, earth_radius)
    # sqrt((R + h)^2 - R^2 cos^2) = sqrt((R + h)^2 - R^2 + (R sin)^2)
    rs = r * se
    rs2 = rs * rs
    delay = kd * (np.sqrt(ad + rs2) - rs)
    delay += kw * (np.sqrt(aw + rs2) - rs)
    return delay / 5.0 if quartic_profile else delay


def goad_goodman_coefficients(
    pressure_hpa: float = GOAD_GOODMAN_PRESSURE_HPA,
    temperature_k: float = GOAD_GOODMAN_TEMPERATURE_K,
    vapour_hpa: float = GOAD_GOODMAN_VAPOUR_HPA,
    earth_radius: float = R_MEAN,
) -> tuple[float, float, float, float, float]:
    """``(1e-6 N_d0, h_d (2 R + h_d), 1e-6 N_w0, h_w (2 R + h_w), R)`` of :func:`goad_goodman_delay`.

    The delay is then ``k_d (sqrt(a_d + (R sin)^2) - R sin) + k_w (sqrt(a_w + (R sin)^2) - R sin)``
    (also what the compiled GpsIns epoch, :mod:`navgym.gps_ins.epoch_kernel`, evaluates).
    """
    t, p, e, r = temperature_k, pressure_hpa, vapour_hpa, earth_radius
    h_d = 40136.0 + 148.72 * (t - 273.16)
    h_w = GOAD_GOODMAN_WET_HEIGHT_M
    n_d = 77.64 * p / t
    n_w = -12.96 * e / t + 3.718e5 * e / t**2
    return 1e-6 * n_d, h_d * (2.0 * r + h_d), 1e-6 * n_w, h_w * (2.0 * r + h_w), r


def saastamoinen_delay(
    elevation: ArrayLike, lat: ArrayLike, h: ArrayLike, humidity: float = 0.7
) -> NDArray[np.float64]:
    """Saastamoinen tropospheric delay with a standard atmosphere.

    Standard atmosphere at height h (RTKLIB ``tropmodel``; Saastamoinen 1972)::

        P = 1013.25 (1 - 2.2557e-5 h)^5.2568 hPa,  T = 15 - 6.5e-3 h + 273.16 K
        e = 6.108 humidity exp((17.15 T - 4684) / (T - 38.45)) hPa
        z = pi/2 - el
        Delta = 0.0022768 P / ((1 - 0.00266 cos 2 lat - 0.00028 h / 1000) cos z)
              + 0.002277 (1255 / T + 0.05) e / cos z

    Args:
        elevation: Elevation [rad], any shape (clipped at 0).
        lat: Receiver geodetic latitude [rad], broadcastable.
        h: Receiver height [m], broadcastable (clipped to 0..10 km for the atmosphere).
        humidity: Relative humidity in [0, 1].

    Returns:
        Slant delay [m], broadcast shape.
    """
    el = np.maximum(np.asarray(elevation, np.float64), 0.0)
    lat = np.asarray(lat, np.float64)
    hgt = np.clip(np.asarray(h, np.float64), 0.0, 1e4)
    p = 1013.25 * (1.0 - 2.2557e-5 * hgt) ** 5.2568
    temp = 15.0 - 6.5e-3 * hgt + 273.16
    e = 6.108 * humidity * np.exp((17.15 * temp - 4684.0) / (temp - 38.45))
    cos_z = np.maximum(np.sin(el), 1e-3)
    dry = 0.0022768 * p / (1.0 - 0.00266 * np.cos(2.0 * lat) - 0.00028 * hgt / 1e3) / cos_z
    wet = 0.002277 * (1255.0 / temp + 0.05) * e / cos_z
    return dry + wet
