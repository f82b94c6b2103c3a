"""Per-episode random streams with block-buffered draws.

Contract (``docs/architecture.md``, "Environment contracts": determinism): every random number
of episode i comes from its own ``np.random.Generator``; a batch built from seeds ``s .. s+B-1``
reproduces B single-episode runs with those seeds, draw for draw.

Pattern chosen: one Generator per episode (``np.random.default_rng(s + i)``) and a *fixed
consumption per step* (the same numbers of normals and uniforms every step, whatever the
noise regime), drawn ahead in blocks of ``block`` steps. A refill loops over the B
generators once (``gen.standard_normal((block, n))``, ``gen.random((block, k))``), so the Python
loop over B runs once every ``block`` steps and each step is a slice of a ``(block, B, n)``
buffer. Because episode i's draws depend only on its own generator, ``block`` and the
per-step sizes, the batch equals the single runs exactly. ``python -m
navgym.gnss.bench`` prints the cost of a refill (microseconds per step and episode when
amortised).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ["episode_generators", "EpisodeStreams"]


def episode_generators(seed: int, batch: int) -> list[np.random.Generator]:
    """Generators for episodes ``seed, seed + 1, ..., seed + batch - 1``."""
    if int(batch) < 1:
        raise ValueError(f"batch must be >= 1, got {batch}")
    return [np.random.default_rng(int(seed) + i) for i in range(int(batch))]


class EpisodeStreams:
    """Block-buffered standard normals and uniforms from per-episode generators.

    Args:
        generators: One ``np.random.Generator`` per episode (B of them).
        n_normal: Standard normals per episode per step.
        n_uniform: Uniforms in [0, 1) per episode per step.
        block: Steps drawn ahead at each refill.

    Each call to :meth:`step` returns ``(normals (B, n_normal), uniforms (B, n_uniform))``.
    """

    def __init__(
        self,
        generators: Sequence[np.random.Generator],
        n_normal: int,
        n_uniform: int = 0,
        block: int = 64,
    ) -> None:
        if len(generators) < 1:
            raise ValueError("generators must hold at least one Generator")
        if n_normal < 0 or n_uniform < 0:
            raise ValueError(f"n_normal and n_uniform must be >= 0, got {n_normal}, {n_uniform}")
        if block < 1:
            raise ValueError(f"block must be >= 1, got {block}")
        self.generators = list(generators)
        self.n_normal = int(n_normal)
        self.n_uniform = int(n_uniform)
        self.block = int(block)
        self._k = self.block
        self._normal: NDArray[np.float64] = np.empty((0,))
        self._uniform: NDArray[np.float64] = np.empty((0,))

    @property
    def batch_size(self) -> int:
        """Number of episodes B."""
        return len(self.generators)

    def _refill(self) -> None:
        shape_n = (self.block, self.n_normal)
        shape_u = (self.block, self.n_uniform)
        normal = np.empty((self.block, self.batch_size, self.n_normal))
        uniform = np.empty((self.block, self.batch_size, self.n_uniform))
        for i, gen in enumerate(self.generators):
            normal[:, i] = gen.standard_normal(shape_n)
            uniform[:, i] = gen.random(shape_u)
        self._normal, self._uniform = normal, uniform
        self._k = 0

    def step(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Draws for one step: ``(normals (B, n_normal), uniforms (B, n_uniform))``."""
        if self._k >= self.block:
            self._refill()
        k = self._k
        self._k += 1
        return self._normal[k], self._uniform[k]
