"""Generic pieces of a simulated GNSS receiver's own quality report (batched, pure).

A receiver reports with each fix the satellites it used, the dilution of precision of their
geometry and the C/N0 of each; from these it also estimates its own accuracy. The functions
here are the platform-independent links of that chain, as the platforms' context modules
(:mod:`navgym.robot2d.context`, :mod:`navgym.quadrotor.context`,
:mod:`navgym.pedestrian.context`) assemble them. Every function broadcasts over leading axes
(episodes, epochs).

* **HDOP** (:func:`hdop`): ``k_geo / sqrt(n_sv - 3)``: ``(G^T G)^-1`` of ``n`` well spread lines
  of sight shrinks like ``1 / (n - 3)`` once the four unknowns (position, clock) are fixed;
  ``k_geo`` is the geometry's luck (Kaplan & Hegarty 2006, ch. 7.1, DOP). ``inf`` below 4.
* **Jamming as J/S** (:func:`jammer_to_signal_db`): a v2 jamming regime adds ``jam_sigma^2`` to
  a fix variance ``sigma_ref^2``. Acting through C/N0 instead, ``1/(c/n0)_eff = 1/(c/n0) +
  (J/S)/(Q R_c)`` (Kaplan & Hegarty 2006, ch. 9) with ``J/S = Q R_c / (c/n0)_ref (jam_sigma /
  sigma_ref)^2`` multiplies the SIGMA-epsilon variance at ``(C/N0)_ref`` by exactly
  ``1 + (jam_sigma / sigma_ref)^2``: the v2 variance.
* **Range-error variance from C/N0** (:func:`uere_variance_factor`): the SIGMA-epsilon law
  ``sigma_i^2 = C_i 10^(-C/N0_i / 10)`` (Hartinger & Brunner 1999; the large-C/N0 limit of the
  DLL jitter, Kaplan & Hegarty 2006, ch. 5) averaged over the satellites used, relative to its
  value at ``(C/N0)_ref``: ``u = mean_i 10^(-(C/N0_i - C/N0_ref) / 10)``. A fix's noise per axis
  is then ``DOP sigma_ref sqrt(u)`` (``sigma_UERE = sigma_ref sqrt(u)``).
* **Held reports** (:func:`held`): a report is repeated until the next fix, with its age.
* **Trailing windows** (:func:`trailing_sums`): sums over the last ``W`` steps that ended by
  epoch ``k`` (0 at the start), for windowed IMU statistics.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.gnss.signal_quality import CA_CHIP_RATE_HZ, sigma_epsilon_variance

__all__ = ["hdop", "jammer_to_signal_db", "uere_variance_factor", "held", "trailing_sums"]


def hdop(n_sv: ArrayLike, k_geo: ArrayLike) -> NDArray[np.float64]:
    """``HDOP = k_geo / sqrt(n_sv - 3)`` (module docstring); ``inf`` below 4 satellites."""
    n = np.asarray(n_sv, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n >= 4, np.asarray(k_geo) / np.sqrt(np.maximum(n - 3.0, 1e-300)), np.inf)


def jammer_to_signal_db(
    jam_sigma: ArrayLike, sigma_ref_m: float, cn0_ref_dbhz: float, q: float = 2.0
) -> NDArray[np.float64]:
    """``J/S`` [dB] equivalent to a v2 jamming noise ``jam_sigma`` [m] (module docstring); -inf at 0.

    Args:
        jam_sigma: v2 jamming noise [m], any shape.
        sigma_ref_m: The fix sigma [m] that the jamming variance is added to in v2.
        cn0_ref_dbhz: C/N0 [dB-Hz] at which the SIGMA-epsilon model gives ``sigma_ref_m``.
        q: The jammer's spectral-separation factor ``Q`` (2: broad-band noise).
    """
    base = 10.0 * np.log10(q * CA_CHIP_RATE_HZ) - cn0_ref_dbhz
    with np.errstate(divide="ignore"):
        return base + 20.0 * np.log10(np.asarray(jam_sigma, np.float64) / sigma_ref_m)


def uere_variance_factor(cn0_dbhz: ArrayLike, used: ArrayLike, cn0_ref_dbhz: float) -> NDArray[np.float64]:
    """``u = mean over used satellites of 10^(-(C/N0_i - C/N0_ref)/10)`` along the last axis.

    The SIGMA-epsilon range variance relative to ``C/N0_ref`` (module docstring); ``inf`` where no
    satellite is used.

    Args:
        cn0_dbhz: Per-satellite C/N0 [dB-Hz] ``(..., n_channels)``.
        used: Whether each channel's satellite is used, same shape.
        cn0_ref_dbhz: The reference C/N0 [dB-Hz].
    """
    used = np.asarray(used, bool)
    v = np.where(used, sigma_epsilon_variance(cn0_dbhz, 10.0 ** (cn0_ref_dbhz / 10.0)), 0.0).sum(-1)
    cnt = used.sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(cnt > 0, v / np.maximum(cnt, 1), np.inf)


def held(values: ArrayLike, delivered: ArrayLike, dt: float) -> tuple[NDArray, NDArray[np.float64]]:
    """Forward-fill ``values (B, n, ...)`` from the epochs ``delivered (B, n)`` (epoch 0 counts).

    Returns:
        The held values and their age [s] ``(B, n)``.

    """
    values = np.asarray(values)
    B, n = values.shape[:2]
    k = np.arange(n)
    d = np.array(delivered, bool, copy=True)
    d[:, 0] = True
    last = np.maximum.accumulate(np.where(d, k, 0), axis=1)
    idx = last.reshape(last.shape + (1,) * (values.ndim - 2))
    return np.take_along_axis(values, np.broadcast_to(idx, values.shape), axis=1), (k - last) * dt


def trailing_sums(x: ArrayLike, window: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Sums of ``x (B, T, ...)`` over the steps ``max(0, k - window) .. k - 1`` for ``k = 0 .. T``.

    Returns:
        The sums ``(B, T + 1, ...)`` (0 at ``k = 0``) and the number of steps summed ``(T + 1,)``.

    """
    a = np.asarray(x, np.float64)
    n = a.shape[1]
    out = np.zeros((a.shape[0], n + 1) + a.shape[2:])
    for j in range(min(int(window), n)):  # the window's j-th last step (direct sums: no cumsum drift)
        out[:, j + 1 :] += a[:, : n - j]
    k = np.arange(n + 1)
    return out, k - np.maximum(k - int(window), 0)
