"""Iridium geolocation fixes: their CEP radius and their errors (Benzerrouk 2014, §2.7d).

Benzerrouk 2014 (§2.7d, dynamic test from Belgium through France to Spain) reports Iridium
positions "delivered every 10 sec with an average error of 1 km", "outliers varying from 2 km to
10 km and in seven (07) cases superior than 100 km", and a measurement covariance set from the
CEP radius of each fix. It gives neither the CEP's law nor the outliers' rate; the model here
(all its numbers are arguments of :class:`IridiumFixNoise`) is:

* **CEP radius** reported with each fix, from the elevation ``el`` of the serving (highest)
  satellite: ``CEP = min(cep_zenith / sqrt(sin el), cep_max)`` (a low satellite locates worse).
  With ``cep_zenith = 650 m`` the CEP is 650 m overhead and 1.7 km at the 8.2 deg mask, about
  0.9 km on average over the constellation of :mod:`navgym.iridium.constellation`.
* **Nominal error**: circular Gaussian ``e ~ N(0, sigma^2 I_2)`` with the CEP's sigma,
  ``P(|e| <= CEP) = 1 - exp(-CEP^2 / (2 sigma^2)) = 1/2``, i.e. ``sigma = CEP / sqrt(2 ln 2) =
  CEP / 1.1774`` (:func:`cep_sigma`); the mean error ``sigma sqrt(pi / 2) = 1.06 CEP`` is about
  1 km.
* **Outliers** (the source's 2-10 km): with probability ``outlier_rate`` per fix the error is
  ``N(0, s^2 I_2)`` with ``s ~ U(outlier_sigma)``, 1.6-8 km by default, whose mean error
  ``1.25 s`` spans 2-10 km. **Gross outliers** (the source's "> 100 km", 7 in a trip of roughly
  a day, some 8000 fixes at 10 s: ``gross_rate = 1e-3``) likewise with ``s ~ U(gross_sigma)``,
  80-240 km (mean errors 100-300 km). The reported CEP does not change: the filter is not told.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.envs import arguments

__all__ = ["CEP_PER_SIGMA", "IridiumFixNoise", "cep_sigma"]

#: ``CEP / sigma`` of a circular Gaussian: ``sqrt(2 ln 2)`` (the median of a Rayleigh law).
CEP_PER_SIGMA = float(np.sqrt(2.0 * np.log(2.0)))


def cep_sigma(cep: ArrayLike) -> NDArray[np.float64]:
    """Per-axis sigma [m] of a circular Gaussian fix of CEP radius ``cep`` [m]: ``CEP / sqrt(2 ln 2)``."""
    return np.asarray(cep, np.float64) / CEP_PER_SIGMA


@dataclass(frozen=True)
class IridiumFixNoise:
    """The Iridium fixes' CEP law and error model (module docstring; assumed where the source is silent).

    Attributes:
        cep_zenith: CEP radius [m] with the serving satellite overhead.
        cep_max: Largest reported CEP radius [m].
        outlier_rate: Probability of a 2-10 km outlier per fix.
        outlier_sigma: Range of an outlier's per-axis sigma [m].
        gross_rate: Probability of a gross (> 100 km) outlier per fix.
        gross_sigma: Range of a gross outlier's per-axis sigma [m].

    """

    cep_zenith: float = 650.0
    cep_max: float = 3000.0
    outlier_rate: float = 0.03
    outlier_sigma: tuple[float, float] = (1600.0, 8000.0)
    gross_rate: float = 1e-3
    gross_sigma: tuple[float, float] = (80e3, 240e3)

    def __post_init__(self) -> None:
        arguments.real("cep_zenith", self.cep_zenith, 0.0, 1e6, low_open=True)
        arguments.real("cep_max", self.cep_max, self.cep_zenith, 1e7)
        arguments.real("outlier_rate", self.outlier_rate, 0.0, 1.0)
        arguments.real("gross_rate", self.gross_rate, 0.0, 1.0)
        arguments.interval("outlier_sigma", self.outlier_sigma, 0.0, 1e7)
        arguments.interval("gross_sigma", self.gross_sigma, 0.0, 1e7)

    def cep(self, elevation: ArrayLike) -> NDArray[np.float64]:
        """Reported CEP radius [m] for the serving satellite's elevation [rad] (NaN: ``cep_max``)."""
        s = np.sin(np.asarray(elevation, np.float64))
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.cep_zenith / np.sqrt(np.where(s > 0, s, np.nan))
        return np.minimum(np.nan_to_num(c, nan=self.cep_max), self.cep_max)

    def outlier_variance(self, u_kind: ArrayLike, u_size: ArrayLike) -> NDArray[np.float64]:
        """Per-axis variance [m^2] of the source's outliers, 0 where a fix is none.

        ``u_kind`` decides (gross below ``gross_rate``, an outlier below ``gross_rate +
        outlier_rate``), ``u_size`` draws the sigma uniformly in its range.
        """
        u, v = np.asarray(u_kind), np.asarray(u_size)
        gross = u < self.gross_rate
        out = ~gross & (u < self.gross_rate + self.outlier_rate)
        s_gross = self.gross_sigma[0] + v * (self.gross_sigma[1] - self.gross_sigma[0])
        s_out = self.outlier_sigma[0] + v * (self.outlier_sigma[1] - self.outlier_sigma[0])
        return np.where(gross, s_gross**2, np.where(out, s_out**2, 0.0))
