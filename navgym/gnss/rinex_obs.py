"""RINEX 2 observation files: GPS observations on fixed slots (RINEX 2.11 Tables A1-A2).

Strict fields and event records as :mod:`navgym.gnss.rinex` describes.
"""

from __future__ import annotations

import math
import os
import re
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.gnss.gpstime import gps_seconds_from_datetime
from navgym.gnss.rinex_fields import (
    _F_LAYOUT,
    _error,
    _f_field,
    _field_text,
    _header_end,
    _layout_problem,
    _plain,
    _read_lines,
    _year4,
)


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


_EPOCH_FORMAT = "1X,I2.2,4(1X,I2),F11.7,2X,I1,I3 (yy mm dd hh mm sec, flag, number of satellites)"

#: A satellite id of an epoch record (A1,I2): system letter (blank = GPS) and PRN.
_SAT_ID = re.compile(r"[A-Z ](?:[ 0-9][0-9]|[0-9] )")

#: A header record's label (columns 61-80) holds a word of three letters or more; an epoch
#: record has satellite ids and the clock offset there, an observation record numbers.
_HEADER_LABEL = re.compile(r"[A-Za-z]{3}")


def _is_header_record(ln: str) -> bool:
    """Whether ``ln`` is a header record (a label in columns 61-80, RINEX 2.11 Table A1)."""
    return bool(_HEADER_LABEL.search(ln[60:80]))


class _Epoch(NamedTuple):
    time: float  # GPS seconds; NaN for an event record without a time
    flag: int
    nsat: int
    label: str  # the time as ISO text, for messages


def _parse_epoch(ln: str, path: str, line_no: int) -> _Epoch:
    """An epoch record's first line (RINEX 2.11 Table A2), its fields checked for their layout."""
    flag_text, nsat_text = ln[28:29], ln[29:32]
    if not re.fullmatch(r"\d", flag_text) or not re.fullmatch(r" *\d*", nsat_text) or ln[26:28].strip():
        raise _error(path, line_no, f"bad epoch line {ln[:32]!r}", _EPOCH_FORMAT)
    flag = int(flag_text)
    nsat = int(nsat_text) if nsat_text.strip() else 0
    if not 0 <= flag <= 6:
        raise _error(
            path, line_no, f"epoch flag {flag} is not one of 0-6", "a flag 0-6 (RINEX 2.11 Table A2)"
        )
    if flag > 1 and not ln[:26].strip():  # event record without a time
        return _Epoch(np.nan, flag, nsat, "(no time)")
    ints = [ln[1:3], ln[4:6], ln[7:9], ln[10:12], ln[13:15]]
    sec_text = ln[15:26]
    if (
        not re.fullmatch(r"\d\d", ints[0])
        or not all(re.fullmatch(r" ?\d\d?", t) and not t.endswith(" ") for t in ints[1:])
        or ln[0] + ln[3] + ln[6] + ln[9] + ln[12] != "     "
        or len(sec_text) < 11
        or sec_text.endswith(" ")
        or not _F_LAYOUT[7].fullmatch(sec_text.lstrip(" "))
    ):
        raise _error(path, line_no, f"bad epoch line {ln[:32]!r}", _EPOCH_FORMAT)
    y, mo, d, h, mi = (int(t) for t in ints)
    sec = float(sec_text)
    if not 0.0 <= sec < 61.0:
        raise _error(path, line_no, f"epoch seconds {_plain(sec)} outside 0..61", _EPOCH_FORMAT)
    try:
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


def _event_records(lines: list[str], i: int, epoch: _Epoch, path: str) -> int:
    """Check the special records of the event record at line index ``i``; the lines it spans.

    RINEX 2.11 §5.4 / Table A2: flags 2-5 are followed by ``nsat`` special records, which are
    header records (flag 3: a new site occupation, at least MARKER NAME; flag 4: header
    information; flags 2 and 5 may have none). An external event (flag 5) has its time.

    Raises:
        ValueError: Fewer lines than announced before the end of the file, an announced line
            that is not a header record (the count is too large: it would swallow epochs), or
            a change of the observation types.
    """
    if epoch.flag == 5 and not np.isfinite(epoch.time):
        raise _error(path, i + 1, "an external event (flag 5) without its time", "the event's epoch time")
    for k in range(1, epoch.nsat + 1):
        j = i + k
        announced = (
            f"the event record of line {i + 1} (flag {epoch.flag}) announces {epoch.nsat} special records"
        )
        if j >= len(lines):
            raise _error(
                path,
                len(lines),
                f"{announced}, but the file ends after {k - 1}",
                "as many header records as the event record's count (columns 30-32)",
            )
        if not _is_header_record(lines[j]):
            raise _error(
                path,
                j + 1,
                f"{announced}, but this line (its record {k}) is not a header record",
                "header records (a label in columns 61-80) as many as the count in columns 30-32",
            )
        if lines[j][60:80].strip() == "# / TYPES OF OBSERV":
            raise _error(
                path,
                j + 1,
                f"the event record of line {i + 1} changes the observation types",
                "one '# / TYPES OF OBSERV' set per file (split the file at the event)",
            )
    return 1 + epoch.nsat


