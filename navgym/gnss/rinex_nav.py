"""RINEX 2 GPS navigation files: broadcast ephemerides (RINEX 2.11 Table A4).

Strict fields, duplicate records and ranges as :mod:`navgym.gnss.rinex` describes.
"""

from __future__ import annotations

import os
import re
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.gnss.gpstime import gps_seconds_from_datetime
from navgym.gnss.rinex_fields import (
    _F_LAYOUT,
    _NAV_BLANK_OK,
    _check_range,
    _d_field,
    _error,
    _header_end,
    _int_field,
    _plain,
    _read_lines,
    _year4,
)


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


_NAV_ORBIT_FIELDS = (
    ("iode", "crs", "delta_n", "m0"),
    ("cuc", "e", "cus", "sqrt_a"),
    ("toe_sow", "cic", "omega0", "cis"),
    ("i0", "crc", "omega", "omega_dot"),
    ("idot", "_l2codes", "week", "_l2p"),
    ("sv_accuracy", "health", "tgd", "iodc"),
    ("_ttm", "_fit", "_spare1", "_spare2"),
)

_NAV_EPOCH_FORMAT = "I2,1X,I2.2,4(1X,I2),F5.1 (PRN, yy mm dd hh mm ss.s; RINEX 2.11 Table A4)"


def _nav_epoch(head: str, path: str, line_no: int) -> tuple[int, float]:
    """PRN and toc (GPS seconds) of a PRN/epoch/clock line (RINEX 2.11 Table A4)."""
    kw = {"path": path, "line_no": line_no, "fmt": _NAV_EPOCH_FORMAT}
    prn = _int_field(head, 0, 2, what="PRN", **kw)
    year_text = head[3:5]
    if not re.fullmatch(r"\d\d", year_text):
        raise _error(path, line_no, f"bad year field {head[2:5]!r}", "1X,I2.2 in columns 3-5 (two digits)")
    y = int(year_text)
    mo, d, h, mi = (
        _int_field(head, 5 + 3 * k, 3, what=name, **kw)
        for k, name in enumerate(("month", "day", "hour", "minute"))
    )
    sec_text = head[17:22]
    if len(sec_text) < 5 or sec_text.endswith(" ") or not _F_LAYOUT[1].fullmatch(sec_text.lstrip(" ")):
        raise _error(
            path, line_no, f"bad toc seconds field {sec_text!r}", "F5.1 in columns 18-22 (such as ' 0.0')"
        )
    sec = float(sec_text)
    if not 1 <= prn <= 32:
        raise _error(path, line_no, f"PRN {prn} outside 1..32", "a GPS PRN 1-32 in columns 1-2")
    if not 0.0 <= sec < 60.0:
        raise _error(path, line_no, f"toc seconds {_plain(sec)} outside 0..60", "0 <= seconds < 60")
    try:
        toc = gps_seconds_from_datetime(_year4(y), mo, d, h, mi, sec)
    except ValueError as exc:
        raise _error(path, line_no, f"bad epoch ({exc})", "a valid calendar date and time") from None
    return prn, toc


