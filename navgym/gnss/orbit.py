"""Keplerian satellite orbits in ECEF (Carvalho et al. 1997, eq. 9; IS-GPS-200 Table 20-IV), batched.

One routine serves both the almanac model (Carvalho et al. 1997, §IV-B; no harmonic corrections, no mean
motion correction, no inclination rate) and the full broadcast-ephemeris model (IS-GPS-200
Table 20-IV with the harmonic corrections ``C_uc, C_us, C_rc, C_rs, C_ic, C_is``). All orbit
parameters and the time since the reference epoch broadcast together, so ``tk`` of shape
``(T, 1)`` against parameters of shape ``(S,)`` yields ``(T, S, 3)`` positions without Python
loops.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.wgs84 import C_LIGHT, GM, OMEGA_E

__all__ = [
    "KEPLER_ITERATIONS",
    "RELATIVISTIC_F",
    "OrbitState",
    "solve_kepler",
    "keplerian_orbit",
    "ecef_acceleration",
]

#: Newton iterations on Kepler's equation; from E0 = M + e sin M, 5 steps reach machine
#: precision for GPS eccentricities (e < 0.03).
KEPLER_ITERATIONS: int = 5
#: Relativistic clock constant F = -2 sqrt(mu) / c^2 [s/m^(1/2)] (IS-GPS-200 §20.3.3.3.3.1).
RELATIVISTIC_F: float = -2.0 * np.sqrt(GM) / C_LIGHT**2


class OrbitState(NamedTuple):
    """Satellite state from a Keplerian orbit; arrays of the broadcast parameter shape.

    Attributes:
        position: ECEF position [m], shape ``(..., 3)``.
        velocity: ECEF velocity (time derivative of the ECEF position) [m/s], ``(..., 3)``.
        eccentric_anomaly: E_k [rad], shape ``(...)`` (for the relativistic clock term).
    """

    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    eccentric_anomaly: NDArray[np.float64]


def solve_kepler(mean_anomaly: ArrayLike, e: ArrayLike) -> NDArray[np.float64]:
    """Solve Kepler's equation ``M = E - e sin E`` for the eccentric anomaly E.

    Carvalho et al. 1997, §IV-C-2 ("Kepler's equation", written there without the eccentricity factor), by
    a fixed number of Newton steps ``E <- E - (E - e sin E - M) / (1 - e cos E)``.

    Args:
        mean_anomaly: M [rad], any shape.
        e: Eccentricity, broadcastable with ``mean_anomaly`` (0 <= e < 0.3 for fast convergence).

    Returns:
        E [rad], broadcast shape.
    """
    m = np.asarray(mean_anomaly, np.float64)
    e = np.asarray(e, np.float64)
    ecc = m + e * np.sin(m)
    for _ in range(KEPLER_ITERATIONS):
        ecc = ecc - (ecc - e * np.sin(ecc) - m) / (1.0 - e * np.cos(ecc))
    return ecc


def keplerian_orbit(
    tk: ArrayLike,
    sqrt_a: ArrayLike,
    e: ArrayLike,
    m0: ArrayLike,
    omega: ArrayLike,
    i0: ArrayLike,
    omega0: ArrayLike,
    omega_dot: ArrayLike,
    toe: ArrayLike,
    delta_n: ArrayLike = 0.0,
    idot: ArrayLike = 0.0,
    cuc: ArrayLike = 0.0,
    cus: ArrayLike = 0.0,
    crc: ArrayLike = 0.0,
    crs: ArrayLike = 0.0,
    cic: ArrayLike = 0.0,
    cis: ArrayLike = 0.0,
) -> OrbitState:
    """ECEF position and velocity of satellites from Keplerian elements.

    IS-GPS-200 Table 20-IV (Carvalho et al. 1997, eq. 9 and the orbit equations after it)::

        A = sqrt_a^2,  n = sqrt(mu / A^3) + delta_n,  M_k = M_0 + n t_k
        E_k - e sin E_k = M_k,   nu_k = atan2(sqrt(1 - e^2) sin E_k, cos E_k - e)
        Phi_k = nu_k + omega
        u_k = Phi_k + C_us sin 2Phi_k + C_uc cos 2Phi_k
        r_k = A (1 - e cos E_k) + C_rs sin 2Phi_k + C_rc cos 2Phi_k
        i_k = i_0 + IDOT t_k + C_is sin 2Phi_k + C_ic cos 2Phi_k
        Omega_k = Omega_0 + (Omega_dot - omega_e) t_k - omega_e t_oe
        x = r_k (cos u_k cos Omega_k - sin u_k cos i_k sin Omega_k)
        y = r_k (cos u_k sin Omega_k + sin u_k cos i_k cos Omega_k)
        z = r_k sin u_k sin i_k

    ``Omega_0`` is the right ascension at the *start of the week* (YUMA "Right Ascen at Week",
    RINEX OMEGA0), so Carvalho et al. 1997's ``Omega(t) = Omega_0 + Omega_dot (t - t_a) - omega_E (t -
    t_week)`` is the line for Omega_k with ``t - t_week = t_k + t_oe``. The velocity is the
    analytic time derivative of these expressions (e.g. IS-GPS-200 rev. N Table 20-IV, "SV
    velocity"), expressed in the rotating ECEF frame.

    Args:
        tk: Time since the reference epoch t - t_oe [s] (continuous GPS seconds difference).
        sqrt_a: Square root of the semi-major axis [m^(1/2)].
        e: Eccentricity.
        m0: Mean anomaly at the reference epoch [rad].
        omega: Argument of perigee [rad].
        i0: Inclination at the reference epoch [rad].
        omega0: Longitude of the ascending node at the start of the week [rad].
        omega_dot: Rate of right ascension [rad/s].
        toe: Reference time of week t_oe (almanac t_oa) [s].
        delta_n: Mean motion correction [rad/s].
        idot: Inclination rate [rad/s].
        cuc: Argument-of-latitude cosine harmonic correction [rad].
        cus: Argument-of-latitude sine harmonic correction [rad].
        crc: Orbit-radius cosine harmonic correction [m].
        crs: Orbit-radius sine harmonic correction [m].
        cic: Inclination cosine harmonic correction [rad].
        cis: Inclination sine harmonic correction [rad].

    Returns:
        :class:`OrbitState` with arrays of the broadcast shape of all inputs.
    """
    tk = np.asarray(tk, np.float64)
    a = np.asarray(sqrt_a, np.float64) ** 2
    e = np.asarray(e, np.float64)
    n0 = np.sqrt(GM / (a * a * a))
    n = n0 + delta_n
    ecc = solve_kepler(m0 + n * tk, e)
    sin_e, cos_e = np.sin(ecc), np.cos(ecc)
    one_m_ecos = 1.0 - e * cos_e
    sq = np.sqrt(1.0 - e * e)
    nu = np.arctan2(sq * sin_e, cos_e - e)
    phi = nu + omega
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    u = phi + cus * s2 + cuc * c2
    r = a * one_m_ecos + crs * s2 + crc * c2
    inc = i0 + idot * tk + cis * s2 + cic * c2
    node_rate = omega_dot - OMEGA_E
    node = omega0 + node_rate * tk - OMEGA_E * toe

    # Rates (derivatives of the lines above).
    e_dot = n / one_m_ecos
    nu_dot = e_dot * sq / one_m_ecos
    u_dot = nu_dot * (1.0 + 2.0 * (cus * c2 - cuc * s2))
    r_dot = a * e * sin_e * e_dot + 2.0 * nu_dot * (crs * c2 - crc * s2)
    i_dot = idot + 2.0 * nu_dot * (cis * c2 - cic * s2)

    cu, su = np.cos(u), np.sin(u)
    ci, si = np.cos(inc), np.sin(inc)
    cn, sn = np.cos(node), np.sin(node)
    xp, yp = r * cu, r * su
    xp_dot = r_dot * cu - r * su * u_dot
    yp_dot = r_dot * su + r * cu * u_dot

    shape = np.broadcast_shapes(xp.shape, cn.shape, ci.shape)
    pos = np.empty(shape + (3,))
    vel = np.empty(shape + (3,))
    pos[..., 0] = xp * cn - yp * ci * sn
    pos[..., 1] = xp * sn + yp * ci * cn
    pos[..., 2] = yp * si
    vel[..., 0] = xp_dot * cn - yp_dot * ci * sn + yp * si * sn * i_dot - node_rate * pos[..., 1]
    vel[..., 1] = xp_dot * sn + yp_dot * ci * cn - yp * si * cn * i_dot + node_rate * pos[..., 0]
    vel[..., 2] = yp_dot * si + yp * ci * i_dot
    return OrbitState(pos, vel, np.broadcast_to(ecc, shape))


def ecef_acceleration(position: ArrayLike, velocity: ArrayLike) -> NDArray[np.float64]:
    """Two-body acceleration of a satellite expressed in the rotating ECEF frame.

    ``a = -mu r / |r|^3 - 2 Omega x v - Omega x (Omega x r)`` with ``Omega = (0, 0, omega_e)``
    (gravity, Coriolis and centrifugal terms; J2 and other perturbations, ~1e-3 of the
    central term, are neglected). Used for the transmit-time velocity in range rates.

    Args:
        position: ECEF positions [m], ``(..., 3)``.
        velocity: ECEF velocities [m/s], ``(..., 3)``.

    Returns:
        Accelerations [m/s^2], ``(..., 3)``.
    """
    r = np.asarray(position, np.float64)
    v = np.asarray(velocity, np.float64)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    n = np.sqrt(x * x + y * y + z * z)
    g = GM / (n * n * n)
    w2 = OMEGA_E * OMEGA_E
    out = np.empty(np.broadcast_shapes(r.shape, v.shape))
    out[..., 0] = (w2 - g) * x + 2.0 * OMEGA_E * v[..., 1]
    out[..., 1] = (w2 - g) * y - 2.0 * OMEGA_E * v[..., 0]
    out[..., 2] = -g * z
    return out
