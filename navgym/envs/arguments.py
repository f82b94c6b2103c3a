"""Validation of environment keyword arguments: one rule per kind, errors that name the argument.

Every platform reads its keyword arguments through these functions, so ``bools are bools``,
integers are integers (no ``1.5`` silently becoming 1), numbers are finite real numbers (no
strings), pairs are pairs and ranges are checked where the argument is read, with an error
that names the argument, the value and what is accepted: :class:`ArgumentTypeError` (both a
``TypeError`` and a ``ValueError``) for a value of the wrong type, ``ValueError`` for one out of
range. :class:`~navgym.scenarios.ScenarioDistribution` checks the scenario arguments with the
same rules.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass
from typing import Any

import numpy as np


class UnknownKeywordError(TypeError, ValueError):
    """Unknown keyword arguments of an environment or a baseline.

    A ``TypeError`` as Python raises for unexpected keyword arguments, and a ``ValueError`` so
    that command lines report it as the user's input error in one line (``navgym.cli``).
    """


class ArgumentTypeError(TypeError, ValueError):
    """A keyword argument of the wrong type (a string for a number, a float for an integer, ...).

    A ``TypeError`` as Python raises for arguments of the wrong type, and a ``ValueError`` so
    that command lines report it as the user's input error in one line (``navgym.cli``), like
    every other bad value.
    """


def _is_real(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )


def _as_float(name: str, value: Any, where: str) -> float:
    """``float(value)``, a ``ValueError`` naming ``name`` where it overflows (an int beyond float64)."""
    try:
        return float(value)
    except OverflowError:
        raise ValueError(
            f"{name} must be a finite number in {where}; got an integer too large for a float"
        ) from None


def _range_text(low: float, high: float, low_open: bool, high_open: bool) -> str:
    lo = f"{'(' if low_open or low == -math.inf else '['}{low:g}"
    hi = f"{high:g}{')' if high_open or high == math.inf else ']'}"
    return f"{lo}, {hi}"


def real(
    name: str,
    value: Any,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """``value`` as a finite float in ``[low, high]`` (open ends where asked)."""
    where = _range_text(low, high, low_open, high_open)
    if not _is_real(value):
        raise ArgumentTypeError(
            f"{name} must be a real number in {where}; got {value!r} ({type(value).__name__})"
        )
    v = _as_float(name, value, where)
    ok = math.isfinite(v)
    ok = ok and (v > low if low_open else v >= low) and (v < high if high_open else v <= high)
    if not ok:
        raise ValueError(f"{name} must be a finite number in {where}; got {value!r}")
    return v


def integer(name: str, value: Any, low: int = 1, high: int | None = None) -> int:
    """``value`` as an int in ``[low, high]`` (Python or NumPy integers only, not bools or floats)."""
    bound = f"in [{low}, {high}]" if high is not None else f">= {low}"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ArgumentTypeError(f"{name} must be an integer {bound}; got {value!r} ({type(value).__name__})")
    v = int(value)
    if v < low or (high is not None and v > high):
        raise ValueError(f"{name} must be an integer {bound}; got {value!r}")
    return v


def flag(name: str, value: Any) -> bool:
    """``value`` as a bool (``True``/``False`` only: ``"no"``, 2 or NaN are errors)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ArgumentTypeError(f"{name} must be True or False; got {value!r} ({type(value).__name__})")
    return bool(value)


def choice(name: str, value: Any, options: Collection[str]) -> str:
    """``value`` when it is one of ``options``."""
    if not isinstance(value, str) or value not in options:
        raise ValueError(f"{name} must be one of {sorted(options)}; got {value!r}")
    return value


def _sequence(value: Any) -> bool:
    """Whether ``value`` is a flat sequence of items (a tuple, a list or a 1-D array)."""
    if isinstance(value, np.ndarray):
        return value.ndim == 1
    return isinstance(value, (tuple, list))


def interval(
    name: str,
    value: Any,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> tuple[float, float]:
    """``value`` as a pair ``(lo, hi)`` of finite floats with ``low <= lo <= hi <= high``.

    A tuple, list or 1-D array of two real numbers (no strings, no bools); open ends where asked.
    """
    where = _range_text(low, high, low_open, high_open)
    if not (_sequence(value) and len(value) == 2 and all(_is_real(v) for v in value)):
        raise ArgumentTypeError(
            f"{name} must be a pair (low, high) of real numbers in {where}; got {value!r}"
        )
    lo, hi = _as_float(name, value[0], where), _as_float(name, value[1], where)
    ok = all(
        math.isfinite(v) and (v > low if low_open else v >= low) and (v < high if high_open else v <= high)
        for v in (lo, hi)
    )
    if not ok or lo > hi:
        raise ValueError(
            f"{name} must be a pair (low, high) of finite numbers in {where} with low <= high; got {value!r}"
        )
    return lo, hi


def count_range(name: str, value: Any, low: int = 0, high: int | None = None) -> tuple[int, int]:
    """``value`` as a pair ``(lo, hi)`` of integers with ``low <= lo <= hi <= high``.

    A tuple, list or 1-D array of two Python or NumPy integers (no floats, no bools).
    """
    where = f"in [{low}, {high}]" if high is not None else f">= {low}"
    if not (
        _sequence(value)
        and len(value) == 2
        and all(isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) for v in value)
    ):
        raise ArgumentTypeError(f"{name} must be a pair (low, high) of integers {where}; got {value!r}")
    lo, hi = int(value[0]), int(value[1])
    if lo < low or lo > hi or (high is not None and hi > high):
        raise ValueError(
            f"{name} must be a pair (low, high) of integers {where} with low <= high; got {value!r}"
        )
    return lo, hi


