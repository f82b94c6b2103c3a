"""Validation of environment keyword arguments: one rule per kind, errors that name the argument.

Every platform reads its keyword arguments through these functions, so ``bools are bools``,
integers are integers (no ``1.5`` silently becoming 1), numbers are finite real numbers (no
strings) and ranges are checked where the argument is read, with a ``TypeError`` or
``ValueError`` that names the argument, the value and what is accepted.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import Any

import numpy as np


class UnknownKeywordError(TypeError, ValueError):
    """Unknown keyword arguments of an environment or a baseline.

    A ``TypeError`` as Python raises for unexpected keyword arguments, and a ``ValueError`` so
    that command lines report it as the user's input error in one line (``navgym.cli``).
    """


def _is_real(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )


def _range_text(low: float, high: float, low_open: bool, high_open: bool) -> str:
    lo = f"{'(' if low_open else '['}{low:g}"
    hi = f"{high:g}{')' if high_open else ']'}"
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
    if not _is_real(value):
        raise TypeError(f"{name} must be a real number; got {value!r} ({type(value).__name__})")
    v = float(value)
    ok = math.isfinite(v)
    ok = ok and (v > low if low_open else v >= low) and (v < high if high_open else v <= high)
    if not ok:
        raise ValueError(
            f"{name} must be a finite number in {_range_text(low, high, low_open, high_open)}; got {value!r}"
        )
    return v


def integer(name: str, value: Any, low: int = 1, high: int | None = None) -> int:
    """``value`` as an int in ``[low, high]`` (Python or NumPy integers only, not bools or floats)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer; got {value!r} ({type(value).__name__})")
    v = int(value)
    if v < low or (high is not None and v > high):
        bound = f"[{low}, {high}]" if high is not None else f">= {low}"
        raise ValueError(f"{name} must be an integer {bound}; got {value!r}")
    return v


def flag(name: str, value: Any) -> bool:
    """``value`` as a bool (``True``/``False`` only: ``"no"``, 2 or NaN are errors)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False; got {value!r} ({type(value).__name__})")
    return bool(value)


def choice(name: str, value: Any, options: Collection[str]) -> str:
    """``value`` when it is one of ``options``."""
    if not isinstance(value, str) or value not in options:
        raise ValueError(f"{name} must be one of {sorted(options)}; got {value!r}")
    return value


def interval(
    name: str, value: Any, low: float = -math.inf, high: float = math.inf, *, low_open: bool = False
) -> tuple[float, float]:
    """``value`` as a pair ``(lo, hi)`` of finite floats with ``low <= lo <= hi <= high``."""
    if isinstance(value, (str, bytes)) or np.ndim(value) != 1 or len(value) != 2:
        raise TypeError(f"{name} must be a pair (low, high); got {value!r}")
    lo = real(f"{name}[0]", value[0], low, high, low_open=low_open)
    hi = real(f"{name}[1]", value[1], low, high, low_open=low_open)
    if lo > hi:
        raise ValueError(f"{name} must be (low, high) with low <= high; got {value!r}")
    return lo, hi
