"""RINEX 2.x readers: GPS navigation (broadcast ephemeris) and observation files.

Own small fixed-column readers (RINEX 2.10/2.11, Gurtner & Estey, "RINEX: The Receiver
Independent Exchange Format Version 2.11", tables A1-A4). Loops run over lines only; the
results are arrays. Numbers are read as Fortran writes them (:func:`_fortran_real`); fields the
readers do not return (spares, L2 codes, transmission time, fit interval, LLI/signal strength)
are not parsed, so nothing in them can fail a read.

Malformed input raises ``ValueError`` of one shape: ``"<file>: line <n>: <what is wrong>;
expected <what the format asks for>"``.
"""

from __future__ import annotations

import os
import re
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
        time: Epoch receive times (GPS seconds), strictly increasing, shape ``(E,)``.
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


def _error(path: str, line_no: int, problem: str, expected: str) -> ValueError:
    """The readers' one error shape: file, line number, what is wrong, what was expected."""
    return ValueError(f"{path}: line {line_no}: {problem}; expected {expected}")


#: A Fortran real as formatted output writes it: a mantissa, then an exponent that is either a
#: letter (E or D, any case) with an optional sign, or, when the exponent has three digits and
#: the letter has no room (``Dw.d`` with |exponent| > 99), a bare sign: ``0.499063314480-269``.
_FORTRAN_REAL = re.compile(r"([+-]?(?:\d+\.?\d*|\.\d+))(?:[EeDd]([+-]?\d+)|([+-]\d+))?")

_NUMBER_FORMS = "a number such as 12.5, -2.5D-03, .1E+01 or 0.5-269 (Fortran, exponent letter optional)"


def _fortran_real(text: str) -> float:
    """Parse one Fortran-formatted real; a blank field is 0.0 (RINEX: blank or zero if unknown).

    Raises:
        ValueError: If ``text`` is not a Fortran real.
    """
    s = text.strip()
    if not s:
        return 0.0
    m = _FORTRAN_REAL.fullmatch(s)
    if m is None:
        raise ValueError(f"not a Fortran real: {s!r}")
    mantissa, exp_letter, exp_bare = m.groups()
    exponent = exp_letter if exp_letter is not None else exp_bare
    return float(mantissa if exponent is None else f"{mantissa}e{exponent}")


def _float(text: str, path: str, line_no: int, what: str) -> float:
    try:
        return _fortran_real(text)
    except ValueError:
        raise _error(path, line_no, f"bad number {text.strip()!r} for {what}", _NUMBER_FORMS) from None


def _year4(yy: int) -> int:
    return yy + (1900 if yy >= 80 else 2000) if yy < 100 else yy


def _read_lines(path: str) -> list[str]:
    with open(path, encoding="ascii", errors="replace") as fh:
        return [ln.rstrip("\n\r") for ln in fh]


def _header_end(lines: list[str], path: str, kind: str) -> int:
    if not lines or "RINEX VERSION / TYPE" not in lines[0]:
        raise _error(path, 1, "not a RINEX file (no 'RINEX VERSION / TYPE')", "that header record as line 1")
    version = _float(lines[0][:9], path, 1, "RINEX version")
    if not 2.0 <= version < 3.0:
        raise _error(path, 1, f"RINEX version {version} is not 2.x", "a version 2.xx file (F9.2)")
    if lines[0][20:21] != kind:
        raise _error(path, 1, f"file type {lines[0][20:21]!r} is not {kind!r}", f"{kind!r} in column 21")
    for i, ln in enumerate(lines):
        if "END OF HEADER" in ln[60:]:
            return i + 1
    raise _error(path, len(lines), "no 'END OF HEADER'", "an 'END OF HEADER' record closing the header")


