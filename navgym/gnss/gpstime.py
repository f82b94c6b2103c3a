"""GPS time: continuous seconds since the GPS epoch, weeks and seconds of week.

The package represents an instant as *GPS seconds*: ``t = week * 604800 + tow`` counted from the
GPS epoch 1980-01-06 00:00:00 GPST (IS-GPS-200 §20.3.3.5.2.4). A continuous scale makes orbit
times ``t - t_oe`` free of week cross-overs; float64 keeps ~0.2 us resolution for the next
decades, far below what orbits need (satellites move ~4 km/s: 1 mm).
"""

from __future__ import annotations

import datetime as _dt

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "SECONDS_PER_WEEK",
    "GPS_EPOCH",
    "gps_seconds",
    "week_and_tow",
    "gps_seconds_from_datetime",
    "resolve_week",
]

#: Seconds in a GPS week.
SECONDS_PER_WEEK: float = 604800.0
#: The GPS epoch (start of week 0) as a naive datetime in GPS time.
GPS_EPOCH = _dt.datetime(1980, 1, 6)


def gps_seconds(week: ArrayLike, tow: ArrayLike) -> NDArray[np.float64]:
    """Continuous GPS seconds ``t = week * 604800 + tow``.

    Args:
        week: Full GPS week number (not modulo 1024).
        tow: Time of week [s].

    Returns:
        GPS seconds since 1980-01-06, broadcast shape.
    """
    return np.asarray(week, np.float64) * SECONDS_PER_WEEK + np.asarray(tow, np.float64)


def week_and_tow(t: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Split GPS seconds into (full week, time of week)."""
    t = np.asarray(t, np.float64)
    week = np.floor(t / SECONDS_PER_WEEK)
    return week.astype(np.int64), t - week * SECONDS_PER_WEEK


def gps_seconds_from_datetime(
    year: int, month: int, day: int, hour: int = 0, minute: int = 0, second: float = 0.0
) -> float:
    """GPS seconds of a calendar instant expressed in GPS time (no leap seconds applied)."""
    whole = int(np.floor(second))
    d = _dt.datetime(year, month, day, hour, minute, whole) - GPS_EPOCH
    return d.days * 86400.0 + d.seconds + (second - whole)


def resolve_week(week_mod_1024: int, reference_week: int) -> int:
    """Resolve a 10-bit broadcast week number to the full week nearest ``reference_week``.

    IS-GPS-200 §20.3.3.3.1.1: the broadcast week is the full week modulo 1024. YUMA almanacs
    carry that truncated number (e.g. week 38 = week 2086 after two roll-overs).

    Args:
        week_mod_1024: Week number as broadcast (0..1023); full weeks pass through unchanged.
        reference_week: A full week near the true one.

    Returns:
        The full GPS week congruent to ``week_mod_1024`` modulo 1024 closest to
        ``reference_week``.
    """
    if week_mod_1024 >= 1024:
        return int(week_mod_1024)
    k = round((reference_week - week_mod_1024) / 1024)
    return int(week_mod_1024 + 1024 * k)
