"""Raw 64-bit words of NumPy's ``PCG64`` generators, compiled: the words ``random_raw`` gives.

A batched particle filter with one generator per filter draws its normals as raw words of
each generator (:func:`filters.core.resampling.standard_normal`, then the Box-Muller transform
of :mod:`filters.core.normal`). ``BitGenerator.random_raw`` produces one word per call of the
bit generator's function pointer, a chain of dependent 128-bit multiply-adds per generator:
a sizeable part of a ``GpsInsResample`` step, which draws two blocks of about 450 000 words at
B = 256 (``docs/performance.md``, "Figures behind the code").

:func:`raw_words` fills ``(G, h)`` words from ``G`` generators in one compiled loop that steps
four generators in lockstep (four independent multiply chains) and leaves every generator in
the state ``random_raw(h)`` leaves it in. ``PCG64`` (O'Neill 2014; NumPy's default) is the
128-bit LCG ``s <- a s + c (mod 2^128)`` with the XSL-RR output
``rotr64(hi(s) xor lo(s), hi(s) >> 58)`` of the new state, ``a`` NumPy's
``PCG_DEFAULT_MULTIPLIER_128`` and ``c`` the generator's increment. The kernel reads and
writes the generator's state where NumPy keeps it (``bit_generator.ctypes.state_address``
points at a ``pcg64_state`` whose first member points at ``{state, inc}``, two 128-bit
integers, low word first), under each generator's lock. A generator's words depend on it
alone, so the generators of a call are split over the threads of :mod:`filters.core.threads`
(the same words on any split); what the kernel needs of a list of generators (their state
addresses and locks, checked distinct ``PCG64``) is kept for the next call with the same
generators, which a task makes every step.

:func:`doubles` turns words into ``Generator.random``'s doubles (``(w >> 11) 2^-53``, NumPy's
``pcg64_next_double``), for :func:`filters.core.resampling.uniform`.

That layout is NumPy's, not a public API: the first call checks the kernel against
``random_raw`` (words, final state of test generators and their ``random`` doubles) and every later call uses
``random_raw`` if they differ, as it does for generators that are not ``PCG64`` and under
:func:`filters.core.compiled.numpy_only` (the NumPy twin; ``tests/filters/core/test_pcg64.py``
holds the two equal).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple, cast

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from filters.core.compiled import compiled_enabled
from filters.core.threads import over_rows

__all__ = ["compiled_applies", "doubles", "raw_words", "restore", "snapshot"]

#: NumPy's PCG_DEFAULT_MULTIPLIER_128 (pcg64.h), high and low 64-bit halves.
_MUL_HI = 2549297995355413924
_MUL_LO = 4865540595714422341


def _umulhi_ir(typingctx, a, b):  # pragma: no cover - compiled
    """The high 64 bits of the 128-bit product of two uint64 (one ``mul`` on x86-64)."""
    sig = types.uint64(types.uint64, types.uint64)

    def codegen(context, builder, signature, args):
        i128 = ir.IntType(128)
        p = builder.mul(builder.zext(args[0], i128), builder.zext(args[1], i128))
        return builder.trunc(builder.lshr(p, ir.Constant(i128, 64)), ir.IntType(64))

    return sig, codegen


def _load_u64_ir(typingctx, addr, i):  # pragma: no cover - compiled
    """The uint64 at ``addr + 8 i``."""
    sig = types.uint64(types.uint64, types.intp)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.IntType(64).as_pointer())
        return builder.load(builder.gep(ptr, [args[1]]))

    return sig, codegen


def _store_u64_ir(typingctx, addr, i, value):  # pragma: no cover - compiled
    """Store ``value`` at ``addr + 8 i``."""
    sig = types.void(types.uint64, types.intp, types.uint64)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.IntType(64).as_pointer())
        builder.store(args[2], builder.gep(ptr, [args[1]]))
        return context.get_dummy_value()

    return sig, codegen


# Compiled code calls an intrinsic without its typing context; Numba's stub types the call with
# the definition's parameters, typing context included, so the call sites see these signatures.
_umulhi = cast("Callable[[np.uint64, np.uint64], np.uint64]", intrinsic(_umulhi_ir))
_load_u64 = cast("Callable[[np.uint64, int], np.uint64]", intrinsic(_load_u64_ir))
_store_u64 = cast("Callable[[np.uint64, int, np.uint64], None]", intrinsic(_store_u64_ir))


@njit(cache=True, inline="always")
def _step(lo, hi, ilo, ihi):  # pragma: no cover - compiled
    """``a s + c (mod 2^128)`` on (low, high) halves, and the XSL-RR output of the new state."""
    mlo = np.uint64(_MUL_LO)
    mhi = np.uint64(_MUL_HI)
    plo = lo * mlo
    phi = _umulhi(lo, mlo) + hi * mlo + lo * mhi
    nlo = plo + ilo
    nhi = phi + ihi + (np.uint64(1) if nlo < plo else np.uint64(0))
    x = nhi ^ nlo
    rot = nhi >> np.uint64(58)
    word = (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))
    return nlo, nhi, word


@njit(cache=True, nogil=True)
def _words_kernel(addrs, out):  # pragma: no cover - compiled
    """``out[g] = random_raw(h)`` of the PCG64 state at ``addrs[g]`` (``pcg64_state *``), advanced."""
    G, h = out.shape
    ptrs = np.empty(G, dtype=np.uint64)
    for g in range(G):
        ptrs[g] = _load_u64(addrs[g], 0)  # pcg64_state.pcg_state -> {state, inc}
    g0 = 0
    while g0 + 4 <= G:  # four generators in lockstep: independent multiply chains
        p0, p1, p2, p3 = ptrs[g0], ptrs[g0 + 1], ptrs[g0 + 2], ptrs[g0 + 3]
        lo0, hi0, il0, ih0 = _load_u64(p0, 0), _load_u64(p0, 1), _load_u64(p0, 2), _load_u64(p0, 3)
        lo1, hi1, il1, ih1 = _load_u64(p1, 0), _load_u64(p1, 1), _load_u64(p1, 2), _load_u64(p1, 3)
        lo2, hi2, il2, ih2 = _load_u64(p2, 0), _load_u64(p2, 1), _load_u64(p2, 2), _load_u64(p2, 3)
        lo3, hi3, il3, ih3 = _load_u64(p3, 0), _load_u64(p3, 1), _load_u64(p3, 2), _load_u64(p3, 3)
        for k in range(h):
            lo0, hi0, w0 = _step(lo0, hi0, il0, ih0)
            lo1, hi1, w1 = _step(lo1, hi1, il1, ih1)
            lo2, hi2, w2 = _step(lo2, hi2, il2, ih2)
            lo3, hi3, w3 = _step(lo3, hi3, il3, ih3)
            out[g0, k] = w0
            out[g0 + 1, k] = w1
            out[g0 + 2, k] = w2
            out[g0 + 3, k] = w3
        _store_u64(p0, 0, lo0)
        _store_u64(p0, 1, hi0)
        _store_u64(p1, 0, lo1)
        _store_u64(p1, 1, hi1)
        _store_u64(p2, 0, lo2)
        _store_u64(p2, 1, hi2)
        _store_u64(p3, 0, lo3)
        _store_u64(p3, 1, hi3)
        g0 += 4
    for g in range(g0, G):
        p = ptrs[g]
        lo, hi, il, ih = _load_u64(p, 0), _load_u64(p, 1), _load_u64(p, 2), _load_u64(p, 3)
        for k in range(h):
            lo, hi, w = _step(lo, hi, il, ih)
            out[g, k] = w
        _store_u64(p, 0, lo)
        _store_u64(p, 1, hi)


class _Batch(NamedTuple):
    """What the compiled passes need of a list of distinct ``PCG64`` generators, found once."""

    gens: tuple  # held, so that no listed generator is freed and its id reused while cached
    addresses: np.ndarray  # each bit generator's ``pcg64_state`` address, (G,) uint64
    locks: list


#: Batches of generators seen lately, by the ids of their generators (a task passes the same
#: generators every step: looking them up again cost about 70 us per call at G = 256).
_BATCHES: dict[tuple[int, ...], _Batch] = {}
_MAX_BATCHES = 8


def _batch(gens: Sequence[np.random.Generator]) -> _Batch | None:
    """The :class:`_Batch` of ``gens`` if they are distinct ``PCG64`` generators, else None."""
    key = tuple(map(id, gens))
    hit = _BATCHES.get(key)
    if hit is not None:
        return hit
    bgs = _distinct_pcg64(gens)
    if bgs is None:
        return None
    addresses = np.fromiter((bg.ctypes.state_address for bg in bgs), dtype=np.uint64, count=len(bgs))
    batch = _Batch(tuple(gens), addresses, [bg.lock for bg in bgs])
    if len(_BATCHES) >= _MAX_BATCHES:
        _BATCHES.pop(next(iter(_BATCHES)), None)
    _BATCHES[key] = batch
    return batch


def _with_locks(locks: list, fn: Callable[[], object]) -> None:
    """``fn()`` holding each generator's lock, as NumPy takes it (the generators are distinct)."""
    taken = 0
    try:
        for lock in locks:
            lock.acquire()
            taken += 1
        fn()
    finally:
        for lock in locks[:taken]:
            lock.release()


