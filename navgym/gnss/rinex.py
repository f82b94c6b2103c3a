"""RINEX 2.x readers: GPS navigation (broadcast ephemeris) and observation files.

Own small fixed-column readers (RINEX 2.10/2.11, Gurtner & Estey, "RINEX: The Receiver
Independent Exchange Format Version 2.11", tables A1-A4). Loops run over lines only; the
results are arrays. Fields the readers do not return (spares, L2 codes, transmission time, fit
interval, the receiver clock offset, fields defined as blank ``nX``) are not parsed, so nothing
in them can fail a read (RINEX 2.11 §6.4: readers skip fields defined to be blank).

**Strict fields.** Every field the readers return is checked for the layout of its Fortran
format, not merely scanned for a number, so that a line cut in the middle of a field or shifted
by a column is refused instead of read as a different number:

* ``Dw.d`` (navigation records ``D19.12``, ``ION ALPHA/BETA`` ``D12.4``): the number ends in the
  field's last column (right-justified, blanks before it only), has at most one digit before the
  point, exactly ``d`` digits after it and an exponent of two or three digits after a letter
  ``D``/``E`` (any case) and a sign, or of three digits after a bare sign when the letter has no
  room (``0.499063314480-269``, Fortran's ``Dw.d`` output for |exponent| > 99);
* ``F14.3`` (observations): right-justified, exactly three decimals; the loss-of-lock and
  signal-strength columns after it (``I1`` each) are blank or a digit;
* integers (``I2``, ``I3``, ``I2.2``) right-justified digits; the seconds ``F5.1`` / ``F11.7``
  with exactly one / seven decimals.

A blank field is refused unless the format lets it be unknown (RINEX 2.11 §5.3, "items that
are not known at the file creation time can be set to zero or blank"; §6.3, empty fields at the
end of a record may be missing): in the navigation records only a_f2, T_GD, IODC and the SV
accuracy (read as 0.0, "not known"); blank observations are missing (NaN). Every number must
be finite and lie in its physical range (the navigation fields: the range of their IS-GPS-200
Table 20-I/20-III bit field, see :data:`NAV_FIELD_RANGES`).

**Duplicate navigation records** (one PRN, the same ``toc`` or the same ``toe``): a copy equal
in every returned field is dropped (broadcast files merged from several receivers repeat
records); two that differ are refused, naming both lines, since
:func:`~navgym.gnss.ephemeris.select_ephemeris` would otherwise take one of them silently.

**Event records** (epoch flags 2-5, RINEX 2.11 §5.4 and Table A2): the ``nsat`` special records
that follow must be header records (a label in columns 61-80), must all be in the file, and the
line after them must be an epoch record again; an event record that changes the
``# / TYPES OF OBSERV`` is refused (the reader keeps one set of types).

Malformed input raises ``ValueError`` of one shape: ``"<file>: line <n>: <what is wrong>;
expected <what the format asks for>"`` (1-based line numbers).
"""

from __future__ import annotations

import math
import os
import re
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.gnss.gpstime import gps_seconds_from_datetime

