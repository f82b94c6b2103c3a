"""Signal quality of GNSS rows: carrier-to-noise density C/N0 and the code noise it causes (batched).

What a receiver reports for each tracked satellite besides the pseudo-range: its C/N0 [dB-Hz]
and, from the almanac, its elevation. A real receiver's pseudo-range noise follows its C/N0
through the code-tracking loop; this module gives both ends of that chain, so a simulator can
draw C/N0 from the physics of an episode (elevation, obstruction, interference) and the
pseudo-range noise from that C/N0, and a classical baseline can weight rows the way standard
methods do. Every function is pure and broadcasts over any leading axes (episodes, rows).

* **Nominal C/N0 against elevation** (:func:`nominal_cn0_dbhz`): a smooth antenna-gain model
  ``C/N0 = C_h + (C_z - C_h) sin(el)`` between the horizon value ``C_h`` and the zenith value
  ``C_z`` (defaults 32 and 48 dB-Hz, the open-sky range of a GPS L1 C/A patch antenna; Kaplan &
  Hegarty 2006, ch. 8 and ch. 9 give received power and C/N0 in this range). A model choice
  with documented parameters, not a fit to one antenna.
* **Effective C/N0 under interference** (:func:`effective_cn0_dbhz`): wide-band interference of
  jammer-to-signal ratio ``J/S`` adds ``J/S / (Q R_c)`` to the noise density, so
  ``1 / (C/N0)_eff = 1 / (C/N0) + (J/S) / (Q R_c)`` with the chip rate ``R_c`` and the
  spectral-separation factor ``Q`` (1 narrow-band, 1.5 matched spectrum, 2 broad-band noise;
  Kaplan & Hegarty 2006, ch. 9). Every row of a receiver sees the same jammer, so jamming lowers
  the C/N0 of all rows together.
* **Code-tracking jitter** (:func:`dll_jitter_m`): the thermal-noise jitter of a non-coherent
  early-minus-late power delay lock loop,
  ``sigma_tau^2 = B_L d / (2 c/n0) (1 + 2 / ((2 - d) T c/n0))`` chips^2, with the loop's noise
  bandwidth ``B_L`` [Hz], the early-late spacing ``d`` [chips], the predetection integration
  time ``T`` [s] and ``c/n0`` the linear C/N0 [Hz] (Kaplan & Hegarty 2006, ch. 5, DLL
  measurement errors); times the chip length ``c / R_c`` (293.05 m for C/A code) in metres.
* **The SIGMA-epsilon variance model** (:func:`sigma_epsilon_variance`):
  ``sigma^2 = C_i 10^(-C/N0 / 10)`` (Hartinger & Brunner 1999), the C/N0-based weighting of
  classical receivers and post-processing; it is the large-C/N0 limit of the DLL jitter above
  with ``C_i = B_L d / 2 (c / R_c)^2``.
* **Elevation weighting** (:func:`elevation_variance`): ``sigma^2 = a^2 + b^2 / sin^2(el)``
  (RTKLIB manual, eq. E.6.24; RTKLIB's ``varerr`` divides by ``sin(el)`` unsquared).
* **What the receiver reports** (:func:`reported_cn0_dbhz`): the true C/N0 plus the estimator's
  noise, rounded to the receiver's resolution; rows under the tracking threshold are lost
  (:func:`tracked`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.wgs84 import C_LIGHT

__all__ = [
    "CA_CHIP_RATE_HZ",
    "CA_CHIP_LENGTH_M",
    "TRACKING_THRESHOLD_DBHZ",
    "nominal_cn0_dbhz",
    "effective_cn0_dbhz",
    "dll_jitter_m",
    "sigma_epsilon_variance",
    "sigma_epsilon_constant",
    "elevation_variance",
    "reported_cn0_dbhz",
    "tracked",
]

#: GPS L1 C/A chip rate R_c [chips/s] (IS-GPS-200).
CA_CHIP_RATE_HZ: float = 1.023e6
#: Length of one C/A chip c / R_c [m].
CA_CHIP_LENGTH_M: float = C_LIGHT / CA_CHIP_RATE_HZ
#: C/N0 [dB-Hz] below which a row loses code lock (a typical tracking threshold of a
#: consumer receiver's DLL/PLL; Kaplan & Hegarty 2006, ch. 5 put the PLL's at 25-30 dB-Hz).
TRACKING_THRESHOLD_DBHZ: float = 25.0


def _db_to_linear(x_db: ArrayLike) -> NDArray[np.float64]:
    return np.power(10.0, np.asarray(x_db, np.float64) / 10.0)


def nominal_cn0_dbhz(
    elevation_rad: ArrayLike, zenith_dbhz: float = 48.0, horizon_dbhz: float = 32.0
) -> NDArray[np.float64]:
    """Open-sky C/N0 [dB-Hz] of rows at ``elevation_rad``: ``C_h + (C_z - C_h) sin(max(el, 0))``.

    Args:
        elevation_rad: Elevations [rad], any shape.
        zenith_dbhz: C/N0 of a satellite at the zenith ``C_z``.
        horizon_dbhz: C/N0 at the horizon ``C_h`` (``<= zenith_dbhz``).

    Raises:
        ValueError: if ``horizon_dbhz > zenith_dbhz``.
    """
    if not horizon_dbhz <= zenith_dbhz:
        raise ValueError(
            f"horizon_dbhz must not exceed zenith_dbhz; got horizon_dbhz={horizon_dbhz!r}, "
            f"zenith_dbhz={zenith_dbhz!r}"
        )
    el = np.asarray(elevation_rad, np.float64)
    return horizon_dbhz + (zenith_dbhz - horizon_dbhz) * np.sin(np.clip(el, 0.0, np.pi / 2))


def effective_cn0_dbhz(
    cn0_dbhz: ArrayLike, jammer_to_signal_db: ArrayLike, q: float = 2.0, chip_rate_hz: float = CA_CHIP_RATE_HZ
) -> NDArray[np.float64]:
    """``(C/N0)_eff`` [dB-Hz] under wide-band interference: ``1/(C/N0)_eff = 1/(C/N0) + (J/S)/(Q R_c)``.

    Args:
        cn0_dbhz: C/N0 without interference [dB-Hz].
        jammer_to_signal_db: Jammer-to-signal power ratio ``J/S`` [dB]; ``-inf`` is no jammer.
        q: Spectral-separation factor ``Q`` (2: broad-band noise jammer).
        chip_rate_hz: Chip rate ``R_c`` [chips/s].
    """
    if not (q > 0 and chip_rate_hz > 0):
        raise ValueError(f"q and chip_rate_hz must be positive; got q={q!r}, chip_rate_hz={chip_rate_hz!r}")
    inv = 1.0 / _db_to_linear(cn0_dbhz) + _db_to_linear(jammer_to_signal_db) / (q * chip_rate_hz)
    return -10.0 * np.log10(inv)


def dll_jitter_m(
    cn0_dbhz: ArrayLike,
    loop_bandwidth_hz: float = 1.0,
    spacing_chips: float = 1.0,
    integration_s: float = 0.02,
    chip_length_m: float = CA_CHIP_LENGTH_M,
) -> NDArray[np.float64]:
    """Thermal-noise code jitter [m] of a non-coherent early-minus-late power DLL (module docstring).

    ``sigma = (c / R_c) sqrt(B_L d / (2 c/n0) (1 + 2 / ((2 - d) T c/n0)))``.

    Args:
        cn0_dbhz: C/N0 of the rows [dB-Hz].
        loop_bandwidth_hz: DLL noise bandwidth ``B_L`` [Hz].
        spacing_chips: Early-late correlator spacing ``d`` [chips], in (0, 1].
        integration_s: Predetection integration time ``T`` [s].
        chip_length_m: Chip length ``c / R_c`` [m].
    """
    if not (loop_bandwidth_hz > 0 and 0 < spacing_chips <= 1 and integration_s > 0 and chip_length_m > 0):
        raise ValueError(
            "dll_jitter_m needs loop_bandwidth_hz > 0, 0 < spacing_chips <= 1, integration_s > 0 and "
            f"chip_length_m > 0; got {loop_bandwidth_hz!r}, {spacing_chips!r}, {integration_s!r}, "
            f"{chip_length_m!r}"
        )
    cn0 = _db_to_linear(cn0_dbhz)
    d = spacing_chips
    var_chips = loop_bandwidth_hz * d / (2.0 * cn0) * (1.0 + 2.0 / ((2.0 - d) * integration_s * cn0))
    return chip_length_m * np.sqrt(var_chips)


def sigma_epsilon_variance(cn0_dbhz: ArrayLike, c_i: float) -> NDArray[np.float64]:
    """SIGMA-epsilon variance ``C_i 10^(-C/N0 / 10)`` [m^2] (Hartinger & Brunner 1999).

    Args:
        cn0_dbhz: C/N0 of the rows [dB-Hz].
        c_i: The model constant ``C_i`` [m^2 Hz].
    """
    if not c_i > 0:
        raise ValueError(f"c_i must be positive; got {c_i!r}")
    return c_i / _db_to_linear(cn0_dbhz)


def sigma_epsilon_constant(
    loop_bandwidth_hz: float = 1.0, spacing_chips: float = 1.0, chip_length_m: float = CA_CHIP_LENGTH_M
) -> float:
    """``C_i = B_L d / 2 (c / R_c)^2`` [m^2 Hz]: the SIGMA-epsilon constant of a DLL's high-C/N0 limit."""
    return loop_bandwidth_hz * spacing_chips / 2.0 * chip_length_m**2