#: Broadcast-orbit lines 1-7 (RINEX 2.11 Table A4); names with a leading underscore are fields
#: the reader does not return (L2 codes, L2 P flag, transmission time, fit interval, spares):
#: they are not parsed, so whatever a writer put there cannot fail a read.
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
    followed by seven "broadcast orbit" lines (3X, 4D19.12) in the order of RINEX 2.11 Table
    A4. The header's ``ION ALPHA`` / ``ION BETA`` lines give the Klobuchar coefficients.
    Numbers may omit the exponent letter (``0.499063314480-269``, as Fortran writes three-digit
    exponents); fields not returned (spares, L2 codes, transmission time, fit interval) are
    skipped unparsed. Records need not be in time order (broadcast files are not).

    Args:
        path: File path.

    Returns:
        :class:`NavigationData`.

    Raises:
        ValueError: If the file is not a RINEX 2 GPS navigation file or a record is malformed;
            the message names the file, the line and what was expected there.
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
            raise _error(
                path,
                i + 1,
                f"truncated navigation record ({len(lines) - i} of 8 lines before the end of the file)",
                "a PRN/epoch/clock line and 7 broadcast-orbit lines",
            )
        head = lines[i]
        rec: dict[str, float] = {}
        try:
            prn = int(head[0:2])
            y, mo, d, h, mi = (int(head[2 + 3 * k : 5 + 3 * k]) for k in range(5))
        except ValueError:
            raise _error(
                path, i + 1, f"bad PRN/epoch field {head[:22]!r}", "I2,5I3 (PRN, yy mm dd hh mm)"
            ) from None
        sec = _float(head[17:22], path, i + 1, "toc seconds")
        if not 1 <= prn <= 32:
            raise _error(path, i + 1, f"PRN {prn} outside 1..32", "a GPS PRN 1-32 in columns 1-2")
        try:
            rec["toc"] = gps_seconds_from_datetime(_year4(y), mo, d, h, mi, sec)
        except ValueError as exc:
            raise _error(path, i + 1, f"bad epoch ({exc})", "a valid calendar date and time") from None
        rec["prn"] = prn
        for k, name in enumerate(("af0", "af1", "af2")):
            rec[name] = _float(head[22 + 19 * k : 41 + 19 * k], path, i + 1, name)
        for j, names in enumerate(_NAV_ORBIT_FIELDS):
            ln = lines[i + 1 + j]
            used = [(k, name) for k, name in enumerate(names) if not name.startswith("_")]
            if used and len(ln) < 22:
                raise _error(
                    path,
                    i + 2 + j,
                    f"short broadcast-orbit line ({len(ln)} columns)",
                    "3X,4D19.12 with at least the first field",
                )
            for k, name in used:
                rec[name] = _float(ln[3 + 19 * k : 22 + 19 * k], path, i + 2 + j, name)
        for name in ("sqrt_a", "e"):
            if not np.isfinite(rec[name]) or rec[name] < 0:
                raise _error(path, i + 3, f"invalid {name} {rec[name]}", "a finite non-negative value")
        if rec["sqrt_a"] < 1000.0:
            raise _error(
                path, i + 3, f"implausible sqrt_a {rec['sqrt_a']}", "sqrt(A) >= 1000 m^0.5 for a GPS orbit"
            )
        rec["toe"] = rec["week"] * 604800.0 + rec["toe_sow"]
        records.append(rec)
        i += 8
    if not records:
        raise _error(path, len(lines), "no navigation records", "at least one record after the header")
    cols = {f: np.array([r[f] for r in records]) for f in BroadcastEphemeris._fields}
    cols["prn"] = cols["prn"].astype(np.int64)
    cols["week"] = cols["week"].astype(np.int64)
    return NavigationData(BroadcastEphemeris(**cols), alpha, beta)


_EPOCH_FORMAT = "1X,I2.2,4(1X,I2),F11.7,2X,I1,I3 (yy mm dd hh mm sec, flag, number of satellites)"

#: A satellite id of an epoch record (A1,I2): system letter (blank = GPS) and PRN.
_SAT_ID = re.compile(r"[A-Z ](?:[ 0-9][0-9]|[0-9] )")


class _Epoch(NamedTuple):
    time: float  # GPS seconds; NaN for an event record without a time
    flag: int
    nsat: int
    label: str  # the time as ISO text, for messages