def _numpy_words(gens: Sequence[np.random.Generator], h: int) -> np.ndarray:
    """The NumPy twin: one ``random_raw(h)`` per generator."""
    out = np.empty((len(gens), h), dtype=np.uint64)
    for b, g in enumerate(gens):
        out[b] = g.bit_generator.random_raw(h)
    return out


def _distinct_pcg64(gens: Sequence[np.random.Generator]) -> list | None:
    """The bit generators of ``gens`` if they are distinct ``PCG64`` ones, else None."""
    bgs = [g.bit_generator for g in gens]
    if not bgs or set(map(type, bgs)) != {np.random.PCG64} or len(set(map(id, bgs))) != len(bgs):
        return None
    return bgs


def _compiled_words(gens: Sequence[np.random.Generator], h: int) -> np.ndarray:
    batch = _batch(gens)
    if batch is None:
        raise ValueError("the generators must be distinct PCG64 ones")
    return _words_of(batch.addresses, batch.locks, h)


def _words_of(addresses: np.ndarray, locks: list, h: int) -> np.ndarray:
    """The words of the generators at ``addresses`` (distinct), the generators split over threads."""
    out = np.empty((len(addresses), h), dtype=np.uint64)

    def rows(start: int, stop: int) -> None:
        _words_kernel(addresses[start:stop], out[start:stop])

    _with_locks(locks, lambda: over_rows(len(addresses), h, rows))
    return out