def read_rinex_nav(path: str | os.PathLike[str]) -> NavigationData:
    """Read a RINEX 2 GPS navigation message file (strict fields, module docstring).

    Each record is a PRN/epoch/clock line (``I2,1X,I2.2,4(1X,I2),F5.1,3D19.12``: PRN, toc,
    a_f0, a_f1, a_f2) followed by seven "broadcast orbit" lines (``3X,4D19.12``) in the order
    of RINEX 2.11 Table A4. The header's ``ION ALPHA`` / ``ION BETA`` lines (``2X,4D12.4``,
    Table A3) give the Klobuchar coefficients. Every returned field must have its format's
    layout, be finite and lie in :data:`NAV_FIELD_RANGES`; only a_f2, T_GD, IODC and the SV
    accuracy may be blank (0.0). Fields not returned (spares, L2 codes, transmission time, fit
    interval) are skipped unparsed. Records need not be in time order (broadcast files are
    not). A record repeated identically (same PRN and toc or toe, every returned field equal)
    is dropped; one that differs is refused naming both lines.

    Args:
        path: File path.

    Returns:
        :class:`NavigationData`.

    Raises:
        ValueError: If the file is not a RINEX 2 GPS navigation file, a record is malformed or
            two records of one satellite and time differ; the message names the file, the line
            and what was expected there.
    """
    path = str(path)
    lines = _read_lines(path)
    start = _header_end(lines, path, "N")
    alpha = np.full(4, np.nan)
    beta = np.full(4, np.nan)
    for i, ln in enumerate(lines[:start]):
        label = ln[60:].strip()
        if label in ("ION ALPHA", "ION BETA"):
            vals = [
                _d_field(ln, 2 + 12 * k, 12, 4, path=path, line_no=i + 1, what=f"{label} {k}", blank_ok=False)
                for k in range(4)
            ]
            (alpha if label == "ION ALPHA" else beta)[:] = vals
    records: list[dict[str, float]] = []
    first_lines: list[int] = []
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
        prn, rec["toc"] = _nav_epoch(head, path, i + 1)
        rec["prn"] = prn
        lead_digit: dict[str, tuple[bool, int, str]] = {}  # field -> digit before the point, line, text
        for j, names in enumerate((("af0", "af1", "af2"), *_NAV_ORBIT_FIELDS)):
            ln = lines[i + j]
            for k, name in enumerate(names):
                if name.startswith("_"):
                    continue
                first = (22 if j == 0 else 3) + 19 * k
                rec[name] = _d_field(
                    ln, first, 19, 12, path=path, line_no=i + 1 + j, what=name, blank_ok=name in _NAV_BLANK_OK
                )
                _check_range(rec[name], name, path, i + 1 + j)
                text = ln[first : first + 19]
                if text.strip():
                    lead_digit[name] = (text.lstrip(" +-")[:1].isdigit(), i + 1 + j, text)
        _check_one_style(lead_digit, path)
        rec["toe"] = rec["week"] * 604800.0 + rec["toe_sow"]
        records.append(rec)
        first_lines.append(i + 1)
        i += 8
    if not records:
        raise _error(path, len(lines), "no navigation records", "at least one record after the header")
    keep = _drop_identical_copies(records, first_lines, path)
    records = [records[k] for k in keep]
    cols = {f: np.array([r[f] for r in records]) for f in BroadcastEphemeris._fields}
    cols["prn"] = cols["prn"].astype(np.int64)
    cols["week"] = cols["week"].astype(np.int64)
    return NavigationData(BroadcastEphemeris(**cols), alpha, beta)


def _check_one_style(lead_digit: dict[str, tuple[bool, int, str]], path: str) -> None:
    """Refuse a record whose fields differ in having a digit before the decimal point.

    A writer formats every field of a record with one format: ``1PD19.12`` (``-5.218750000000D+01``),
    ``D19.12`` with the zero (``-0.521875000000D+02``) or without it (``-.521875000000D+02``, the
    example of RINEX 2.11 Table A8; zero there is `` .000000000000D+00``). A digit lost before
    the point of one field (``5.957618006510D-03`` -> `` .957618006510D-03``) leaves a number
    of the other layout: the odd field is named.
    """
    with_digit = [name for name, (d, _, _) in lead_digit.items() if d]
    without = [name for name, (d, _, _) in lead_digit.items() if not d]
    if with_digit and without:
        odd = without if len(without) <= len(with_digit) else with_digit
        name = odd[0]
        _, line_no, text = lead_digit[name]
        has = "has no" if name in without else "has a"
        raise _error(
            path,
            line_no,
            f"{name} field {text!r} {has} digit before the decimal point, unlike the record's other fields"
            f" (a character lost or replaced?); odd fields: {', '.join(odd)}",
            "every field of a record in the one layout of its writer",
        )


def _drop_identical_copies(records: list[dict[str, float]], first_lines: list[int], path: str) -> list[int]:
    """Indices of the records to keep: the first of identical copies (module docstring).

    Raises:
        ValueError: Two records of one PRN with the same toc or toe differ in a returned field.
    """
    seen: dict[tuple[int, str, float], int] = {}
    keep: list[int] = []
    for r, rec in enumerate(records):
        duplicate = False
        for key in ((int(rec["prn"]), "toc", rec["toc"]), (int(rec["prn"]), "toe", rec["toe"])):
            other = seen.get(key)
            if other is None:
                continue
            differ = [f for f in BroadcastEphemeris._fields if records[other][f] != rec[f]]
            if differ:
                f = differ[0]
                raise _error(
                    path,
                    first_lines[r],
                    f"the record of PRN {key[0]} here and the one of line {first_lines[other]} have the "
                    f"same {key[1]} but differ in {', '.join(differ)} ({f} {_plain(records[other][f])} "
                    f"there, {_plain(rec[f])} here)",
                    "one record per satellite and time (identical copies are dropped): remove the wrong one",
                )
            duplicate = True
        if duplicate:
            continue
        for key in ((int(rec["prn"]), "toc", rec["toc"]), (int(rec["prn"]), "toe", rec["toe"])):
            seen[key] = r
        keep.append(r)
    return keep
