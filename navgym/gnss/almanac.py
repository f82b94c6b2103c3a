"""YUMA almanac: parsing and Kepler propagation of the GPS constellation (Carvalho et al. 1997, §IV-B).

An :class:`Almanac` is a NamedTuple of arrays over satellites (axis ``S``). Satellite states at
GPS times ``t`` of any shape come from :func:`almanac_orbit` (positions/velocities of shape
``t.shape + (S, 3)``) without Python loops; :func:`take` gathers a per-episode subset
(``(B, m)`` indices) so only the tracked satellites are propagated.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.gnss.gpstime import SECONDS_PER_WEEK, resolve_week
from navgym.gnss.orbit import OrbitState, keplerian_orbit

__all__ = [
    "Almanac",
    "DEFAULT_ALMANAC_FILE",
    "DEFAULT_ALMANAC_WEEK",
    "parse_yuma",
    "load_default_almanac",
    "almanac_orbit",
    "almanac_clock",
    "take",
]

#: Package resource holding the default (real) almanac; see ``navgym/data/PROVENANCE.md``.
DEFAULT_ALMANAC_FILE = "yuma_gps_week2086_toa503808.txt"
#: Full GPS week of the default almanac (file week 38 after two 1024-week roll-overs).
DEFAULT_ALMANAC_WEEK = 2086

# YUMA key (case-insensitive prefix of the text before ':') -> Almanac field.
_KEYS: tuple[tuple[str, str], ...] = (
    ("id", "prn"),
    ("health", "health"),
    ("eccentricity", "e"),
    ("time of applicability", "toa"),
    ("orbital inclination", "i0"),
    ("rate of right ascen", "omega_dot"),
    ("sqrt(a)", "sqrt_a"),
    ("right ascen at", "omega0"),
    ("argument of perigee", "omega"),
    ("mean anom", "m0"),
    ("af0", "af0"),
    ("af1", "af1"),
    ("week", "week"),
)


class Almanac(NamedTuple):
    """GPS almanac, one entry per satellite (YUMA fields; IS-GPS-200 §20.3.3.5.1.2).

    Attributes:
        prn: PRN numbers, int ``(S,)``.
        health: Health word (0 = healthy), int ``(S,)``.
        e: Eccentricity ``(S,)``.
        toa: Time of applicability, seconds of week ``(S,)``.
        i0: Inclination [rad] ``(S,)``.
        omega_dot: Rate of right ascension [rad/s] ``(S,)``.
        sqrt_a: Square root of the semi-major axis [m^(1/2)] ``(S,)``.
        omega0: Right ascension at the start of the week [rad] ``(S,)``.
        omega: Argument of perigee [rad] ``(S,)``.
        m0: Mean anomaly at t_oa [rad] ``(S,)``.
        af0: Clock bias [s] ``(S,)``.
        af1: Clock drift [s/s] ``(S,)``.
        week: Full GPS week of t_oa, int ``(S,)``.
    """

    prn: NDArray[np.int64]
    health: NDArray[np.int64]
    e: NDArray[np.float64]
    toa: NDArray[np.float64]
    i0: NDArray[np.float64]
    omega_dot: NDArray[np.float64]
    sqrt_a: NDArray[np.float64]
    omega0: NDArray[np.float64]
    omega: NDArray[np.float64]
    m0: NDArray[np.float64]
    af0: NDArray[np.float64]
    af1: NDArray[np.float64]
    week: NDArray[np.int64]

    @property
    def t_ref(self) -> NDArray[np.float64]:
        """Reference epoch t_oa as continuous GPS seconds ``(S,)``."""
        return self.week * SECONDS_PER_WEEK + self.toa

    @property
    def semi_major_axis(self) -> NDArray[np.float64]:
        """Semi-major axis A = sqrt_a^2 [m] ``(S,)``."""
        return self.sqrt_a**2


def _flush(block: dict[str, float], path: str, line_no: int, records: list[dict[str, float]]):
    if not block:
        return
    missing = [f for _, f in _KEYS if f not in block]
    if missing:
        raise ValueError(f"{path}: line {line_no}: almanac block ends without {', '.join(missing)}")
    records.append(block)


def parse_yuma(
    path: str | os.PathLike[str], reference_week: int | None = None, healthy_only: bool = False
) -> Almanac:
    """Read a YUMA almanac file.

    Blocks start with a line of ``*`` and hold ``Key: value`` lines (the US Coast Guard YUMA
    format; orbit elements as in Carvalho et al. 1997, §IV-B): ID, Health, Eccentricity, Time of
    Applicability(s), Orbital Inclination(rad), Rate of Right Ascen(r/s), SQRT(A) (m 1/2), Right
    Ascen at Week (or at TOA)(rad), Argument of Perigee(rad), Mean Anom(rad), Af0(s), Af1(s/s),
    week.

    Args:
        path: File path.
        reference_week: Full GPS week near the almanac's; when given, the file's 10-bit week
            is resolved to the nearest full week (:func:`navgym.gnss.gpstime.resolve_week`).
        healthy_only: Drop satellites whose health word is non-zero.

    Returns:
        The :class:`Almanac`, satellites in file order.

    Raises:
        ValueError: If the file is malformed; the message names the file and the line.
    """
    path = str(path)
    records: list[dict[str, float]] = []
    block: dict[str, float] = {}
    line_no = 0
    with open(path, encoding="ascii", errors="replace") as fh:
        for line_no, raw in enumerate(fh, start=1):
            line = raw.strip()
            if not line:
                continue
            if line.startswith("*"):
                _flush(block, path, line_no, records)
                block = {}
                continue
            key, sep, value = line.partition(":")
            if not sep:
                raise ValueError(f"{path}: line {line_no}: expected 'Key: value', got {line!r}")
            key_l = key.strip().lower()
            field = next((f for k, f in _KEYS if key_l.startswith(k)), None)
            if field is None:
                raise ValueError(f"{path}: line {line_no}: unknown almanac key {key.strip()!r}")
            if field in block:
                raise ValueError(
                    f"{path}: line {line_no}: duplicate {key.strip()!r} (missing '****' header?)"
                )
            try:
                block[field] = float(value.strip().replace("D", "E").replace("d", "e"))
            except ValueError:
                raise ValueError(
                    f"{path}: line {line_no}: bad number {value.strip()!r} for {key.strip()!r}"
                ) from None
            if not np.isfinite(block[field]):
                raise ValueError(f"{path}: line {line_no}: non-finite {key.strip()!r}")
    _flush(block, path, line_no, records)
    if not records:
        raise ValueError(f"{path}: line {line_no}: no almanac blocks found")
    cols = {f: np.array([r[f] for r in records]) for _, f in _KEYS}
    for f in ("prn", "health", "week"):
        cols[f] = cols[f].astype(np.int64)
    if reference_week is not None:
        cols["week"] = np.array([resolve_week(int(w), reference_week) for w in cols["week"]])
    bad = np.flatnonzero((cols["e"] < 0) | (cols["e"] >= 1) | (cols["sqrt_a"] <= 0))
    if bad.size:
        raise ValueError(
            f"{path}: line {line_no}: PRN {int(cols['prn'][bad[0]])} has e or A outside an elliptic orbit"
        )
    alm = Almanac(**cols)
    if healthy_only:
        alm = take(alm, np.flatnonzero(alm.health == 0))
    return alm


def load_default_almanac(healthy_only: bool = True) -> Almanac:
    """Load the packaged real almanac (GPS week 2086, t_oa = 503808 s, 31 satellites).

    US Coast Guard YUMA almanac of 2020-01-03 via the MAAST tool (Stanford GPS Lab); see
    ``navgym/data/PROVENANCE.md``. This is the default constellation of the simulator.

    Args:
        healthy_only: Drop unhealthy satellites (PRN 4 has health 63 in this file: 30 remain).

    Returns:
        The :class:`Almanac` with full week numbers.
    """
    res = resources.files("navgym").joinpath("data", DEFAULT_ALMANAC_FILE)
    with resources.as_file(res) as p:
        return parse_yuma(Path(p), reference_week=DEFAULT_ALMANAC_WEEK, healthy_only=healthy_only)


def take(almanac: Almanac, index: ArrayLike) -> Almanac:
    """Gather satellites: every field becomes ``field[index]`` (any index shape, e.g. (B, m))."""
    idx = np.asarray(index)
    return Almanac(*(np.asarray(f)[idx] for f in almanac))


def almanac_orbit(almanac: Almanac, t: ArrayLike) -> OrbitState:
    """Satellite ECEF position and velocity from the almanac at GPS times ``t``.

    Carvalho et al. 1997, eq. 9 with the orbit equations after it; IS-GPS-200 §20.3.3.5.2.1 (almanac: the
    Table 20-IV model with ``delta_n = IDOT = C_xx = 0``). ``t_k = t - (week * 604800 + t_oa)``
    on the continuous GPS-seconds scale, so week cross-overs need no special case.

    Args:
        almanac: Almanac with satellite axis ``(S,)`` (or gathered ``(B, m)`` via :func:`take`).
        t: GPS seconds. Shape ``(...)`` gives outputs ``(..., S, 3)`` for an ``(S,)`` almanac;
            for a gathered ``(B, m)`` almanac pass ``t`` of shape ``(B, 1)`` (or scalar).

    Returns:
        :class:`~navgym.gnss.orbit.OrbitState` (positions, velocities, eccentric anomalies).
    """
    t = np.asarray(t, np.float64)
    if almanac.e.ndim == 1 and t.ndim > 0:
        t = t[..., None]
    tk = t - almanac.t_ref
    return keplerian_orbit(
        tk,
        almanac.sqrt_a,
        almanac.e,
        almanac.m0,
        almanac.omega,
        almanac.i0,
        almanac.omega0,
        almanac.omega_dot,
        almanac.toa,
    )


def almanac_clock(almanac: Almanac, t: ArrayLike) -> NDArray[np.float64]:
    """Satellite clock offset from the almanac, ``dt_sv = a_f0 + a_f1 (t - t_oa)`` [s].

    Carvalho et al. 1997, eq. 9 (third line); IS-GPS-200 §20.3.3.5.2.3. Broadcasting as in
    :func:`almanac_orbit`.
    """
    t = np.asarray(t, np.float64)
    if almanac.e.ndim == 1 and t.ndim > 0:
        t = t[..., None]
    return almanac.af0 + almanac.af1 * (t - almanac.t_ref)
