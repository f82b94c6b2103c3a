"""The critical 3-to-2 visible-satellite scenario of Carvalho et al. 1997, §V.

Carvalho et al. 1997 chose "a critical situation ... in which the number of visible satellites decays from 3
(the minimum required for 2D static positioning) to 2", with a 50 deg visibility mask,
pseudo-ranges every 1 s over 3600 s (Fig. 12). :func:`find_critical_window` finds such a place
and time in a real almanac by a deterministic grid search; :data:`CRITICAL_WINDOW_DEFAULT`
caches the answer for the packaged almanac (the test suite checks it still holds).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.geo.frames import geodetic_to_ecef, up_vector
from navgym.gnss.almanac import Almanac, almanac_orbit
from navgym.gnss.visibility import check_mask_angle

__all__ = [
    "CriticalWindow",
    "CRITICAL_WINDOW_DEFAULT",
    "visible_counts",
    "find_critical_window",
    "default_critical_window",
]

#: Search order starts at Toulouse (LAAS-CNRS, the authors' laboratory) [deg].
_HOME_LAT_DEG, _HOME_LON_DEG = 43.6, 1.44


class CriticalWindow(NamedTuple):
    """A place and time where the visible-satellite count goes from 3 to 2.

    Attributes:
        lat: Geodetic latitude [rad].
        lon: Longitude [rad].
        h: Height [m].
        t0: Start, GPS seconds.
        duration_s: Length of the run [s].
        mask_deg: Elevation mask [deg].
        counts: Satellites above the mask at ``t0 + k dt``, int ``(n,)``.
        switch_s: First time (from t0) with 2 satellites [s].
    """

    lat: float
    lon: float
    h: float
    t0: float
    duration_s: float
    mask_deg: float
    counts: NDArray[np.int64]
    switch_s: float


#: Cached search result for ``load_default_almanac()`` with mask 50 deg and 3600 s
#: (``find_critical_window`` reproduces it): (lat_deg, lon_deg, t0 GPS seconds).
#: 45 N 0 E (south-west France, 2 degrees from Toulouse), h = 0, from GPS week 2086
#: t.o.w. 503808 s (2020-01-03 19:56:48 GPST): 3 satellites above 50 deg for 1983 s,
#: then 2 until the end.
CRITICAL_WINDOW_DEFAULT: tuple[float, float, float] = (45.0, 0.0, 2086 * 604800.0 + 503808.0)


def visible_counts(
    almanac: Almanac, rx_ecef: NDArray[np.float64], t: NDArray[np.float64], mask_deg: float
) -> NDArray[np.int64]:
    """Numbers of satellites above the mask, ``(L, T)`` for receivers ``(L, 3)``, times ``(T,)``.

    Elevation test ``sin(el) = u . (r_s - r) / |r_s - r| > sin(mask)`` with ``u`` the
    ellipsoid normal (Carvalho et al. 1997, §IV-C-1).
    """
    check_mask_angle(mask_deg)
    rx = np.atleast_2d(np.asarray(rx_ecef, np.float64))
    pos = almanac_orbit(almanac, np.asarray(t, np.float64)).position  # (T, S, 3)
    up = up_vector(rx)
    s_mask = np.sin(np.deg2rad(mask_deg))
    out = np.empty((rx.shape[0], pos.shape[0]), np.int64)
    for start in range(0, rx.shape[0], 32):  # chunks bound memory; not a per-step loop
        r = rx[start : start + 32, None, None, :]
        d = pos[None] - r
        su = np.einsum("ltsi,li->lts", d, up[start : start + 32])
        dist = np.sqrt(np.einsum("ltsi,ltsi->lts", d, d))
        out[start : start + 32] = (su > s_mask * dist).sum(axis=-1)
    return out


def _is_three_to_two(c: NDArray[np.int64], lo: float, hi: float) -> int:
    """Index of the 3 -> 2 switch if ``c`` is 3...3 2...2 with the switch in [lo, hi]."""
    if c[0] != 3 or c[-1] != 2 or np.any((c != 2) & (c != 3)) or np.any(np.diff(c) > 0):
        return -1
    k = int(np.argmax(c == 2))
    return k if lo * (len(c) - 1) <= k <= hi * (len(c) - 1) else -1


def find_critical_window(
    almanac: Almanac,
    mask_deg: float = 50.0,
    duration_s: float = 3600.0,
    dt: float = 1.0,
    lat_step_deg: float = 5.0,
    lon_step_deg: float = 10.0,
    t_step_s: float = 60.0,
    search_s: float = 86400.0,
    switch_range: tuple[float, float] = (0.25, 0.75),
) -> CriticalWindow:
    """Find where and when the visible count goes 3 -> 2 during a run (Carvalho et al. 1997, §V).

    Deterministic grid search: receivers at h = 0 on a latitude/longitude grid (|lat| <= 60
    deg) ordered by distance from Toulouse, start times ``t_oa + k t_step`` within
    ``search_s``. Counts are screened every ``t_step`` and confirmed every ``dt``: the
    count must be exactly 3 then exactly 2 (one switch, no other value), the switch inside
    ``switch_range`` of the run.

    Args:
        almanac: Constellation.
        mask_deg: Elevation mask [deg] (Carvalho et al. 1997: 50).
        duration_s: Run length [s] (Carvalho et al. 1997: 3600).
        dt: Confirmation sampling [s] (Carvalho et al. 1997: 1).
        lat_step_deg: Latitude grid step [deg].
        lon_step_deg: Longitude grid step [deg].
        t_step_s: Start-time and screening step [s].
        search_s: Span of start times searched [s].
        switch_range: Allowed switch time as fractions of the run.

    Returns:
        The first :class:`CriticalWindow` in search order.

    Raises:
        ValueError: If ``mask_deg`` is outside [0, 90) or nothing is found.
    """
    check_mask_angle(mask_deg)
    lats = np.arange(-60.0, 60.0 + 1e-9, lat_step_deg)
    lons = np.arange(-180.0, 180.0 - 1e-9, lon_step_deg)
    glat, glon = (g.ravel() for g in np.meshgrid(lats, lons, indexing="ij"))
    dlon = np.deg2rad((glon - _HOME_LON_DEG + 180.0) % 360.0 - 180.0)
    cos_c = np.sin(np.deg2rad(glat)) * np.sin(np.deg2rad(_HOME_LAT_DEG)) + np.cos(np.deg2rad(glat)) * np.cos(
        np.deg2rad(_HOME_LAT_DEG)
    ) * np.cos(dlon)
    order = np.argsort(-cos_c, kind="stable")
    glat, glon = glat[order], glon[order]
    rx = geodetic_to_ecef(np.deg2rad(glat), np.deg2rad(glon), 0.0)
    t_ref = float(np.min(almanac.t_ref))
    n_win = int(round(duration_s / t_step_s))
    n_start = int(round(search_s / t_step_s))
    t_grid = t_ref + t_step_s * np.arange(n_start + n_win + 1)
    counts = visible_counts(almanac, rx, t_grid, mask_deg)
    n_fine = int(round(duration_s / dt)) + 1
    for li in range(rx.shape[0]):
        c = counts[li]
        for k in range(n_start):
            if _is_three_to_two(c[k : k + n_win + 1], *switch_range) < 0:
                continue
            t0 = float(t_grid[k])
            fine = visible_counts(almanac, rx[li], t0 + dt * np.arange(n_fine), mask_deg)[0]
            ks = _is_three_to_two(fine, *switch_range)
            if ks >= 0:
                return CriticalWindow(
                    float(np.deg2rad(glat[li])),
                    float(np.deg2rad(glon[li])),
                    0.0,
                    t0,
                    float(duration_s),
                    float(mask_deg),
                    fine,
                    ks * dt,
                )
    raise ValueError("no 3 -> 2 window found; widen the search (search_s, grid steps)")


def default_critical_window(almanac: Almanac, dt: float = 1.0) -> CriticalWindow:
    """:data:`CRITICAL_WINDOW_DEFAULT` with its visibility counts (mask 50 deg, 3600 s)."""
    lat_deg, lon_deg, t0 = CRITICAL_WINDOW_DEFAULT
    lat, lon = np.deg2rad(lat_deg), np.deg2rad(lon_deg)
    rx = geodetic_to_ecef(lat, lon, 0.0)
    n = int(round(3600.0 / dt)) + 1
    c = visible_counts(almanac, rx, t0 + dt * np.arange(n), 50.0)[0]
    ks = int(np.argmax(c == 2))
    return CriticalWindow(float(lat), float(lon), 0.0, float(t0), 3600.0, 50.0, c, ks * dt)
