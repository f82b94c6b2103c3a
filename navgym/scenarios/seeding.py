"""Per-episode random generators for batched simulation.

The design's determinism contract: episode ``i`` of a batch reset with seed ``s`` reproduces a
single episode reset with seed ``s + i``. Every batched sampler in ``navgym.ins``,
the truth generators and ``navgym.scenarios`` therefore takes one :class:`numpy.random.Generator`
per episode and draws each episode's numbers from its own generator only.

Draws happen once per episode (at reset) or once per chunk of steps (:class:`NormalStream`), so the
short Python loop over generators never runs inside a per-step hot path.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ["SeedsOrGenerators", "as_generators", "standard_normal_batch", "NormalStream"]

#: What batched samplers accept: an int seed (B = 1), a sequence of int seeds, or generators.
SeedsOrGenerators = int | np.random.Generator | Sequence[int | np.random.Generator]


def as_generators(seeds_or_rngs: SeedsOrGenerators) -> list[np.random.Generator]:
    """Turn seeds and/or generators into a list of per-episode generators.

    Generators are used as given (and advanced by the caller's draws); integers become
    ``np.random.default_rng(seed)``.

    Args:
        seeds_or_rngs: One seed or generator, or a non-empty sequence of them.

    Returns:
        One generator per episode.

    Raises:
        ValueError: If the sequence is empty or holds something else.

    """
    items = (
        [seeds_or_rngs]
        if isinstance(seeds_or_rngs, int | np.integer | np.random.Generator)
        else list(seeds_or_rngs)
    )
    if not items:
        raise ValueError("seeds_or_rngs must hold at least one seed or generator")
    out = []
    for item in items:
        if isinstance(item, np.random.Generator):
            out.append(item)
        elif isinstance(item, int | np.integer) and not isinstance(item, bool):
            out.append(np.random.default_rng(int(item)))
        else:
            raise ValueError(f"seeds_or_rngs items must be ints or Generators, got {item!r}")
    return out


def standard_normal_batch(rngs: Sequence[np.random.Generator], shape: tuple[int, ...]):
    """Stack ``rng.standard_normal(shape)`` over the episodes: shape ``(B,) + shape``."""
    out = np.empty((len(rngs),) + tuple(shape))
    for i, rng in enumerate(rngs):
        out[i] = rng.standard_normal(shape)
    return out


class NormalStream:
    """Chunked per-episode standard-normal draws for step-by-step simulation.

    Each call to :meth:`next` returns ``(B, width)`` numbers, the same numbers that drawing
    ``rng.standard_normal((n_steps, width))`` at once would give step after step (NumPy's
    ``Generator.standard_normal`` is chunk-size independent), so stepping an episode and
    precomputing it agree exactly. The loop over episodes runs once per ``chunk`` steps.

    Args:
        rngs: One generator per episode.
        width: Numbers per step and episode.
        chunk: Steps drawn at a time.

    """

    def __init__(self, rngs: Sequence[np.random.Generator], width: int, chunk: int = 256):
        if int(width) < 1:
            raise ValueError(f"width must be >= 1, got {width!r}")
        if int(chunk) < 1:
            raise ValueError(f"chunk must be >= 1, got {chunk!r}")
        self.rngs = list(rngs)
        self.width = int(width)
        self.chunk = int(chunk)
        self._buf = np.empty((len(self.rngs), 0, self.width))
        self._pos = 0

    def next(self) -> NDArray[np.float64]:
        """Return the next step's numbers, shape ``(B, width)``."""
        if self._pos >= self._buf.shape[1]:
            self._buf = standard_normal_batch(self.rngs, (self.chunk, self.width))
            self._pos = 0
        out = self._buf[:, self._pos]
        self._pos += 1
        return out
