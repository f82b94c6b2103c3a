"""Ideal IMU outputs from truth kinematics: the strapdown equations solved for f and omega.

The continuous-time local-navigation-frame mechanization (Groves 2013, eq. 5.46 and 5.54;
Benzerrouk 2014, eq. 3 and 6 on the rotating Earth)::

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

from navgym.geo import OMEGA_E, gravity
from navgym.ins.frame_rates import transport_rate_components
from navgym.ins.types import ImuSample
from navgym.ins.vec3 import Vec3, cross

__all__ = ["imu_from_kinematics", "imu_from_components"]


def imu_from_components(
    lat: np.ndarray,
    h: np.ndarray,
    v: Vec3,
    a: Vec3,
    C: tuple[Vec3, Vec3, Vec3],
    w_nb: Vec3,
    rotating_earth: bool = True,
    *,
    sin_lat: np.ndarray | None = None,
    cos_lat: np.ndarray | None = None,
    w_en: Vec3 | None = None,
) -> tuple[Vec3, Vec3]:
    """:func:`imu_from_kinematics` on component arrays (the module docstring's equations).

    Every input and output vector is three arrays of one common shape (``C[i][j]`` is row i,
    column j of ``C_b^n``), so each step is an element-wise pass over contiguous memory instead
    of a reduction over a trailing axis of length 3 (NumPy's ``cross``, ``einsum`` and small
    ``matmul`` pay several times more per element there). ``omega_ie^n = omega_e (cos lat, 0,
    -sin lat)`` (Groves eq. 2.123), ``omega_en^n = (v_E / (R_N + h), -v_N / (R_M + h), -v_E tan
    lat / (R_N + h))`` (Groves eq. 5.44), ``g^n = (0, 0, gamma(lat, h))``.

    Returns:
        ``(f_ib^b, omega_ib^b)`` as component triples.
    """
    sl = np.sin(lat) if sin_lat is None else sin_lat
    if rotating_earth:
        cl = np.cos(lat) if cos_lat is None else cos_lat
        if w_en is None:
            w_en = transport_rate_components(lat, h, v, sl, cl)
        w_ie = (OMEGA_E * cl, 0.0, -OMEGA_E * sl)
    else:
        w_en = w_ie = (0.0, 0.0, 0.0)
    coriolis = cross(tuple(w_en[i] + 2.0 * w_ie[i] for i in range(3)), v)  # (w_en + 2 w_ie) x v
    f_n = (a[0] + coriolis[0], a[1] + coriolis[1], a[2] - gravity(lat, h, sl) + coriolis[2])
    w_in = tuple(w_ie[i] + w_en[i] for i in range(3))
    f_b = tuple(C[0][j] * f_n[0] + C[1][j] * f_n[1] + C[2][j] * f_n[2] for j in range(3))
    w_ib = tuple(w_nb[j] + (C[0][j] * w_in[0] + C[1][j] * w_in[1] + C[2][j] * w_in[2]) for j in range(3))
    return f_b, w_ib


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
        rotating_earth: If False, Earth and transport rates are zero (Benzerrouk 2014's flat model);
            must match the mechanization that will integrate the output.

    Returns:
        :class:`ImuSample` with ``f_ib^b`` and ``omega_ib^b`` of shape ``(..., 3)``.

    """
    v = np.asarray(v_ned, np.float64)
    a = np.asarray(a_ned, np.float64)
    C = np.asarray(C_b_n, np.float64)
    w_nb = np.asarray(omega_nb_b, np.float64)
    shape = np.broadcast_shapes(np.shape(lat), np.shape(h), v.shape[:-1], a.shape[:-1], C.shape[:-2])
    lat = np.broadcast_to(np.asarray(lat, np.float64), shape)
    h = np.broadcast_to(np.asarray(h, np.float64), shape)

    def comps(x: np.ndarray) -> Vec3:
        return tuple(np.broadcast_to(x[..., i], shape) for i in range(3))

    f_b, w_ib = imu_from_components(
        lat, h, comps(v), comps(a), tuple(comps(C[..., i, :]) for i in range(3)), comps(w_nb), rotating_earth
    )
    return ImuSample(np.stack(f_b, axis=-1), np.stack(w_ib, axis=-1))
