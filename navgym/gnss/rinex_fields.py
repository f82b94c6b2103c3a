"""Fixed-width field readers shared by the RINEX 2 navigation and observation readers.

The layout rules, the error shape and the physical ranges are those of :mod:`navgym.gnss.rinex`
(see its docstring); this module holds the field-level parts both readers use.
"""

from __future__ import annotations

import math
import re
from typing import NamedTuple


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