def elevation_variance(
    elevation_rad: ArrayLike, a_m: float, b_m: float, min_elevation_rad: float = 0.0873
) -> NDArray[np.float64]:
    """Elevation-weighted variance ``a^2 + b^2 / sin^2(el)`` [m^2] (RTKLIB manual, eq. E.6.24).

    Elevations below ``min_elevation_rad`` (5 deg, RTKLIB's ``MIN_EL``) are taken at it.
    """
    if not (a_m >= 0 and b_m >= 0 and 0 < min_elevation_rad <= np.pi / 2):
        raise ValueError(
            f"elevation_variance needs a_m >= 0, b_m >= 0 and 0 < min_elevation_rad <= pi/2; got {a_m!r}, "
            f"{b_m!r}, {min_elevation_rad!r}"
        )
    s = np.sin(np.maximum(np.asarray(elevation_rad, np.float64), min_elevation_rad))
    return a_m**2 + b_m**2 / (s * s)


def reported_cn0_dbhz(
    cn0_dbhz: ArrayLike, normals: ArrayLike, sigma_db: float = 1.0, resolution_db: float = 1.0
) -> NDArray[np.float64]:
    """The receiver's C/N0 report: ``round((C/N0 + sigma_db n) / resolution) * resolution`` [dB-Hz].

    Args:
        cn0_dbhz: True C/N0 [dB-Hz].
        normals: Standard normals of the same shape (drawn from the episode's generator).
        sigma_db: Standard deviation of the receiver's C/N0 estimator [dB].
        resolution_db: Resolution of the report [dB] (1 dB-Hz in NMEA GSV and most receivers'
            binary outputs); 0 reports unrounded values.
    """
    if not (sigma_db >= 0 and resolution_db >= 0):
        raise ValueError(f"sigma_db and resolution_db must be >= 0; got {sigma_db!r}, {resolution_db!r}")
    x = np.asarray(cn0_dbhz, np.float64) + sigma_db * np.asarray(normals, np.float64)
    return np.round(x / resolution_db) * resolution_db if resolution_db > 0 else x


def tracked(cn0_dbhz: ArrayLike, threshold_dbhz: float = TRACKING_THRESHOLD_DBHZ) -> NDArray[np.bool_]:
    """Rows whose C/N0 keeps code lock: ``C/N0 >= threshold_dbhz``."""
    return np.asarray(cn0_dbhz, np.float64) >= threshold_dbhz