def _parse_epoch(ln: str, path: str, line_no: int) -> _Epoch:
    try:
        flag = int(ln[26:29])
        nsat = int(ln[29:32]) if ln[29:32].strip() else 0
    except ValueError:
        raise _error(path, line_no, f"bad epoch line {ln[:32]!r}", _EPOCH_FORMAT) from None
    if nsat < 0:
        raise _error(path, line_no, f"bad epoch line {ln[:32]!r}", _EPOCH_FORMAT)
    if not 0 <= flag <= 6:
        raise _error(
            path, line_no, f"epoch flag {flag} is not one of 0-6", "a flag 0-6 (RINEX 2.11 Table A2)"
        )
    if flag > 1 and not ln[:26].strip():  # event record without a time
        return _Epoch(np.nan, flag, nsat, "(no time)")
    try:
        y, mo, d, h, mi = (int(ln[1 + 3 * k : 3 + 3 * k]) for k in range(5))
        sec = _fortran_real(ln[15:26])
        t = gps_seconds_from_datetime(_year4(y), mo, d, h, mi, sec)
    except ValueError:
        raise _error(path, line_no, f"bad epoch line {ln[:32]!r}", _EPOCH_FORMAT) from None
    return _Epoch(t, flag, nsat, f"{_year4(y):04d}-{mo:02d}-{d:02d} {h:02d}:{mi:02d}:{sec:010.7f}")


def _satellite_key(sid: str) -> tuple[str, int]:
    """System letter and PRN of an A1,I2 satellite id; a blank letter is GPS (RINEX 2.11 §5.1)."""
    return (sid[0] if sid[0] != " " else "G", int(sid[1:3]))