def read_rinex_obs(path: str | os.PathLike[str]) -> ObservationData:
    """Read a RINEX 2 observation file (GPS satellites; other systems are skipped).

    Epoch lines (``1X,I2.2,4(1X,I2),F11.7,2X,I1,I3``): `` yy mm dd hh mm ss.sssssss  flag
    nsat`` then up to 12 satellite ids (``G05``; a blank system letter means GPS), continued on
    following lines from column 33. Each satellite has ceil(n_types / 5) lines of 16-column
    fields (``F14.3`` then the loss-of-lock and signal-strength ``I1`` columns), checked for
    their layout (module docstring); a blank value is missing (NaN). Event records (RINEX 2.11
    §5.4, Table A2): flags 2-5 are followed by ``nsat`` special records, which must be header
    records (checked, module docstring); flag 6 (cycle slips) by a satellite list and records
    in the observation format (checked like observations, not returned).

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
    approx, types = _obs_header(lines, start, path)
    n_types = len(types)
    times: list[float] = []
    sats: list[list[int]] = []
    vals: list[list[list[float]]] = []
    previous: tuple[float, str, int] | None = None  # time, label and line of the last epoch
    last_event: tuple[int, int] | None = None  # line and count of the last event record
    i = start
    while i < len(lines):
        ln = lines[i]
        if not ln.strip():
            i += 1
            continue
        if _is_header_record(ln):
            raise _stray_header_record(ln, i, last_event, path)
        epoch = _parse_epoch(ln, path, i + 1)
        if 2 <= epoch.flag <= 5:  # event record: nsat header records follow
            i += _event_records(lines, i, epoch, path)
            last_event = (i - epoch.nsat, epoch.nsat)
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
        prns, rows, i = _satellite_rows(lines, i, ids, types, path)
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


def _obs_header(lines: list[str], start: int, path: str) -> tuple[NDArray[np.float64], list[str]]:
    """``APPROX POSITION XYZ`` (3F14.4) and the ``# / TYPES OF OBSERV`` (RINEX 2.11 Table A1)."""
    approx = None
    types: list[str] = []
    n_types = 0
    for i, ln in enumerate(lines[:start]):
        label = ln[60:].strip()
        if label == "APPROX POSITION XYZ":
            approx = np.array(
                [_f_field(ln, 14 * k, 14, 4, path=path, line_no=i + 1, what=label) for k in range(3)]
            )
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
    return approx, types


def _stray_header_record(ln: str, i: int, last_event: tuple[int, int] | None, path: str) -> ValueError:
    """The error of a header record found where an epoch record belongs (an event count too small)."""
    after = (
        f" (the event record of line {last_event[0]} announced {last_event[1]} special records)"
        if last_event is not None
        else ""
    )
    return _error(
        path,
        i + 1,
        f"a header record ({ln[60:80].strip()!r}) where an epoch record belongs{after}",
        "header records only after END OF HEADER inside an event record (flags 2-5) that counts them",
    )


def _satellite_rows(
    lines: list[str], i: int, ids: list[str], types: list[str], path: str
) -> tuple[list[int], list[list[float]], int]:
    """The GPS PRNs and observation rows of an epoch's satellites from line index ``i``; next index."""
    n_types = len(types)
    lines_per_sat = (n_types + 4) // 5
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
            n_here = min(5, n_types - 5 * k)
            row += _observation_line(lines[i], n_here, types[5 * k : 5 * k + n_here], path, i + 1)
            i += 1
        if sid[0] in " G":
            prns.append(int(sid[1:3].strip()))
            rows.append(row)
    return prns, rows, i


_OBS_FORMAT = (
    "5(F14.3,I1,I1): right-justified values with 3 decimals, LLI and signal strength blank or a digit"
)


def _observation_line(ln: str, n_here: int, names: list[str], path: str, line_no: int) -> list[float]:
    """The ``n_here`` values of one observation line (RINEX 2.11 Table A2); NaN where blank."""
    out: list[float] = []
    for f in range(n_here):
        text = _field_text(ln, 16 * f, 14)
        if text is None or not text.strip():
            out.append(np.nan)
        else:
            problem = _layout_problem(text, 14, _F_LAYOUT[3])
            if problem is not None:
                raise _error(path, line_no, f"{names[f]} field {text!r}: {problem}", _OBS_FORMAT)
            value = float(text)
            if not math.isfinite(value):
                raise _error(path, line_no, f"{names[f]} {text.strip()!r} is not finite", "a finite number")
            out.append(value)
        flags = ln[16 * f + 14 : 16 * f + 16]
        if not re.fullmatch(r"[ 0-9]{0,2}", flags):
            raise _error(
                path,
                line_no,
                f"{names[f]}: loss-of-lock / signal-strength columns {16 * f + 15}-{16 * f + 16}"
                f" hold {flags!r}",
                _OBS_FORMAT,
            )
    rest = ln[16 * n_here :]
    if rest.strip():
        raise _error(
            path,
            line_no,
            f"text after the last of the line's {n_here} observation fields: {rest.strip()!r}"
            " (a shifted field?)",
            _OBS_FORMAT,
        )
    return out
