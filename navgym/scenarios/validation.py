"""Argument checks shared by the simulation packages (ins, platforms, scenarios).

Every check raises :class:`ValueError` whose message starts with the argument's name, as the
design's "bad input" contract asks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = [
    "check_finite",
    "check_positive",
    "check_nonnegative",
    "check_probability",
    "check_range",
]


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as float if it is finite, else raise ``ValueError`` naming ``name``."""
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def check_positive(name: str, value: float) -> float:
    """Return ``value`` if it is finite and > 0, else raise ``ValueError`` naming ``name``."""
    v = check_finite(name, value)
    if v <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return v


def check_nonnegative(name: str, value: float, *, allow_inf: bool = False) -> float:
    """Return ``value`` if it is >= 0 (and finite unless ``allow_inf``), else raise."""
    v = float(value)
    if math.isnan(v) or (not allow_inf and math.isinf(v)) or v < 0.0:
        raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    return v


def check_probability(name: str, value: float) -> float:
    """Return ``value`` if it lies in [0, 1], else raise ``ValueError`` naming ``name``."""
    v = float(value)
    if not (0.0 <= v <= 1.0):
        raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")
    return v


def check_range(
    name: str,
    value: Sequence[float],
    *,
    lower: float = -math.inf,
    upper: float = math.inf,
    lower_open: bool = False,
) -> tuple[float, float]:
    """Validate a ``(low, high)`` pair with ``lower <= low <= high <= upper``.

    Args:
        name: Argument name used in the error message.
        value: The pair.
        lower: Smallest admissible value.
        upper: Largest admissible value.
        lower_open: If True, ``low`` must be strictly greater than ``lower``.

    Returns:
        The pair as a tuple of floats.

    Raises:
        ValueError: If ``value`` is not a finite ordered pair inside the bounds.

    """
    try:
        lo, hi = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a (low, high) pair, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise ValueError(f"{name} must be a finite pair with low <= high, got {value!r}")
    if lo < lower or (lower_open and lo <= lower) or hi > upper:
        raise ValueError(f"{name} must lie within [{lower}, {upper}], got {value!r}")
    return lo, hi
