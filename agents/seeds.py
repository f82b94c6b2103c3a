"""Disjoint seed ranges: training, tuning and evaluation never share an episode.

An episode is fully determined by its environment id, keyword arguments and reset seed, so
keeping the seed ranges apart keeps the three uses apart:

* training (SB3): seeds ``[TRAIN_START, TUNE_START)``;
* baseline tuning (grid searches): seeds ``[TUNE_START, EVAL_START)``;
* evaluation (held-out): seeds ``>= EVAL_START``.

:func:`check_seeds` raises when a seed list strays outside its range.
"""

from __future__ import annotations

from collections.abc import Iterable

TRAIN_START = 0
TUNE_START = 1_000_000
EVAL_START = 2_000_000_000

RANGES = {
    "train": (TRAIN_START, TUNE_START),
    "tune": (TUNE_START, EVAL_START),
    "eval": (EVAL_START, 2**63 - 1),
}


def seeds(kind: str, n: int, offset: int = 0) -> list[int]:
    """``n`` consecutive seeds of range ``kind`` (``"train" | "tune" | "eval"``) from ``offset``."""
    lo, hi = RANGES[kind]
    if n < 0 or offset < 0 or lo + offset + n > hi:
        raise ValueError(f"{n} {kind} seeds from offset {offset} leave the {kind} range [{lo}, {hi})")
    return list(range(lo + offset, lo + offset + n))


def check_seeds(kind: str, values: Iterable[int]) -> None:
    """Raise ``ValueError`` naming ``kind`` if a seed lies outside its range."""
    lo, hi = RANGES[kind]
    bad = [s for s in values if not lo <= int(s) < hi]
    if bad:
        raise ValueError(f"{kind} seeds must lie in [{lo}, {hi}); got {bad[:5]}")