def _increasing(rows: np.ndarray) -> bool:
    """Whether ``rows`` is strictly increasing (so its generators are distinct)."""
    return rows.size < 2 or bool((rows[1:] > rows[:-1]).all())


#: 64-bit words of a generator's state in a snapshot: ``{state, inc}`` (four) and the
#: ``pcg64_state`` word after its pointer (``has_uint32`` and the buffered ``uinteger``).
_SNAPSHOT_WORDS = 5


@njit(cache=True)
def _snapshot_kernel(addrs, out):  # pragma: no cover - compiled
    """``out[g]``: the state words of the ``pcg64_state`` at ``addrs[g]`` (:data:`_SNAPSHOT_WORDS`)."""
    for g in range(addrs.shape[0]):
        p = _load_u64(addrs[g], 0)
        for k in range(4):
            out[g, k] = _load_u64(p, k)
        out[g, 4] = _load_u64(addrs[g], 1)


@njit(cache=True)
def _restore_kernel(addrs, snap):  # pragma: no cover - compiled
    """The inverse of :func:`_snapshot_kernel`: write the words of ``snap[g]`` back."""
    for g in range(addrs.shape[0]):
        p = _load_u64(addrs[g], 0)
        for k in range(4):
            _store_u64(p, k, snap[g, k])
        _store_u64(addrs[g], 1, snap[g, 4])


_VERIFIED: list[bool] = []


def _kernel_matches_numpy() -> bool:
    """Whether the kernel reproduces ``random_raw`` here (words and final states); once per process."""
    if not _VERIFIED:
        try:
            seeds = [12345, 2**64 + 7, 0, 99, 123456789]
            a = [np.random.Generator(np.random.PCG64(s)) for s in seeds]
            b = [np.random.Generator(np.random.PCG64(s)) for s in seeds]
            ok = True
            for h in (1, 5, 1000):
                ok &= np.array_equal(_compiled_words(a, h), _numpy_words(b, h))
            ok &= all(x.bit_generator.state == y.bit_generator.state for x, y in zip(a, b, strict=True))
            # Generator.random of a PCG64 is (next64 >> 11) 2^-53 (NumPy's pcg64_next_double)
            ok &= np.array_equal(doubles(_compiled_words(a, 7)), np.stack([y.random(7) for y in b]))
        except Exception:  # any failure means: use random_raw
            ok = False
        _VERIFIED.append(bool(ok))
    return _VERIFIED[0]


def doubles(words: np.ndarray) -> np.ndarray:
    """``Generator.random``'s doubles in ``[0, 1)`` of PCG64 words: ``(w >> 11) 2^-53`` (exact)."""
    u = (words >> np.uint64(11)).astype(np.float64)
    u *= 2.0**-53
    return u


