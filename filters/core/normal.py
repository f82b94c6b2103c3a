"""Standard normal variates by the Box-Muller transform of raw 64-bit words, batched.

Box & Muller (1958): for independent ``u1, u2 ~ U(0, 1)``,

    ``r = sqrt(-2 ln u1)``,  ``theta = 2 pi u2``,  ``z1 = r cos(theta)``,  ``z2 = r sin(theta)``

are two independent ``N(0, 1)`` variates. Here both uniforms come from one 64-bit word of
``BitGenerator.random_raw``: its upper 40 bits give ``u1 = (k + 1/2) 2^-40`` and its lower 24
bits ``u2 = (j + 1/2) 2^-24``. ``-2 ln u1`` is computed in float64, its square root and
``cos``/``sin`` of the angle in float32 (NumPy's SIMD kernels), so every variate carries a
relative error of about 1e-7 (a float32 ulp or two), and ``|z| <= sqrt(-2 ln 2^-41) = 7.54``
(``P(|Z| > 7.54) = 4.7e-14`` under the exact normal: the only truncation).

Why not ``Generator.standard_normal``: NumPy's ziggurat produces one variate per call through
the bit generator's function pointer, most of the particle-filter budget of ``navgym bench
particles``. Drawing raw words and transforming the whole block with vectorized ``log``,
``sqrt``, ``cos`` and ``sin`` is about three times faster (``docs/performance.md``, "Figures
behind the code").

Layout: a block of ``2h`` variates from ``h`` words holds the ``cos`` branch in its first half
and the ``sin`` branch in its second half (contiguous writes); a block of odd size drops the
last ``sin`` variate. The values depend only on the words, so a generator advanced by
``random_raw`` elsewhere stays reproducible.

Compiled twin. :func:`box_muller` runs a Numba kernel (:func:`_box_muller_kernel`) unless the
switch of :mod:`filters.core.compiled` forces the NumPy code above, which stays the reference.
Numba has no vector ``log``, ``cos`` or ``sin`` (without Intel's SVML), so the kernel evaluates
them with polynomials that LLVM vectorises, in float64 from the same float32 angle and radius
inputs the NumPy code forms: ``ln u1`` from ``u1 = m 2^e`` (``m`` in ``[sqrt(1/2), sqrt(2))``)
as ``e ln 2 + 2 atanh((m - 1) / (m + 1))`` (series to ``s^17``, relative error below
``1e-13``), ``cos`` and ``sin`` after an exact quadrant reduction by ``pi / 2`` (Taylor series
to degree 12 on ``|x| <= pi / 4``, error below ``1e-12``). Each result is rounded to float32
where the NumPy code rounds, so the two agree to within 2 float32 ulps of each variate
(``tests/filters/core/test_normal.py``); NumPy's own SIMD ``cos``/``sin``/``log`` are not
correctly rounded either. The kernel costs about a third of the NumPy passes (``navgym bench
particles``, its normals row); the rows of a block are split over the threads of
:mod:`filters.core.threads` (nothing is shared between rows, so any split gives the same values).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from filters.core.compiled import compiled_enabled
from filters.core.threads import over_rows

__all__ = ["MAX_ABS", "box_muller", "standard_normal_block"]

_RADIUS_BITS = 40
_ANGLE_BITS = 64 - _RADIUS_BITS
#: Largest ``|z|`` the transform can return: ``sqrt(-2 ln(2^-41))``.
MAX_ABS = float(np.sqrt(-2.0 * np.log(0.5 * 2.0**-_RADIUS_BITS)))


def box_muller(words: np.ndarray, dtype: type | np.dtype = np.float64) -> np.ndarray:
    """Two standard normals per raw 64-bit word (Box & Muller 1958; module docstring).

    Args:
        words: ``(..., h)`` unsigned 64-bit integers (``BitGenerator.random_raw`` output).
        dtype: ``float64`` (default) or ``float32`` output; the values are the same up to the
            float32 rounding of the output (the radius is formed from ``-2 ln u1`` in float64).

    Returns:
        ``(..., 2h)``: ``r cos(theta)`` in ``[..., :h]``, ``r sin(theta)`` in ``[..., h:]``.
    """
    words = np.asarray(words)
    if words.dtype != np.uint64:
        raise ValueError(f"words must be uint64 (BitGenerator.random_raw); got {words.dtype}")
    dtype = np.dtype(dtype)
    if dtype not in (np.float64, np.float32):
        raise ValueError(f"dtype must be float64 or float32; got {dtype}")
    h = words.shape[-1]
    if compiled_enabled() and words.size:
        flat = np.ascontiguousarray(words).reshape(-1, h)
        out = np.empty((flat.shape[0], 2 * h), dtype=dtype)

        def rows(start: int, stop: int) -> None:
            _box_muller_kernel(flat[start:stop], out[start:stop])

        over_rows(flat.shape[0], h, rows)  # each word's pair depends on that word alone
        return out.reshape(*words.shape[:-1], 2 * h)
    u1 = (words >> np.uint64(_ANGLE_BITS)).astype(np.float64)
    u1 += 0.5
    u1 *= 2.0**-_RADIUS_BITS
    np.log(u1, out=u1)
    r = np.empty(words.shape, dtype=np.float32)
    np.multiply(u1, -2.0, out=r, casting="same_kind")  # -2 ln u1 in [0, 56.8]: float32 is ample
    np.sqrt(r, out=r)
    theta = (words & np.uint64((1 << _ANGLE_BITS) - 1)).astype(np.float32)
    theta += np.float32(0.5)
    theta *= np.float32(2.0 * np.pi * 2.0**-_ANGLE_BITS)
    out = np.empty((*words.shape[:-1], 2 * h), dtype=dtype)
    np.multiply(r, np.cos(theta), out=out[..., :h])
    np.multiply(r, np.sin(theta), out=out[..., h:])
    return out


_LN2_HI = 6.93147180369123816490e-01  # ln 2 = _LN2_HI + _LN2_LO (fdlibm's split)
_LN2_LO = 1.90821492927058770002e-10
_PIO2_HI = 1.5707963267948966  # pi / 2 = _PIO2_HI + _PIO2_LO
_PIO2_LO = 6.123233995736766e-17
_SQRT_HALF_BITS = 0x3FE6A09E667F3BCD  # the float64 bits of sqrt(1/2)
_CHUNK = 1024  # words per pass (the scratch stays in the L1 cache)


_FAST = {"nsz"}  # no reassociation and no contraction: every operation rounds as written


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _bm_u1(w, u1):  # pragma: no cover - compiled
    """``2^41 u1 = 2 k + 1`` (exact in float64) for the upper 40 bits ``k`` of each word."""
    for i in range(w.shape[0]):
        u1[i] = np.float64(np.int64(w[i] >> np.uint64(24)) * 2 + 1)


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _bm_split(bits, mbits, expo):  # pragma: no cover - compiled
    """``2^41 u1 = m 2^e`` with ``m`` in ``[sqrt(1/2), sqrt(2))`` from the float64 bits."""
    for i in range(bits.shape[0]):
        x = bits[i]
        m = (x & np.uint64(0x000FFFFFFFFFFFFF)) | np.uint64(0x3FE0000000000000)  # [1/2, 1)
        e = np.int64(x >> np.uint64(52)) - 1022
        low = m < np.uint64(_SQRT_HALF_BITS)
        mbits[i] = m + (np.uint64(0x0010000000000000) if low else np.uint64(0))
        expo[i] = np.float64(e - (1 if low else 0) - 41)


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _bm_radius(mant, expo, r):  # pragma: no cover - compiled
    """``r = sqrt(-2 ln u1)``, ``-2 ln u1`` rounded to float32 as the NumPy code rounds it."""
    for i in range(mant.shape[0]):
        f = mant[i] - 1.0
        s = f / (2.0 + f)
        z = s * s
        p = 1 / 11 + z * (1 / 13 + z * (1 / 15 + z / 17))
        p = z * (1 / 3 + z * (1 / 5 + z * (1 / 7 + z * (1 / 9 + z * p))))
        ln_u1 = expo[i] * _LN2_HI + ((2.0 * s + 2.0 * s * p) + expo[i] * _LN2_LO)
        r[i] = np.sqrt(np.float32(-2.0 * ln_u1))


@njit(cache=True, error_model="numpy", fastmath=_FAST)
def _bm_angle(w, r, cos_out, sin_out):  # pragma: no cover - compiled
    """``r cos(theta)``, ``r sin(theta)`` with ``theta`` formed in float32 as the NumPy code does."""
    for i in range(w.shape[0]):
        j = np.float32(np.int64(w[i] & np.uint64(0xFFFFFF)))
        t = np.float64((j + np.float32(0.5)) * np.float32(2.0 * np.pi * 2.0**-24))
        q = np.floor(t * (2.0 / np.pi) + 0.5)
        x = (t - q * _PIO2_HI) - q * _PIO2_LO
        x2 = x * x
        sn = -1 / 5040 + x2 * (1 / 362880 - x2 / 39916800)
        sn = x + x * x2 * (-1 / 6 + x2 * (1 / 120 + x2 * sn))
        cs = 1 / 40320 + x2 * (-1 / 3628800 + x2 / 479001600)
        cs = 1.0 + x2 * (-0.5 + x2 * (1 / 24 + x2 * (-1 / 720 + x2 * cs)))
        qi = np.int64(q)  # the quadrant: cos(x + qi pi/2), sin(x + qi pi/2)
        swap = (qi & 1) == 1
        sign_c = np.float64(1 - 2 * (((qi + 1) >> 1) & 1))
        sign_s = np.float64(1 - 2 * ((qi >> 1) & 1))
        ri = r[i]
        cos_out[i] = ri * np.float32(sign_c * (sn if swap else cs))
        sin_out[i] = ri * np.float32(sign_s * (cs if swap else sn))


@njit(cache=True, error_model="numpy", fastmath=_FAST, nogil=True)
def _box_muller_kernel(words, out):  # pragma: no cover - compiled
    """:func:`box_muller` of ``words (k, h)`` into ``out (k, 2h)`` (the module docstring).

    Four loops per chunk of words, each free of calls and branches so that it vectorises
    (:func:`_bm_u1`, :func:`_bm_split`, :func:`_bm_radius`, :func:`_bm_angle`).
    """
    k, h = words.shape
    u1 = np.empty(_CHUNK)
    mant = np.empty(_CHUNK)
    expo = np.empty(_CHUNK)
    r = np.empty(_CHUNK, dtype=np.float32)
    for b in range(k):
        for start in range(0, h, _CHUNK):
            stop = min(start + _CHUNK, h)
            c = stop - start
            w = words[b, start:stop]
            _bm_u1(w, u1[:c])
            _bm_split(u1[:c].view(np.uint64), mant[:c].view(np.uint64), expo[:c])
            _bm_radius(mant[:c], expo[:c], r[:c])
            _bm_angle(w, r[:c], out[b, start:stop], out[b, h + start : h + stop])


def standard_normal_block(
    generators: np.random.Generator | Sequence[np.random.Generator],
    shape: tuple[int, ...],
    dtype: type | np.dtype = np.float64,
) -> np.ndarray:
    """Standard normals ``(k, *shape)``: row ``b`` from ``generators[b]`` alone.

    One ``random_raw`` call per generator (the only per-row Python-level work); the transform
    runs once on the stacked words. A single Generator fills one row ``(1, *shape)``.

    Args:
        generators: one ``np.random.Generator`` or a sequence of them (one per row).
        shape: the shape of each row's variates.
        dtype: ``float64`` or ``float32`` (:func:`box_muller`).

    Returns:
        ``(len(generators), *shape)`` (``(1, *shape)`` for a single Generator).
    """
    gens = [generators] if isinstance(generators, np.random.Generator) else list(generators)
    if any(s < 0 for s in shape):
        raise ValueError(f"shape must be non-negative; got {shape}")
    size = int(np.prod(shape, dtype=np.int64))
    h = (size + 1) // 2
    words = np.empty((len(gens), h), dtype=np.uint64)
    for b, g in enumerate(gens):
        words[b] = g.bit_generator.random_raw(h)
    return box_muller(words, dtype)[:, :size].reshape(len(gens), *shape)
