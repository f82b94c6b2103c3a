"""Single-point positioning (SPP): batched least squares on code pseudo-ranges.

Solves for receiver position and clock bias independently at each of B epochs (or episodes)
with no Python loop over them: every Gauss-Newton iteration builds ``(B, m, 4)`` geometry
matrices with a mask and solves ``(B, 4, 4)`` normal equations. :func:`spp_from_rinex` is the
RINEX workflow (ephemeris selection, transmission time, satellite clocks, Sagnac term).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.frames import ecef_to_geodetic, elevation_azimuth
from navgym.geo.wgs84 import C_LIGHT
from navgym.gnss.ephemeris import (
    ephemeris_clock,
    ephemeris_orbit,
    select_ephemeris,
    take_ephemeris,
)
from navgym.gnss.gpstime import week_and_tow
from navgym.gnss.ionosphere import klobuchar_delay
from navgym.gnss.measurements import sagnac_correction
from navgym.gnss.rinex import NavigationData, ObservationData
from navgym.gnss.troposphere import saastamoinen_delay
from navgym.gnss.visibility import check_mask_angle

__all__ = ["SppSolution", "solve_spp", "spp_from_rinex"]


class SppSolution(NamedTuple):
    """Batched SPP result.

    Attributes:
        position: Receiver ECEF position [m], ``(B, 3)``; NaN where fewer than 4 satellites.
        clock_bias_m: Receiver clock bias times c [m], ``(B,)``.
        used: Satellites used (mask after the elevation cut), ``(B, m)``.
        residuals: Post-fit residuals [m], ``(B, m)`` (0 where unused).
        valid: At least 4 satellites and a finite solution, ``(B,)``.
    """

    position: NDArray[np.float64]
    clock_bias_m: NDArray[np.float64]
    used: NDArray[np.bool_]
    residuals: NDArray[np.float64]
    valid: NDArray[np.bool_]


def solve_spp(
    pseudorange: ArrayLike,
    sat_pos: ArrayLike,
    mask: ArrayLike,
    mask_deg: float = 10.0,
    iono_alpha: ArrayLike | None = None,
    iono_beta: ArrayLike | None = None,
    tow: ArrayLike | None = None,
    troposphere: bool = False,
    iterations: int = 10,
    x0: ArrayLike | None = None,
) -> SppSolution:
    """Least-squares position and clock bias from corrected pseudo-ranges.

    Model (Touil & Ghadi 2012, eq. 5, Carvalho et al. 1997, eq. 10 with Delta_atm modelled)::

        rho_i = |r_s,i - r| + omega_e (x_s y - y_s x) / c + b + I_i + T_i

    with the Sagnac term of :func:`~navgym.gnss.measurements.sagnac_correction`, I the
    Klobuchar delay (when ``iono_alpha``/``iono_beta``/``tow`` are given) and T the Saastamoinen
    delay (``troposphere=True``). Gauss-Newton from the Earth's centre (or ``x0``) with rows
    ``[-(r_s - r)^T / |r_s - r|, 1]``. The elevation mask and the atmospheric terms need a
    position, so they apply once the estimate is more than 1000 km from the Earth's centre
    (from the second iteration when starting at the centre).

    Args:
        pseudorange: Pseudo-ranges already corrected for satellite clocks [m], ``(B, m)``.
        sat_pos: Satellite ECEF positions at transmission time [m], ``(B, m, 3)``.
        mask: Usable rows, bool ``(B, m)``.
        mask_deg: Elevation mask [deg], in [0, 90).
        iono_alpha: Klobuchar alpha (4,), or None for no ionosphere correction.
        iono_beta: Klobuchar beta (4,).
        tow: GPS time of week per epoch ``(B,)`` (needed with the ionosphere).
        troposphere: Apply the Saastamoinen standard-atmosphere delay.
        iterations: Gauss-Newton iterations.
        x0: Initial ``(B, 4)`` state ``[x, y, z, b]``; zeros if None.

    Returns:
        :class:`SppSolution`.

    Raises:
        ValueError: For inconsistent shapes or a mask angle outside [0, 90).
    """
    check_mask_angle(mask_deg)
    rho = np.asarray(pseudorange, np.float64)
    sat = np.asarray(sat_pos, np.float64)
    base = np.asarray(mask, bool) & np.isfinite(rho)
    if rho.ndim != 2 or sat.shape != rho.shape + (3,) or base.shape != rho.shape:
        raise ValueError(
            f"pseudorange (B, m), sat_pos (B, m, 3), mask (B, m) expected; got {rho.shape}, "
            f"{sat.shape}, {base.shape}"
        )
    use_iono = iono_alpha is not None and iono_beta is not None
    if use_iono and tow is None:
        raise ValueError("tow is required with iono_alpha/iono_beta")
    rho = np.where(base, rho, 0.0)
    sat = np.where(base[..., None], sat, 0.0)
    x = np.zeros((rho.shape[0], 4)) if x0 is None else np.array(x0, np.float64)
    mask_rad = np.deg2rad(mask_deg)
    used = base
    for _ in range(iterations):
        r = x[:, None, :3]
        d = sat - r
        rng = np.linalg.norm(d, axis=-1)
        model = rng + sagnac_correction(r, sat) + x[:, None, 3]
        above = np.linalg.norm(x[:, :3], axis=-1) > 1e6
        el, az = elevation_azimuth(r, sat)
        used = base & (~above[:, None] | (el >= mask_rad))
        if np.any(above):
            lat, lon, h = ecef_to_geodetic(x[:, :3])
            atm = np.zeros_like(rho)
            if use_iono:
                atm += klobuchar_delay(
                    iono_alpha,
                    iono_beta,
                    lat[:, None],
                    lon[:, None],
                    el,
                    az,
                    np.asarray(tow, np.float64)[:, None],
                )
            if troposphere:
                atm += saastamoinen_delay(el, lat[:, None], h[:, None])
            model = model + np.where(above[:, None], atm, 0.0)
        g = np.concatenate([-d / np.maximum(rng, 1.0)[..., None], np.ones_like(rng)[..., None]], axis=-1)
        w = used.astype(np.float64)
        res = np.where(used, rho - model, 0.0)
        n = np.einsum("bmi,bm,bmj->bij", g, w, g)
        enough = used.sum(axis=1) >= 4
        n[~enough] = np.eye(4)
        rhs = np.einsum("bmi,bm->bi", g, w * res)
        dx = np.linalg.solve(n, rhs[..., None])[..., 0]
        x = x + np.where(enough[:, None], dx, 0.0)
    valid = enough & np.all(np.isfinite(x), axis=1)
    pos = np.where(valid[:, None], x[:, :3], np.nan)
    return SppSolution(pos, np.where(valid, x[:, 3], np.nan), used, res, valid)


def spp_from_rinex(
    obs: ObservationData,
    nav: NavigationData,
    mask_deg: float = 10.0,
    ionosphere: bool = False,
    troposphere: bool = False,
    code: str = "C1",
    epochs: ArrayLike | None = None,
) -> SppSolution:
    """SPP for the epochs of a RINEX observation file with a broadcast navigation file.

    Per (epoch, satellite), batched: the nearest-t_oe healthy ephemeris; transmission time
    ``t_tx = t_rx - P / c - dt_sv`` (receive time tags include the receiver clock, which the
    pseudo-range contains too); satellite position (IS-GPS-200 Table 20-IV) and clock
    (af0/af1/af2, relativistic term, T_GD) at t_tx; then :func:`solve_spp` with the Sagnac
    (Earth rotation during the signal flight) term in the range model.

    Args:
        obs: Observations (:func:`~navgym.gnss.rinex.read_rinex_obs`).
        nav: Navigation data (:func:`~navgym.gnss.rinex.read_rinex_nav`).
        mask_deg: Elevation mask [deg].
        ionosphere: Apply the broadcast Klobuchar model from the navigation header.
        troposphere: Apply the Saastamoinen standard-atmosphere model.
        code: Code observable to use.
        epochs: Indices of the epochs to solve (all if None).

    Returns:
        :class:`SppSolution` over the selected epochs.
    """
    sel = slice(None) if epochs is None else np.asarray(epochs)
    t_rx = obs.time[sel]
    prn = obs.prn[sel]
    rho = obs.observable(code)[sel]
    idx = select_ephemeris(nav.ephemeris, prn, t_rx[:, None])
    ok = (prn > 0) & np.isfinite(rho) & (idx >= 0)
    eph = take_ephemeris(nav.ephemeris, idx)
    t_tx = t_rx[:, None] - np.where(ok, rho, 0.0) / C_LIGHT
    dts = ephemeris_clock(eph, t_tx)
    t_tx = t_tx - dts
    orbit = ephemeris_orbit(eph, t_tx)
    dts = ephemeris_clock(eph, t_tx, orbit.eccentric_anomaly)
    corrected = rho + C_LIGHT * dts
    if ionosphere and not np.all(np.isfinite(nav.ion_alpha) & np.isfinite(nav.ion_beta)):
        raise ValueError("nav: ionosphere=True needs ION ALPHA/ION BETA in the header")
    return solve_spp(
        corrected,
        orbit.position,
        ok,
        mask_deg=mask_deg,
        iono_alpha=nav.ion_alpha if ionosphere else None,
        iono_beta=nav.ion_beta if ionosphere else None,
        tow=week_and_tow(t_rx)[1],
        troposphere=troposphere,
    )
