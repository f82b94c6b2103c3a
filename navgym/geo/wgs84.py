"""WGS-84 ellipsoid and Earth constants.

The ellipsoid (``A``, ``B``) and the GPS constants (``OMEGA_E``, ``GM``) are those of Carvalho
et al. 1997, §IV-A (table "WGS84 Reference Frame"). Two refinements are taken from the
GPS interface specification because the project also processes real broadcast data:

* ``OMEGA_E = 7.2921151467e-5`` rad/s (IS-GPS-200, Table 20-IV); Carvalho et al. 1997 round it to
  7.2921150e-5.
* ``GM = 3.986005e14`` m^3/s^2 is the IS-GPS-200 value, identical to Carvalho et al. 1997's mu.

Normal gravity uses the WGS-84 Somigliana constants of NIMA TR8350.2 (§4.2, eq. 4-1).
"""

from __future__ import annotations

#: Semi-major axis a [m] (Carvalho et al. 1997, §IV-A).
A: float = 6378137.0
#: Flattening f = 1/298.257223563 (WGS-84 defining parameter, TR8350.2 Table 3.1).
F: float = 1.0 / 298.257223563
#: Semi-minor axis b = a (1 - f) [m]; Carvalho et al. 1997, §IV-A quotes 6 356 752.314 m.
B: float = A * (1.0 - F)
#: First eccentricity squared e^2 = f (2 - f).
E2: float = F * (2.0 - F)
#: Second eccentricity squared e'^2 = e^2 / (1 - e^2).
EP2: float = E2 / (1.0 - E2)
#: Earth rotation rate omega_e [rad/s] (IS-GPS-200 Table 20-IV; Carvalho et al. 1997, §IV-A).
OMEGA_E: float = 7.2921151467e-5
#: Earth gravitational constant GM = mu [m^3/s^2] (IS-GPS-200; Carvalho et al. 1997, §IV-A).
GM: float = 3.986005e14
#: Speed of light in vacuum c [m/s] (IS-GPS-200 §20.3.4.3).
C_LIGHT: float = 299792458.0
#: Mean Earth radius used by simple spherical models [m] (IUGG R1 = (2a + b) / 3).
R_MEAN: float = (2.0 * A + B) / 3.0

#: Normal gravity at the equator gamma_e [m/s^2] (TR8350.2 Table 3.4).
GAMMA_E: float = 9.7803253359
#: Somigliana constant k = (b gamma_p) / (a gamma_e) - 1 (TR8350.2 eq. 4-1).
SOMIGLIANA_K: float = 0.00193185265241
#: m = omega^2 a^2 b / GM with the WGS-84 gravity GM = 3.986004418e14 (TR8350.2 Table 3.4).
GRAVITY_M: float = 0.00344978650684

__all__ = [
    "A",
    "F",
    "B",
    "E2",
    "EP2",
    "OMEGA_E",
    "GM",
    "C_LIGHT",
    "R_MEAN",
    "GAMMA_E",
    "SOMIGLIANA_K",
    "GRAVITY_M",
]