def reals(name: str, value: Any, low: float = -math.inf, high: float = math.inf) -> tuple[float, ...]:
    """``value`` as a tuple of finite floats in ``[low, high]`` (a tuple, list or 1-D array; may be empty)."""
    where = _range_text(low, high, False, False)
    if not (_sequence(value) and all(_is_real(v) for v in value)):
        raise ArgumentTypeError(f"{name} must be a tuple of real numbers in {where}; got {value!r}")
    out = tuple(_as_float(name, v, where) for v in value)
    if not all(math.isfinite(v) and low <= v <= high for v in out):
        raise ValueError(f"{name} must hold finite numbers in {where}; got {value!r}")
    return out


def instance(name: str, value: Any, kind: type) -> Any:
    """``value`` when it is a ``kind`` (a ``TypeError`` naming the argument otherwise)."""
    if not isinstance(value, kind):
        raise ArgumentTypeError(
            f"{name} must be a {kind.__module__}.{kind.__qualname__}; got {value!r} ({type(value).__name__})"
        )
    return value


def multipath_rows(scenarios: Any, rows: Collection[int], what: str) -> None:
    """Check that the multipath segments of ``scenarios`` can only fall on ``rows`` of the fix.

    ``scenarios`` is a :class:`~navgym.scenarios.ScenarioDistribution`; its ``multipath_rows``
    must lie within ``rows`` whenever multipath can occur (``multipath_probability > 0``);
    ``what`` names the rows in the error (e.g. ``"GNSS rows of Robot2d (GPS N/E, GLONASS N/E)"``).
    """
    chosen = scenarios.multipath_rows
    if scenarios.multipath_probability > 0.0 and not set(chosen) <= set(rows):
        raise ValueError(f"multipath_rows must hold {what}, within {tuple(rows)}; got {chosen!r}")


# ------------------------------------------------------------------------- declared arguments
# An argument declared once with its rule: the rule checks it (the functions above), documents
# it and tells the registry-wide fuzz (tests/navgym/envs/test_kwargs_fuzz.py) what to feed it.


@dataclass(frozen=True)
class Real:
    """A finite real number in ``[low, high]`` (open ends where given): :func:`real`."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False

    def check(self, name: str, value: Any) -> float:
        return real(name, value, self.low, self.high, low_open=self.low_open, high_open=self.high_open)


@dataclass(frozen=True)
class Integer:
    """An integer in ``[low, high]`` (``high`` None: no upper bound): :func:`integer`."""

    low: int = 1
    high: int | None = None

    def check(self, name: str, value: Any) -> int:
        return integer(name, value, self.low, self.high)


@dataclass(frozen=True)
class Flag:
    """``True`` or ``False``: :func:`flag`."""

    def check(self, name: str, value: Any) -> bool:
        return flag(name, value)


@dataclass(frozen=True)
class Choice:
    """One of the strings ``options``: :func:`choice`."""

    options: tuple[str, ...]

    def check(self, name: str, value: Any) -> str:
        return choice(name, value, self.options)


@dataclass(frozen=True)
class Interval:
    """A pair ``(lo, hi)`` of finite reals in ``[low, high]`` with ``lo <= hi``: :func:`interval`."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False

    def check(self, name: str, value: Any) -> tuple[float, float]:
        return interval(name, value, self.low, self.high, low_open=self.low_open, high_open=self.high_open)


@dataclass(frozen=True)
class Reals:
    """``size`` finite reals, each above ``low`` (strictly where ``low_open``), or None: :func:`reals`."""

    size: int
    low: float = -math.inf
    low_open: bool = False

    def check(self, name: str, value: Any) -> tuple[float, ...] | None:
        if value is None:
            return None
        out = reals(name, value, self.low)
        if len(out) != self.size or (self.low_open and min(out) <= self.low):
            bound = f"> {self.low:g}" if self.low_open else f">= {self.low:g}"
            raise ValueError(f"{name} must be None or {self.size} finite numbers {bound}; got {value!r}")
        return out


#: The kinds of a declared argument.
Rule = Real | Integer | Flag | Choice | Interval | Reals


@dataclass(frozen=True)
class Argument:
    """A keyword argument declared once: its name, default, rule and documentation.

    ``rule.check`` is what the code that reads the argument calls (through :meth:`check`);
    ``refused`` lists values the rule alone accepts but the reader refuses (a condition across
    the pair's ends, say), so that a fuzz built from the declaration feeds them too. ``opt_in``
    marks an argument whose default keeps the behaviour of the ids that predate it (the v2
    options: ``per_row``, ``clairvoyant``, ``memory_features``).
    """

    name: str
    default: Any
    rule: Rule
    doc: str
    refused: tuple[Any, ...] = ()
    opt_in: bool = False

    def check(self, value: Any) -> Any:
        """``value`` checked by the rule (a ``TypeError`` or ``ValueError`` naming the argument)."""
        return self.rule.check(self.name, value)