__all__ = [
    "BroadcastEphemeris",
    "NAV_FIELD_RANGES",
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


def _plain(x: float) -> str:
    """A number as plain text for messages (``repr`` of a Python float, never a numpy repr)."""
    return repr(float(x))


#: A Fortran real as formatted output writes it: a mantissa, then an exponent that is either a
#: letter (E or D, any case) with an optional sign, or, when the exponent has three digits and
#: the letter has no room (``Dw.d`` with |exponent| > 99), a bare sign: ``0.499063314480-269``.
_FORTRAN_REAL = re.compile(r"([+-]?(?:\d+\.?\d*|\.\d+))(?:[EeDd]([+-]?\d+)|([+-]\d+))?")

_NUMBER_FORMS = "a number such as 12.5, -2.5D-03, .1E+01 or 0.5-269 (Fortran, exponent letter optional)"


def _fortran_real(text: str) -> float:
    """Parse one Fortran-formatted real; a blank field is 0.0 (RINEX: blank or zero if unknown).

    The value only: the field's layout is checked by :func:`_d_field` / :func:`_f_field`.

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
    """A number of a field whose layout is not checked (header records the readers tolerate)."""
    try:
        value = _fortran_real(text)
    except ValueError:
        raise _error(path, line_no, f"bad number {text.strip()!r} for {what}", _NUMBER_FORMS) from None
    if not math.isfinite(value):
        raise _error(path, line_no, f"{what} {text.strip()!r} is not finite", "a finite number")
    return value


def _d_layout(decimals: int) -> re.Pattern[str]:
    """The text of a ``Dw.d`` field without its leading blanks (module docstring)."""
    return re.compile(rf"[+-]?\d?\.\d{{{decimals}}}(?:[EeDd][+-]\d{{2,3}}|[+-]\d{{3}})")


_D_LAYOUT = {12: _d_layout(12), 4: _d_layout(4)}
_F_LAYOUT = {
    1: re.compile(r"\d*\.\d"),
    3: re.compile(r"[+-]?(?:0|[1-9]\d*)?\.\d{3}"),  # no leading zeros: Fortran writes none
    4: re.compile(r"[+-]?(?:0|[1-9]\d*)?\.\d{4}"),
    7: re.compile(r"\d*\.\d{7}"),
}


def _field_text(ln: str, start: int, width: int) -> str | None:
    """Columns ``start .. start + width`` of ``ln`` (0-based); None when the line ends before them.

    A line may end early (RINEX 2.11 §6.3: empty fields at the end of a record may be missing);
    a field the line ends *inside* keeps its short text, which the layout checks refuse.
    """
    if len(ln) <= start:
        return None
    return ln[start : start + width]


def _layout_problem(text: str, width: int, pattern: re.Pattern[str]) -> str | None:
    """Why ``text`` is not a right-justified field of ``width`` columns matching ``pattern``."""
    if len(text) < width:
        return f"the field is cut by the end of the line after {len(text)} of its {width} columns"
    body = text.lstrip(" ")
    if text.endswith(" "):
        return "the number does not end in the field's last column (shifted or cut)"
    if not pattern.fullmatch(body):
        return "the field's text does not have the layout of the format (shifted, cut or corrupted)"
    return None


def _d_field(
    ln: str,
    start: int,
    width: int,
    decimals: int,
    *,
    path: str,
    line_no: int,
    what: str,
    blank_ok: bool,
) -> float:
    """The value of a ``Dw.d`` field (module docstring); a blank allowed field is 0.0."""
    text = _field_text(ln, start, width)
    fmt = f"D{width}.{decimals} in columns {start + 1}-{start + width}"
    if text is None or not text.strip():
        if blank_ok:
            return 0.0
        raise _error(
            path, line_no, f"{what} is blank", f"{fmt} (the format allows no blank here: the value is needed)"
        )
    problem = _layout_problem(text, width, _D_LAYOUT[decimals])
    if problem is not None:
        raise _error(
            path,
            line_no,
            f"{what} field {text!r}: {problem}",
            f"{fmt}, right-justified, such as {f'{-1.5:{width}.{decimals}E}'.replace('E', 'D')!r}",
        )
    value = _fortran_real(text)
    if not math.isfinite(value):
        raise _error(path, line_no, f"{what} {text.strip()!r} is not finite", "a finite number")
    return value


def _f_field(ln: str, start: int, width: int, decimals: int, *, path: str, line_no: int, what: str) -> float:
    """The value of a required ``Fw.d`` field: right-justified, exactly ``d`` decimals, finite."""
    text = _field_text(ln, start, width) or ""
    fmt = f"F{width}.{decimals} in columns {start + 1}-{start + width}, right-justified"
    if not text.strip():
        raise _error(path, line_no, f"{what} is blank", fmt)
    problem = _layout_problem(text, width, _F_LAYOUT[decimals])
    if problem is not None:
        raise _error(path, line_no, f"{what} field {text!r}: {problem}", fmt)
    value = float(text)
    if not math.isfinite(value):
        raise _error(path, line_no, f"{what} {text.strip()!r} is not finite", "a finite number")
    return value


def _int_field(ln: str, start: int, width: int, *, path: str, line_no: int, what: str, fmt: str) -> int:
    """An ``Iw`` field: right-justified digits (a leading minus allowed)."""
    text = ln[start : start + width]
    if len(text) < width or not re.fullmatch(r" *-?\d+", text):
        raise _error(
            path, line_no, f"bad {what} field {text!r}", f"{fmt} in columns {start + 1}-{start + width}"
        )
    return int(text)


class _FieldRange(NamedTuple):
    """Physical range of a navigation field: ``lo <= x <= hi`` (``hi_open``: ``x < hi``)."""

    lo: float
    hi: float
    integer: bool = False
    hi_open: bool = False
    why: str = ""


_PI = math.pi
#: Ranges of the navigation fields the reader returns (IS-GPS-200 Table 20-I/20-III: a field of
#: ``n`` bits with scale ``s`` holds at most ``2^(n-1) s`` in magnitude, twos complement; angles
#: in semicircles times pi): a value outside could not have been broadcast. ``sqrt_a`` is held to
#: a GNSS orbit (MEO to geostationary, semi-major axis 20,250-43,560 km) within that field.
NAV_FIELD_RANGES: dict[str, _FieldRange] = {
    "af0": _FieldRange(-(2.0**-10), 2.0**-10, why="22 bits x 2^-31 s"),
    "af1": _FieldRange(-(2.0**-28), 2.0**-28, why="16 bits x 2^-43 s/s"),
    "af2": _FieldRange(-(2.0**-48), 2.0**-48, why="8 bits x 2^-55 s/s^2"),
    "iode": _FieldRange(0, 255, integer=True, why="an 8-bit issue of data"),
    "crs": _FieldRange(-(2.0**10), 2.0**10, why="16 bits x 2^-5 m"),
    "delta_n": _FieldRange(-(2.0**-28) * _PI, 2.0**-28 * _PI, why="16 bits x 2^-43 semicircles/s"),
    "m0": _FieldRange(-_PI, _PI, why="32 bits x 2^-31 semicircles"),
    "cuc": _FieldRange(-(2.0**-14), 2.0**-14, why="16 bits x 2^-29 rad"),
    "e": _FieldRange(0.0, 0.5, hi_open=True, why="32 unsigned bits x 2^-33 (an ellipse: 0 <= e < 1)"),
    "cus": _FieldRange(-(2.0**-14), 2.0**-14, why="16 bits x 2^-29 rad"),
    "sqrt_a": _FieldRange(4500.0, 6600.0, why="a GNSS orbit, semi-major axis 20,250-43,560 km"),
    "toe_sow": _FieldRange(0.0, 604800.0, hi_open=True, why="seconds of the GPS week"),
    "cic": _FieldRange(-(2.0**-14), 2.0**-14, why="16 bits x 2^-29 rad"),
    "omega0": _FieldRange(-_PI, _PI, why="32 bits x 2^-31 semicircles"),
    "cis": _FieldRange(-(2.0**-14), 2.0**-14, why="16 bits x 2^-29 rad"),
    "i0": _FieldRange(0.0, _PI, why="an inclination, 32 bits x 2^-31 semicircles"),
    "crc": _FieldRange(-(2.0**10), 2.0**10, why="16 bits x 2^-5 m"),
    "omega": _FieldRange(-_PI, _PI, why="32 bits x 2^-31 semicircles"),
    "omega_dot": _FieldRange(-(2.0**-20) * _PI, 2.0**-20 * _PI, why="24 bits x 2^-43 semicircles/s"),
    "idot": _FieldRange(-(2.0**-30) * _PI, 2.0**-30 * _PI, why="14 bits x 2^-43 semicircles/s"),
    "week": _FieldRange(0, 9999, integer=True, why="a continuous GPS week (RINEX 2.10: no roll-over)"),
    "sv_accuracy": _FieldRange(0.0, 8192.0, why="URA in metres (0 if not known)"),
    "health": _FieldRange(0, 63, integer=True, why="the 6-bit health (RINEX 2.11 §6.7)"),
    "tgd": _FieldRange(-(2.0**-24), 2.0**-24, why="8 bits x 2^-31 s"),
    "iodc": _FieldRange(0, 1023, integer=True, why="a 10-bit issue of data"),
}

#: Returned navigation fields that may be blank ("not known", read as 0.0; RINEX 2.11 §5.3).
_NAV_BLANK_OK = frozenset({"af2", "tgd", "iodc", "sv_accuracy"})


def _check_range(value: float, name: str, path: str, line_no: int) -> None:
    r = NAV_FIELD_RANGES[name]
    slack = 1e-12 * max(abs(r.lo), abs(r.hi))  # the decimal text of a bound rounds either way
    inside = r.lo - slack <= value and (value < r.hi if r.hi_open else value <= r.hi + slack)
    if not inside or (r.integer and value != int(value)):
        kind = "an integer " if r.integer else ""
        hi = f"< {_plain(r.hi)}" if r.hi_open else f"<= {_plain(r.hi)}"
        raise _error(
            path,
            line_no,
            f"{name} {_plain(value)} is outside its physical range",
            f"{kind}{_plain(r.lo)} <= {name} {hi} ({r.why})",
        )


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
