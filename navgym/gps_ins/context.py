"""GpsIns v3 context physics: the C/N0 -> pseudo-range noise chain and the jammer's J/S.

The building blocks of the v3 variant's receiver context (work in progress: the platform
does not call them yet). Pure, batched functions that broadcast over episodes and rows.

* **Pseudo-range sigma from C/N0** (:func:`pseudorange_sigma_m`): a row's code noise follows
  the DLL thermal jitter of :func:`navgym.gnss.signal_quality.dll_jitter_m` (Kaplan & Hegarty
  2006, ch. 5), scaled so that the open-sky value at the reference elevation ``el_ref``
  (45 degrees) equals the v2 nominal ``sigma_pr``::

      sigma(C/N0) = sigma_pr * jitter(C/N0) / jitter(C_nom(el_ref))

  with ``C_nom`` the nominal C/N0 of :func:`navgym.gnss.signal_quality.nominal_cn0_dbhz`. In
  its large-C/N0 limit this is the SIGMA-epsilon law ``sigma^2 ∝ 10^(-C/N0/10)`` (Hartinger &
  Brunner 1999).
* **J/S of a v2 jamming regime** (:func:`jammer_to_signal_db`): v2 adds a jamming variance
  ``jam_sigma^2`` to ``sigma_pr^2``. v3 acts through C/N0 instead; the J/S is the one that makes
  DLL jitter variance at the reference C/N0 grow by the same factor
  ``k^2 = 1 + (jam_sigma / sigma_pr)^2``. With ``u = 1 / (c/n0)`` the jitter variance is
  ``∝ u (1 + a u)``, ``a = 2 / ((2 - d) T)`` (the squaring loss), so the jammed
  ``u_j = (sqrt(1 + 4 a k^2 V) - 1) / (2 a)`` with ``V = u_ref (1 + a u_ref)``, and since
  ``1/(c/n0)_eff = 1/(c/n0) + (J/S)/(Q R_c)`` (Kaplan & Hegarty 2006, ch. 9),

      J/S = Q R_c (u_j - u_ref)        (linear; -inf dB without jamming)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.gnss import signal_quality as sq

__all__ = [
    "REFERENCE_ELEVATION_RAD",
    "JAMMER_Q",
    "pseudorange_sigma_m",
    "jammer_to_signal_db",
    "row_cn0_dbhz",
    "window_stats",
]

#: The "typical" elevation at which v3's open-sky pseudo-range sigma equals v2's sigma_pr [rad].
REFERENCE_ELEVATION_RAD: float = float(np.deg2rad(45.0))
#: Spectral-separation factor Q of the simulated jammer (broad-band noise; Kaplan & Hegarty 2006).
JAMMER_Q: float = 2.0


def _reference_cn0_dbhz() -> float:
    return float(sq.nominal_cn0_dbhz(REFERENCE_ELEVATION_RAD))


def pseudorange_sigma_m(cn0_dbhz: ArrayLike, sigma_pr: float) -> NDArray[np.float64]:
    """Pseudo-range noise sigma [m] of rows at ``cn0_dbhz``: ``sigma_pr jitter(C/N0) / jitter(C_ref)``."""
    ref = sq.dll_jitter_m(_reference_cn0_dbhz())
    return sigma_pr * sq.dll_jitter_m(cn0_dbhz) / ref


def jammer_to_signal_db(jam_sigma_m: ArrayLike, sigma_pr: float) -> NDArray[np.float64]:
    """J/S [dB] equivalent to v2's jamming sigma ``jam_sigma_m`` (module docstring); -inf at 0."""
    k2 = 1.0 + (np.asarray(jam_sigma_m, np.float64) / sigma_pr) ** 2
    a = 2.0 / ((2.0 - 1.0) * 0.02)  # dll_jitter_m's defaults: d = 1 chip, T = 20 ms
    u_ref = 10.0 ** (-_reference_cn0_dbhz() / 10.0)
    u_j = (np.sqrt(1.0 + 4.0 * a * k2 * u_ref * (1.0 + a * u_ref)) - 1.0) / (2.0 * a)
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(np.maximum(JAMMER_Q * sq.CA_CHIP_RATE_HZ * (u_j - u_ref), 0.0))


def row_cn0_dbhz(
    elevation_rad: ArrayLike,
    attenuation_db: ArrayLike,
    jammer_to_signal_db: ArrayLike,
) -> NDArray[np.float64]:
    """True C/N0 [dB-Hz] of rows: nominal at their elevation, less the obstruction, under the jammer.

    ``C/N0 = eff(C_nom(el) - L, J/S)`` with ``C_nom`` :func:`navgym.gnss.signal_quality.nominal_cn0_dbhz`,
    ``L >= 0`` the row's attenuation [dB] (NLOS / canyon, 0 in open sky) and ``eff`` the
    interference law :func:`navgym.gnss.signal_quality.effective_cn0_dbhz` (one J/S for all rows
    of an episode: pass it with a trailing axis of length 1).
    """
    clear = sq.nominal_cn0_dbhz(elevation_rad) - np.asarray(attenuation_db, np.float64)
    return sq.effective_cn0_dbhz(clear, jammer_to_signal_db, q=JAMMER_Q)


def window_stats(x: ArrayLike, t: int, window: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and standard deviation of ``x[:, t - window + 1 : t + 1]`` along the time axis (1).

    ``x`` is ``(B, T, ...)`` (e.g. an IMU's specific-force magnitude per sample); the window is
    shortened at the start of the episode.
    """
    a = np.asarray(x, np.float64)[:, max(0, t - window + 1) : t + 1]
    return a.mean(axis=1), a.std(axis=1)