def compiled_applies(gens: Sequence[np.random.Generator]) -> bool:
    """Whether :func:`raw_words` runs the compiled loop for ``gens`` (distinct PCG64 generators)."""
    return compiled_enabled() and _batch(gens) is not None and _kernel_matches_numpy()


def raw_words(gens: Sequence[np.random.Generator], h: int, rows: np.ndarray | None = None) -> np.ndarray:
    """``(len(gens), h)`` raw words, row ``b`` equal to ``gens[b].bit_generator.random_raw(h)``.

    Each generator is advanced exactly as ``random_raw(h)`` advances it (a generator listed
    twice gives its two rows in order). Compiled for ``PCG64`` generators unless
    :func:`~filters.core.compiled.numpy_only` is active (module docstring).

    ``rows`` (integer indices into ``gens``): the words of ``gens[rows[0]], gens[rows[1]], ...``
    only, ``(len(rows), h)``; a task drawing for a varying subset of its filters passes its
    whole list of generators and the subset, so the list is looked up once, not once a step.
    """
    h = int(h)
    sel = None if rows is None else np.asarray(rows, dtype=np.intp).reshape(-1)
    if h > 0 and compiled_enabled() and len(gens):
        batch = _batch(gens)
        if batch is not None and _kernel_matches_numpy():
            if sel is None:
                return _words_of(batch.addresses, batch.locks, h)
            if _increasing(sel) and (sel.size == 0 or (sel[0] >= 0 and sel[-1] < len(gens))):
                return _words_of(batch.addresses[sel], [batch.locks[int(b)] for b in sel], h)
    chosen = list(gens) if sel is None else [gens[int(b)] for b in sel]
    return _numpy_words(chosen, h)


_SNAPSHOT_VERIFIED: list[bool] = []


def _snapshot_matches_numpy() -> bool:
    """Whether :func:`snapshot` and :func:`restore` round-trip ``bit_generator.state``; once per process."""
    if not _SNAPSHOT_VERIFIED:
        try:
            gens = [np.random.Generator(np.random.PCG64(s)) for s in (3, 2**70 + 1, 17)]
            gens[1].integers(0, 10, dtype=np.uint32)  # a buffered 32-bit half-word
            before = [g.bit_generator.state for g in gens]
            batch = cast(_Batch, _batch(gens))
            snap = np.empty((len(gens), _SNAPSHOT_WORDS), dtype=np.uint64)
            _with_locks(batch.locks, lambda: _snapshot_kernel(batch.addresses, snap))
            first = [g.random(3).tolist() + [int(g.integers(0, 2**32, dtype=np.uint32))] for g in gens]
            _with_locks(batch.locks, lambda: _restore_kernel(batch.addresses, snap))
            ok = [g.bit_generator.state for g in gens] == before
            ok &= [g.random(3).tolist() + [int(g.integers(0, 2**32, dtype=np.uint32))] for g in gens] == first
        except Exception:  # any failure means: record bit_generator.state
            ok = False
        _SNAPSHOT_VERIFIED.append(bool(ok))
    return _SNAPSHOT_VERIFIED[0]


def snapshot(gens: Sequence[np.random.Generator]) -> np.ndarray | None:
    """The states of distinct ``PCG64`` generators, ``(G, 5)`` words, in one compiled pass; else None.

    What ``[g.bit_generator.state for g in gens]`` records (about a microsecond per generator,
    a dict each), for :func:`restore`. None when the generators are not distinct ``PCG64``
    ones, under :func:`~filters.core.compiled.numpy_only`, or if the round trip does not
    reproduce ``bit_generator.state`` here (then the caller records the dicts).
    """
    if not compiled_enabled():
        return None
    batch = _batch(gens)
    if batch is None or not _snapshot_matches_numpy():
        return None
    out = np.empty((len(batch.addresses), _SNAPSHOT_WORDS), dtype=np.uint64)
    _with_locks(batch.locks, lambda: _snapshot_kernel(batch.addresses, out))
    return out


def restore(gens: Sequence[np.random.Generator], snap: np.ndarray) -> None:
    """Put ``gens`` back in the states :func:`snapshot` recorded in ``snap``."""
    batch = _batch(gens)
    if batch is None or np.shape(snap) != (len(batch.addresses), _SNAPSHOT_WORDS):
        raise ValueError(f"snap must be snapshot(gens) of {len(gens)} distinct PCG64 generators")
    words = np.ascontiguousarray(snap, dtype=np.uint64)
    _with_locks(batch.locks, lambda: _restore_kernel(batch.addresses, words))
