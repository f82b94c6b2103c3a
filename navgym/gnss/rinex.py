"""RINEX 2.x readers: GPS navigation (broadcast ephemeris) and observation files.

Own small fixed-column readers (RINEX 2.10/2.11, Gurtner & Estey, "RINEX: The Receiver
Independent Exchange Format Version 2.10", tables A3/A4). Loops run over lines only; the
results are arrays. Malformed input raises ``ValueError`` naming the file and the line.
"""

from __future__ import annotations

import os
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.gnss.gpstime import gps_seconds_from_datetime

__all__ = [
    "BroadcastEphemeris",
    "NavigationData",
    "ObservationData",
    "read_rinex_nav",
    "read_rinex_obs",
]


class BroadcastEphemeris(NamedTuple):
    """GPS broadcast ephemerides, one entry per navigation record (axis ``R``).

    Fields follow IS-GPS-200 Table 20-III and the RINEX 2 navigation record order. Times
    ``toc``/``toe`` are continuous GPS seconds (week from the record times 604800 plus the
    seconds of week); ``toe_sow`` keeps the seconds of week for the Omega_k formula.
    """

    prn: NDArray[np.int64]
    toc: NDArray[np.float64]
    af0: NDArray[np.float64]
    af1: NDArray[np.float64]
    af2: NDArray[np.float64]
    iode: NDArray[np.float64]
    crs: NDArray[np.float64]
    delta_n: NDArray[np.float64]
    m0: NDArray[np.float64]
    cuc: NDArray[np.float64]
    e: NDArray[np.float64]
    cus: NDArray[np.float64]
    sqrt_a: NDArray[np.float64]
    toe_sow: NDArray[np.float64]
    cic: NDArray[np.float64]
    omega0: NDArray[np.float64]
    cis: NDArray[np.float64]
    i0: NDArray[np.float64]
    crc: NDArray[np.float64]
    omega: NDArray[np.float64]
    omega_dot: NDArray[np.float64]
    idot: NDArray[np.float64]
    week: NDArray[np.int64]
    sv_accuracy: NDArray[np.float64]
    health: NDArray[np.float64]
    tgd: NDArray[np.float64]
    iodc: NDArray[np.float64]
    toe: NDArray[np.float64]


class NavigationData(NamedTuple):
    """Content of a RINEX 2 GPS navigation file.

    Attributes:
        ephemeris: :class:`BroadcastEphemeris` over records.
        ion_alpha: Klobuchar alpha_0..alpha_3 (``ION ALPHA``), shape (4,), NaN if absent.
        ion_beta: Klobuchar beta_0..beta_3 (``ION BETA``), shape (4,), NaN if absent.
    """

    ephemeris: BroadcastEphemeris
    ion_alpha: NDArray[np.float64]
    ion_beta: NDArray[np.float64]


class ObservationData(NamedTuple):
    """GPS observations of a RINEX 2 observation file on fixed slots.

    Attributes:
        approx_position: Header ``APPROX POSITION XYZ`` [m], shape (3,).
        obs_types: Observation type names in column order (e.g. ``("L1", "C1", "L2", "P2")``).
        time: Epoch receive times (GPS seconds), shape ``(E,)``.
        prn: GPS PRN per slot, int ``(E, S)``, 0 for empty slots (S = most GPS satellites in an
            epoch; slots keep the file's order).
        values: Observations ``(E, S, n_types)``, NaN where missing.
    """

    approx_position: NDArray[np.float64]
    obs_types: tuple[str, ...]
    time: NDArray[np.float64]
    prn: NDArray[np.int64]
    values: NDArray[np.float64]

    def observable(self, name: str) -> NDArray[np.float64]:
        """One observation type as ``(E, S)`` (NaN where missing)."""
        if name not in self.obs_types:
            raise ValueError(f"name: {name!r} not among the observation types {self.obs_types}")
        return self.values[..., self.obs_types.index(name)]


