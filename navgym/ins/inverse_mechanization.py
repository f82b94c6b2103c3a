"""Ideal IMU outputs from truth kinematics: the strapdown equations solved for f and omega.

The continuous-time local-navigation-frame mechanization (Groves 2013 eq. 5.46 and 5.54; seed 001
eq. 3 and 6 on the rotating Earth)::

    dC_b^n/dt = C_b^n [omega_ib^b x] - [omega_in^n x] C_b^n
    dv^n/dt   = C_b^n f_ib^b + g^n - (omega_en^n + 2 omega_ie^n) x v^n

solved for the sensed quantities gives::

    omega_ib^b = omega_nb^b + C_n^b (omega_ie^n + omega_en^n)
    f_ib^b     = C_n^b (dv^n/dt - g^n + (omega_en^n + 2 omega_ie^n) x v^n)

where ``omega_nb^b`` is the body rate relative to the local NED frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from navgym.ins.frame_rates import earth_rate_ned, gravity_ned, transport_rate_ned
from navgym.ins.types import ImuSample

__all__ = ["imu_from_kinematics"]


def imu_from_kinematics(
    lat: ArrayLike,
    h: ArrayLike,
    v_ned: ArrayLike,
    a_ned: ArrayLike,
    C_b_n: ArrayLike,
    omega_nb_b: ArrayLike,
    *,
    rotating_earth: bool = True,
) -> ImuSample:
    """Error-free specific force and angular rate of a body moving along truth kinematics.

    Args:
        lat: Geodetic latitude [rad], shape ``(...)``.
        h: Height [m], shape ``(...)``.
        v_ned: NED velocity [m/s], shape ``(..., 3)``.
        a_ned: Time derivative of ``v_ned`` [m/s^2], shape ``(..., 3)``.
        C_b_n: Body-to-NED DCM, shape ``(..., 3, 3)``.
        omega_nb_b: Body rate relative to NED, in body axes [rad/s], shape ``(..., 3)``.
        rotating_earth: If False, Earth and transport rates are zero (seed 001's flat model);
            must match the mechanization that will integrate the output.

    Returns:
        :class:`ImuSample` with ``f_ib^b`` and ``omega_ib^b`` of shape ``(..., 3)``.

    """
    lat = np.asarray(lat, np.float64)
    h = np.asarray(h, np.float64)
    v = np.asarray(v_ned, np.float64)
    a = np.asarray(a_ned, np.float64)
    C = np.asarray(C_b_n, np.float64)
    w_nb = np.asarray(omega_nb_b, np.float64)
    if rotating_earth:
        w_ie = earth_rate_ned(lat)
        w_en = transport_rate_ned(lat, h, v)
    else:
        w_ie = w_en = np.zeros_like(v)
    f_n = a - gravity_ned(lat, h) + np.cross(w_en + 2.0 * w_ie, v)
    f_b = np.einsum("...ji,...j->...i", C, f_n)
    w_ib = w_nb + np.einsum("...ji,...j->...i", C, w_ie + w_en)
    return ImuSample(f_b, w_ib)
