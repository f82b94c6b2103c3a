"""``np.random.default_rng(seed)`` for many integer seeds at once, bit for bit.

Every episode draws from child generators seeded with integers it drew from its own generator
(:mod:`navgym.scenarios.seeding`): ten per GpsIns episode, so a reset of 4096 episodes builds
40,960 generators. ``np.random.default_rng(s)`` spends most of its time in ``SeedSequence``:
hashing the seed into a pool of four 32-bit words and hashing the pool into the PCG64 state
(O'Neill's ``seed_seq_fe`` design as NumPy implements it, ``bit_generator.pyx``). That integer
arithmetic is the same for every seed, so it runs here as array operations over all seeds
(:func:`pcg64_seed_states`); each generator is then built from its precomputed state (several
times faster; ``docs/performance.md``, "Figures behind the code"), and is the generator
``np.random.default_rng(s)`` returns, draw for draw
(``tests/navgym/scenarios/test_seed_sequence.py`` checks this on random seeds and edge cases).

NumPy's algorithm (``SeedSequence(entropy=s)`` for ``0 <= s < 2**64``, no spawn key, pool of 4)::

    entropy  = [s mod 2^32, s >> 32, 0, 0]        (an entropy of one word is padded with 0 alike)
    hashmix(v): v ^= c_A; c_A *= MULT_A; v *= c_A; v ^= v >> 16      (c_A from INIT_A, 32-bit)
    mix(x, y) = (MIX_L x - MIX_R y) ^ ((MIX_L x - MIX_R y) >> 16)
    pool_i = hashmix(entropy_i);  then for src, dst (src != dst): pool_dst = mix(pool_dst, hashmix(pool_src))
    state_j = hashmix_B(pool_{j mod 4}),  j = 0..7  (c_B from INIT_B, MULT_B)

and ``PCG64`` seeds itself with the eight words read as four little-endian 64-bit words.
Seeds outside ``[0, 2**64)`` go through ``np.random.default_rng`` (which rejects negative ones).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.random.bit_generator import ISpawnableSeedSequence
from numpy.typing import ArrayLike, NDArray

__all__ = ["default_rngs", "pcg64_seed_states"]

_MASK32 = 0xFFFFFFFF
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = 0xCA01F9DD, 0x4973F715
_XSHIFT = 16
_POOL_SIZE = 4
_STATE_WORDS = 4  # PCG64 asks for four 64-bit words
#: Below this many seeds the array hashing costs more than it saves (its fixed cost).
_MIN_BATCH = 64


class _Hasher:
    """NumPy's ``hashmix`` with its running multiplier, applied to uint32 arrays."""

    def __init__(self, init: int, mult: int) -> None:
        self.const, self.mult = init, mult

    def __call__(self, value: NDArray[np.uint32]) -> NDArray[np.uint32]:
        value = value ^ np.uint32(self.const)
        self.const = (self.const * self.mult) & _MASK32
        value = value * np.uint32(self.const)
        value ^= value >> np.uint32(_XSHIFT)
        return value


def _mix(x: NDArray[np.uint32], y: NDArray[np.uint32]) -> NDArray[np.uint32]:
    result = np.uint32(_MIX_MULT_L) * x - np.uint32(_MIX_MULT_R) * y
    result ^= result >> np.uint32(_XSHIFT)
    return result


def pcg64_seed_states(seeds: ArrayLike) -> NDArray[np.uint64]:
    """The four words ``SeedSequence(s).generate_state(4, np.uint64)`` for every seed, ``(k, 4)``.

    Args:
        seeds: integers in ``[0, 2**64)``, shape ``(k,)``.

    Returns:
        ``(k, 4)`` uint64: what ``np.random.PCG64(s)`` seeds itself with.
    """
    s = np.asarray(seeds, dtype=np.uint64).reshape(-1)
    hash_a = _Hasher(_INIT_A, _MULT_A)
    entropy = [(s & np.uint64(_MASK32)).astype(np.uint32), (s >> np.uint64(32)).astype(np.uint32)]
    zero = np.zeros(s.shape, dtype=np.uint32)
    pool = [hash_a(entropy[i] if i < len(entropy) else zero) for i in range(_POOL_SIZE)]
    for src in range(_POOL_SIZE):
        for dst in range(_POOL_SIZE):
            if src != dst:
                pool[dst] = _mix(pool[dst], hash_a(pool[src]))
    hash_b = _Hasher(_INIT_B, _MULT_B)
    words = np.stack([hash_b(pool[j % _POOL_SIZE]) for j in range(2 * _STATE_WORDS)], axis=-1)
    lo, hi = words[:, 0::2].astype(np.uint64), words[:, 1::2].astype(np.uint64)
    return lo | (hi << np.uint64(32))


class _IntegerSeed(ISpawnableSeedSequence):
    """The seed sequence of ``default_rng(entropy)`` with its PCG64 words already computed.

    ``generate_state`` hands PCG64 the precomputed words; anything else (``spawn``, pickling)
    goes through the real :class:`numpy.random.SeedSequence` of the same entropy.
    """

    __slots__ = ("entropy", "_state", "_full")

    def __init__(self, entropy: int, state: NDArray[np.uint64]) -> None:
        self.entropy = entropy
        self._state = state
        self._full: np.random.SeedSequence | None = None

    def _sequence(self) -> np.random.SeedSequence:
        if self._full is None:
            self._full = np.random.SeedSequence(self.entropy)
        return self._full

    def generate_state(self, n_words: int, dtype: type = np.uint32) -> NDArray:
        state, self._state = self._state, None  # handed over once, to the PCG64 being built
        if state is not None and n_words == _STATE_WORDS and np.dtype(dtype) == np.uint64:
            return state
        return self._sequence().generate_state(n_words, dtype)

    def spawn(self, n_children: int) -> list[np.random.SeedSequence]:
        return self._sequence().spawn(n_children)

    def __reduce__(self):  # pickles as the SeedSequence it stands for
        return self._sequence().__reduce__()


def default_rngs(seeds: Sequence[int] | ArrayLike) -> list[np.random.Generator]:
    """``[np.random.default_rng(int(s)) for s in seeds]``, the same generators, about 6x faster.

    Args:
        seeds: integers (any shape; flattened in C order).

    Returns:
        One ``Generator(PCG64)`` per seed, each drawing exactly what ``default_rng(s)`` draws.
    """
    arr = np.asarray(seeds)
    if arr.dtype.kind in "iu":  # the common case: a NumPy integer array, checked in one pass
        flat = arr.reshape(-1).tolist()
        in_range = arr.dtype.kind == "u" or not (arr < 0).any()
    else:
        flat = [int(v) for v in np.asarray(seeds, dtype=object).reshape(-1)]
        in_range = all(0 <= v < 2**64 for v in flat)
    if not in_range or len(flat) < _MIN_BATCH:
        return [np.random.default_rng(v) for v in flat]
    states = pcg64_seed_states(np.array(flat, dtype=np.uint64))
    pairs = zip(flat, states, strict=True)
    return [np.random.Generator(np.random.PCG64(_IntegerSeed(v, st))) for v, st in pairs]