def _float(text: str, path: str, line_no: int, what: str) -> float:
    s = text.strip()
    if not s:
        return 0.0
    try:
        return float(s.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise ValueError(f"{path}: line {line_no}: bad number {s!r} for {what}") from None


def _year4(yy: int) -> int:
    return yy + (1900 if yy >= 80 else 2000) if yy < 100 else yy


def _read_lines(path: str) -> list[str]:
    with open(path, encoding="ascii", errors="replace") as fh:
        return [ln.rstrip("\n\r") for ln in fh]


def _header_end(lines: list[str], path: str, kind: str) -> int:
    if not lines or "RINEX VERSION / TYPE" not in lines[0]:
        raise ValueError(f"{path}: line 1: not a RINEX file (no 'RINEX VERSION / TYPE')")
    version = _float(lines[0][:9], path, 1, "RINEX version")
    if not 2.0 <= version < 3.0:
        raise ValueError(f"{path}: line 1: RINEX version {version} is not 2.x")
    if lines[0][20:21] != kind:
        raise ValueError(f"{path}: line 1: file type {lines[0][20:21]!r} is not {kind!r}")
    for i, ln in enumerate(lines):
        if "END OF HEADER" in ln[60:]:
            return i + 1
    raise ValueError(f"{path}: line {len(lines)}: no 'END OF HEADER'")


_NAV_ORBIT_FIELDS = (
    ("iode", "crs", "delta_n", "m0"),
    ("cuc", "e", "cus", "sqrt_a"),
    ("toe_sow", "cic", "omega0", "cis"),
    ("i0", "crc", "omega", "omega_dot"),
    ("idot", "_l2codes", "week", "_l2p"),
    ("sv_accuracy", "health", "tgd", "iodc"),
    ("_ttm", "_fit", "_spare1", "_spare2"),
)


def read_rinex_nav(path: str | os.PathLike[str]) -> NavigationData:
    """Read a RINEX 2 GPS navigation message file.

    Each record is a PRN/epoch/clock line (I2, 5I3, F5.1, 3D19.12: PRN, toc, a_f0, a_f1, a_f2)
    followed by seven "broadcast orbit" lines (3X, 4D19.12) in the order of RINEX 2.10 Table
    A4. The header's ``ION ALPHA`` / ``ION BETA`` lines give the Klobuchar coefficients.

    Args:
        path: File path.

    Returns:
        :class:`NavigationData`.

    Raises:
        ValueError: If the file is not a RINEX 2 GPS navigation file or a record is malformed;
            the message names the file and the line.
    """
    path = str(path)
    lines = _read_lines(path)
    start = _header_end(lines, path, "N")
    alpha = np.full(4, np.nan)
    beta = np.full(4, np.nan)
    for i, ln in enumerate(lines[:start]):
        label = ln[60:].strip()
        if label in ("ION ALPHA", "ION BETA"):
            vals = [_float(ln[2 + 12 * k : 14 + 12 * k], path, i + 1, label) for k in range(4)]
            (alpha if label == "ION ALPHA" else beta)[:] = vals
    records: list[dict[str, float]] = []
    i = start
    while i < len(lines):
        if not lines[i].strip():
            i += 1
            continue
        if i + 8 > len(lines):
            raise ValueError(f"{path}: line {i + 1}: truncated navigation record")
        head = lines[i]
        rec: dict[str, float] = {}
        try:
            prn = int(head[0:2])
            y, mo, d, h, mi = (int(head[2 + 3 * k : 5 + 3 * k]) for k in range(5))
        except ValueError:
            raise ValueError(f"{path}: line {i + 1}: bad PRN/epoch field {head[:22]!r}") from None
        sec = _float(head[17:22], path, i + 1, "toc seconds")
        if not 1 <= prn <= 32:
            raise ValueError(f"{path}: line {i + 1}: PRN {prn} outside 1..32")
        try:
            rec["toc"] = gps_seconds_from_datetime(_year4(y), mo, d, h, mi, sec)
        except ValueError as exc:
            raise ValueError(f"{path}: line {i + 1}: bad epoch ({exc})") from None
        rec["prn"] = prn
        for k, name in enumerate(("af0", "af1", "af2")):
            rec[name] = _float(head[22 + 19 * k : 41 + 19 * k], path, i + 1, name)
        for j, names in enumerate(_NAV_ORBIT_FIELDS):
            ln = lines[i + 1 + j]
            if len(ln) < 22:
                raise ValueError(f"{path}: line {i + 2 + j}: short broadcast-orbit line")
            for k, name in enumerate(names):
                rec[name] = _float(ln[3 + 19 * k : 22 + 19 * k], path, i + 2 + j, name)
        for name in ("sqrt_a", "e"):
            if not np.isfinite(rec[name]) or rec[name] < 0:
                raise ValueError(f"{path}: line {i + 3}: invalid {name} {rec[name]}")
        if rec["sqrt_a"] < 1000.0:
            raise ValueError(f"{path}: line {i + 3}: implausible sqrt_a {rec['sqrt_a']}")
        rec["toe"] = rec["week"] * 604800.0 + rec["toe_sow"]
        records.append(rec)
        i += 8
    if not records:
        raise ValueError(f"{path}: line {len(lines)}: no navigation records")
    cols = {f: np.array([r[f] for r in records]) for f in BroadcastEphemeris._fields}
    cols["prn"] = cols["prn"].astype(np.int64)
    cols["week"] = cols["week"].astype(np.int64)
    return NavigationData(BroadcastEphemeris(**cols), alpha, beta)


def _parse_epoch(ln: str, path: str, line_no: int) -> tuple[float, int, int]:
    try:
        flag = int(ln[26:29])
        nsat = int(ln[29:32]) if ln[29:32].strip() else 0
    except ValueError:
        raise ValueError(f"{path}: line {line_no}: bad epoch line {ln[:32]!r}") from None
    if not 0 <= flag <= 6:
        raise ValueError(f"{path}: line {line_no}: epoch flag {flag} is not one of 0-6 (RINEX 2 Table A2)")
    if flag > 1 and not ln[:26].strip():  # event record without a time
        return np.nan, flag, nsat
    try:
        y, mo, d, h, mi = (int(ln[1 + 3 * k : 3 + 3 * k]) for k in range(5))
        sec = float(ln[15:26])
        t = gps_seconds_from_datetime(_year4(y), mo, d, h, mi, sec)
    except ValueError:
        raise ValueError(f"{path}: line {line_no}: bad epoch line {ln[:32]!r}") from None
    return t, flag, nsat


def read_rinex_obs(path: str | os.PathLike[str]) -> ObservationData:
    """Read a RINEX 2 observation file (GPS satellites; other systems are skipped).

    Epoch lines: `` yy mm dd hh mm ss.sssssss  flag nsat`` then up to 12 satellite ids
    (``G05``; a blank system letter means GPS), continued on following lines from column 33.
    Each satellite has ceil(n_types / 5) lines of 16-column fields (F14.3, LLI, SSI). Event
    records are skipped (RINEX 2.11 Table A2): flags 2-5 are followed by ``nsat`` special
    records; flag 6 (cycle slips) by a satellite list and records in the observation format.

    Args:
        path: File path.

    Returns:
        :class:`ObservationData` with GPS satellites only.

    Raises:
        ValueError: If the file is not a RINEX 2 observation file or is malformed; the message
            names the file and the line.
    """
    path = str(path)
    lines = _read_lines(path)
    start = _header_end(lines, path, "O")
    approx = None
    types: list[str] = []
    n_types = 0
    for i, ln in enumerate(lines[:start]):
        label = ln[60:].strip()
        if label == "APPROX POSITION XYZ":
            approx = np.array([_float(ln[14 * k : 14 * k + 14], path, i + 1, label) for k in range(3)])
        elif label == "# / TYPES OF OBSERV":
            if not types:
                try:
                    n_types = int(ln[:6])
                except ValueError:
                    raise ValueError(f"{path}: line {i + 1}: bad number of types") from None
            types += ln[6:60].split()
    if approx is None:
        raise ValueError(f"{path}: line {start}: header lacks 'APPROX POSITION XYZ'")
    if n_types == 0 or len(types) != n_types:
        raise ValueError(f"{path}: line {start}: '# / TYPES OF OBSERV' lists {len(types)} of {n_types} types")
    lines_per_sat = (n_types + 4) // 5
    times: list[float] = []
    sats: list[list[int]] = []
    vals: list[list[list[float]]] = []
    i = start
    while i < len(lines):
        ln = lines[i]
        if not ln.strip():
            i += 1
            continue
        t, flag, nsat = _parse_epoch(ln, path, i + 1)
        if 2 <= flag <= 5:  # event record: nsat special lines follow
            i += 1 + nsat
            continue
        ids = ln[32:68]
        n_id_lines = (nsat + 11) // 12
        for k in range(1, n_id_lines):
            if i + k >= len(lines):
                raise ValueError(f"{path}: line {i + k + 1}: truncated satellite list")
            ids += lines[i + k][32:68]
        i += n_id_lines
        prns: list[int] = []
        rows: list[list[float]] = []
        for s in range(nsat):
            sid = ids[3 * s : 3 * s + 3]
            system = sid[0] if sid[0] != " " else "G"
            try:
                prn = int(sid[1:3])
            except ValueError:
                raise ValueError(f"{path}: line {i - n_id_lines + 1}: bad satellite id {sid!r}") from None
            row: list[float] = []
            for k in range(lines_per_sat):
                if i >= len(lines):
                    raise ValueError(f"{path}: line {i + 1}: truncated observation record")
                obs_ln = lines[i].ljust(80)
                for f in range(min(5, n_types - 5 * k)):
                    field = obs_ln[16 * f : 16 * f + 14]
                    row.append(_float(field, path, i + 1, types[5 * k + f]) if field.strip() else np.nan)
                i += 1
            if system == "G":
                prns.append(prn)
                rows.append(row)
        if flag == 6:  # cycle-slip records: the observation format, slips instead of values
            continue
        times.append(t)
        sats.append(prns)
        vals.append(rows)
    if not times:
        raise ValueError(f"{path}: line {len(lines)}: no observation epochs")
    n_slots = max(len(p) for p in sats)
    prn_arr = np.zeros((len(times), n_slots), np.int64)
    val_arr = np.full((len(times), n_slots, n_types), np.nan)
    for e, (p, r) in enumerate(zip(sats, vals, strict=True)):
        prn_arr[e, : len(p)] = p
        if p:
            val_arr[e, : len(p)] = r
    return ObservationData(approx, tuple(types), np.array(times), prn_arr, val_arr)
