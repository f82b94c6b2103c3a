"""Klobuchar broadcast ionosphere model (IS-GPS-200 §20.3.3.5.2.5, Figure 20-4)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.wgs84 import C_LIGHT

__all__ = ["klobuchar_delay"]


def klobuchar_delay(
    alpha: ArrayLike,
    beta: ArrayLike,
    lat: ArrayLike,
    lon: ArrayLike,
    elevation: ArrayLike,
    azimuth: ArrayLike,
    tow: ArrayLike,
) -> NDArray[np.float64]:
    """L1 ionospheric group delay from the broadcast Klobuchar coefficients [m].

    IS-GPS-200 Figure 20-4 (angles in semicircles, sc)::

        psi = 0.0137 / (E + 0.11) - 0.022                  (E elevation in sc)
        phi_i = clip(phi_u + psi cos A, -0.416, 0.416)
        lambda_i = lambda_u + psi sin A / cos(phi_i)
        phi_m = phi_i + 0.064 cos(lambda_i - 1.617)
        t = (4.32e4 lambda_i + GPS time) mod 86400
        F = 1 + 16 (0.53 - E)^3
        AMP = max(sum alpha_n phi_m^n, 0),  PER = max(sum beta_n phi_m^n, 72000)
        x = 2 pi (t - 50400) / PER
        T_iono = F (5e-9 + AMP (1 - x^2/2 + x^4/24)) if |x| < 1.57 else F 5e-9

    Args:
        alpha: alpha_0..alpha_3, shape (4,) (RINEX ``ION ALPHA``).
        beta: beta_0..beta_3, shape (4,) (RINEX ``ION BETA``).
        lat: Receiver geodetic latitude [rad].
        lon: Receiver longitude [rad].
        elevation: Satellite elevation [rad].
        azimuth: Satellite azimuth [rad].
        tow: GPS time of week (or GPS seconds) [s].

    Returns:
        Delay [m] (``c T_iono``), broadcast shape of the angular inputs and ``tow``.
    """
    a = np.asarray(alpha, np.float64)
    b = np.asarray(beta, np.float64)
    if a.shape != (4,) or b.shape != (4,):
        raise ValueError(f"alpha and beta must have shape (4,), got {a.shape} and {b.shape}")
    el = np.asarray(elevation, np.float64) / np.pi
    az = np.asarray(azimuth, np.float64)
    phi_u = np.asarray(lat, np.float64) / np.pi
    lam_u = np.asarray(lon, np.float64) / np.pi
    psi = 0.0137 / (el + 0.11) - 0.022
    phi_i = np.clip(phi_u + psi * np.cos(az), -0.416, 0.416)
    lam_i = lam_u + psi * np.sin(az) / np.cos(phi_i * np.pi)
    phi_m = phi_i + 0.064 * np.cos((lam_i - 1.617) * np.pi)
    t = np.mod(4.32e4 * lam_i + np.asarray(tow, np.float64), 86400.0)
    f = 1.0 + 16.0 * (0.53 - el) * (0.53 - el) * (0.53 - el)
    amp = np.maximum(a[0] + phi_m * (a[1] + phi_m * (a[2] + phi_m * a[3])), 0.0)
    per = np.maximum(b[0] + phi_m * (b[1] + phi_m * (b[2] + phi_m * b[3])), 72000.0)
    x = 2.0 * np.pi * (t - 50400.0) / per
    x2 = x * x
    day = np.where(np.abs(x) < 1.57, amp * (1.0 - x2 / 2.0 + x2 * x2 / 24.0), 0.0)
    return C_LIGHT * f * (5e-9 + day)