def _satellite_list(lines: list[str], i: int, nsat: int, path: str) -> tuple[list[str], int]:
    """The ``nsat`` satellite ids of the epoch record at line index ``i``.

    RINEX 2.11 Table A2: 12(A1,I2) from column 33, more than 12 on continuation lines (32X,
    12(A1,I2)). Returns the ids and the number of lines the epoch record spans.
    """
    n_lines = max(1, (nsat + 11) // 12)
    ids: list[str] = []
    for k in range(n_lines):
        j = i + k
        if j >= len(lines) or (k > 0 and lines[j][:32].strip()):
            raise _error(
                path,
                j + 1,
                f"the epoch record of line {i + 1} announces {nsat} satellites but lists {len(ids)}",
                f"{n_lines - 1} continuation line(s): columns 1-32 blank, satellite ids from column 33",
            )
        field = lines[j][32:68]
        n_here = min(12, nsat - 12 * k)
        for s in range(n_here):
            sid = field[3 * s : 3 * s + 3]
            if not sid.strip():
                raise _error(
                    path,
                    j + 1,
                    f"the epoch record of line {i + 1} announces {nsat} satellites but lists {len(ids)}",
                    f"{nsat} satellite ids (A1,I2), 12 a line from column 33",
                )
            if not _SAT_ID.fullmatch(sid):
                raise _error(path, j + 1, f"bad satellite id {sid!r}", "A1,I2 such as 'G05' or ' 5'")
            same = [o for o in ids if _satellite_key(o) == _satellite_key(sid)]
            if same:
                raise _error(
                    path,
                    j + 1,
                    f"the epoch record of line {i + 1} lists satellite {sid!r} twice (also as {same[0]!r})",
                    "each satellite once per epoch",
                )
            ids.append(sid)
        if field[3 * n_here :].strip():
            raise _error(
                path,
                j + 1,
                f"the epoch record of line {i + 1} announces {nsat} satellites but lists more"
                f" ({field.strip()!r})",
                f"{nsat} satellite ids (A1,I2), 12 a line from column 33",
            )
    return ids, n_lines


def read_rinex_obs(path: str | os.PathLike[str]) -> ObservationData:
    """Read a RINEX 2 observation file (GPS satellites; other systems are skipped).

    Epoch lines: `` yy mm dd hh mm ss.sssssss  flag nsat`` then up to 12 satellite ids
    (``G05``; a blank system letter means GPS), continued on following lines from column 33.
    Each satellite has ceil(n_types / 5) lines of 16-column fields (F14.3, LLI, SSI). Event
    records are skipped (RINEX 2.11 Table A2): flags 2-5 are followed by ``nsat`` special
    records; flag 6 (cycle slips) by a satellite list and records in the observation format.

    Observation epochs (flags 0 and 1) must come in strictly increasing time: a file out of
    order or with a repeated time tag is rejected, not sorted. RINEX 2.11 states no rule
    beyond its header's TIME OF FIRST OBS / TIME OF LAST OBS ("time of first / last
    observation record", Table A1); RINEX 3.04 §6.5 spells it out: "Multiple epoch observation
    data records with identical time tags are not allowed (exception: Event records). Epochs
    have to appear ordered in time." Event records (flags 2-6) are exempt and not checked.
    Sorting would hide a damaged or wrongly concatenated file and would have to move the
    event records with their epochs. A satellite listed twice in one epoch (``G05`` and `` 5``
    are the same satellite) is rejected too: two rows for one satellite at one time tag.

    Args:
        path: File path.

    Returns:
        :class:`ObservationData` with GPS satellites only.

    Raises:
        ValueError: If the file is not a RINEX 2 observation file or is malformed; the message
            names the file, the line and what was expected there.
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
                    raise _error(
                        path, i + 1, f"bad number of observation types {ln[:6]!r}", "I6 in columns 1-6"
                    ) from None
            types += ln[6:60].split()
    if approx is None:
        raise _error(path, start, "header lacks 'APPROX POSITION XYZ'", "that record before END OF HEADER")
    if n_types == 0 or len(types) != n_types:
        raise _error(
            path,
            start,
            f"'# / TYPES OF OBSERV' lists {len(types)} of {n_types} types",
            "at least one type and as many as announced",
        )
    lines_per_sat = (n_types + 4) // 5
    times: list[float] = []
    sats: list[list[int]] = []
    vals: list[list[list[float]]] = []
    previous: tuple[float, str, int] | None = None  # time, label and line of the last epoch
    i = start
    while i < len(lines):
        ln = lines[i]
        if not ln.strip():
            i += 1
            continue
        epoch = _parse_epoch(ln, path, i + 1)
        if 2 <= epoch.flag <= 5:  # event record: nsat special lines follow
            i += 1 + epoch.nsat
            continue
        if epoch.flag <= 1:
            if previous is not None and not epoch.time > previous[0]:
                raise _error(
                    path,
                    i + 1,
                    f"epoch {epoch.label} is not after the previous epoch {previous[1]} (line {previous[2]})",
                    "observation epochs in increasing time order without repeated time tags",
                )
            previous = (epoch.time, epoch.label, i + 1)
        ids, n_id_lines = _satellite_list(lines, i, epoch.nsat, path)
        i += n_id_lines
        prns: list[int] = []
        rows: list[list[float]] = []
        for sid in ids:
            row: list[float] = []
            for k in range(lines_per_sat):
                if i >= len(lines):
                    raise _error(
                        path,
                        i + 1,
                        f"truncated observation record (satellite {sid!r} at the end of the file)",
                        f"{lines_per_sat} line(s) of observations per satellite",
                    )
                obs_ln = lines[i].ljust(80)
                for f in range(min(5, n_types - 5 * k)):
                    field = obs_ln[16 * f : 16 * f + 14]
                    row.append(_float(field, path, i + 1, types[5 * k + f]) if field.strip() else np.nan)
                i += 1
            if sid[0] in " G":
                prns.append(int(sid[1:3].strip()))
                rows.append(row)
        if epoch.flag == 6:  # cycle-slip records: the observation format, slips instead of values
            continue
        times.append(epoch.time)
        sats.append(prns)
        vals.append(rows)
    if not times:
        raise _error(path, len(lines), "no observation epochs", "at least one epoch after the header")
    n_slots = max(len(p) for p in sats)
    prn_arr = np.zeros((len(times), n_slots), np.int64)
    val_arr = np.full((len(times), n_slots, n_types), np.nan)
    for e, (p, r) in enumerate(zip(sats, vals, strict=True)):
        prn_arr[e, : len(p)] = p
        if p:
            val_arr[e, : len(p)] = r
    return ObservationData(approx, tuple(types), np.array(times), prn_arr, val_arr)
