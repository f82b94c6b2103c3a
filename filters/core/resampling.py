"""Resampling schemes for batched particle filters, vectorized over ``(B, N)``.

Every scheme maps normalized weights ``w (B, N)`` and uniforms in ``(0, 1]`` to ancestor indices
``a (B, N)``: particle ``j`` of filter ``b`` after resampling is particle ``a[b, j]`` before it.
The selection rule is the inverse-CDF rule of Touil & Ghadi 2012, eq. 17: a uniform ``u`` picks the index
``M`` with ``sum_{i<M} w_i < u <= sum_{i<=M} w_i``, so a zero-weight particle is never picked.

Schemes (registered by name in :data:`RESAMPLERS`; Douc, Cappe & Moulines 2005 compare them):

* ``multinomial``: ``N`` i.i.d. uniforms ``u_j`` (Touil & Ghadi 2012, eq. 17), ancestors in draw order;
* ``stratified``: ``u_j = (j + U_j) / N`` with ``N`` i.i.d. ``U_j`` (Kitagawa 1996);
* ``systematic``: ``u_j = (j + U) / N`` with one ``U`` per filter (Carpenter, Clifford &
  Fearnhead 1999);
* ``residual``: ``floor(N w_i)`` deterministic copies, the ``R = N - sum floor(N w_i)`` others
  drawn multinomially from the residual weights ``(N w_i - floor(N w_i)) / R`` (Liu & Chen 1998).

All four are unbiased: the expected number of copies of particle ``i`` is ``N w_i``.
Stratified, systematic and residual return ancestors in nondecreasing order.

Vectorization. Stratified and systematic counts have closed forms: the number of points
``u_j <= c`` below a CDF value ``c`` is ``clip(floor(N c - U) + 1, 0, N)`` (systematic) and
``k + [k < N and U_k <= N c - k]`` with ``k = floor(N c)`` (stratified). Over the cumulative
weights these give each particle's bound ``l_i`` (points ``l_{i-1} <= j < l_i`` are its
offspring), and the ancestor of point ``j`` is ``#{i : l_i <= j}``: one ``np.bincount`` of the
bounds and a running sum (residual resampling forms its bounds from its counts). The
multinomial and residual searches run as one ``np.searchsorted`` on the flattened cumulative
weights with row offsets ``2 b``, followed by an exact per-element check of the inequality of
eq. 17 (the offsets cost a few ulps of resolution, which the check repairs).

Randomness and determinism. ``rng`` is either one ``np.random.Generator`` or a sequence of
``B`` of them (one per filter):

* one Generator: each random quantity is drawn as one block ``(B_sel, ...)`` in row-major order
  for the ``B_sel`` filters that draw, so filter ``b`` receives the ``b``-th row of the block.
  Results are reproducible for a given seed and batch, but depend on ``B`` and on which filters
  draw: filter ``b`` in a batch does not reproduce a single-filter run.
* a sequence of ``B`` Generators: filter ``b`` draws only from ``rng[b]`` (one generator call per
  drawing filter, the only per-filter Python-level operation; the arithmetic stays batched), so
  ``B`` filters advanced together equal ``B`` separate runs with ``rng[b]`` each, step for step.
  A single-filter run with a plain Generator ``g`` equals one with ``[g]``.

Filters whose ``decision`` is False draw nothing, keep ``a[b] = (0, ..., N-1)``, and leave
their generator untouched, so "decision False" is indistinguishable from "no call".
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from itertools import repeat
from typing import NamedTuple

import numpy as np

from filters.core.normal import box_muller, standard_normal_block
from filters.core.pcg64 import compiled_applies, doubles, raw_words

__all__ = [
    "RESAMPLERS",
    "Resampler",
    "Rng",
    "check_decision",
    "check_log_weights",
    "check_rng",
    "draw",
    "exp_weights",
    "multinomial_ancestors",
    "normalized_weights",
    "residual_ancestors",
    "resample",
    "standard_normal",
    "stratified_ancestors",
    "systematic_ancestors",
    "uniform",
]

#: One Generator for the whole batch, or one per filter (see the module docstring).
Rng = np.random.Generator | Sequence[np.random.Generator]


# --------------------------------------------------------------------------------------------
# randomness
# --------------------------------------------------------------------------------------------
def check_rng(rng: object, B: int, name: str = "rng") -> np.random.Generator | list[np.random.Generator]:
    """Validate ``rng``: one ``np.random.Generator`` or a sequence of ``B`` of them."""
    if isinstance(rng, np.random.Generator):
        return rng
    # all(map(isinstance, ...)): a third of a generator expression's cost at B = 256, and this
    # check runs several times per particle-filter step
    if isinstance(rng, (list, tuple)) and all(map(isinstance, rng, repeat(np.random.Generator))):
        if len(rng) != B:
            raise ValueError(f"{name} must hold one Generator per filter ({B}); got {len(rng)}")
        return list(rng)
    raise ValueError(
        f"{name} must be a numpy.random.Generator or a sequence of {B} of them; got {type(rng).__name__}"
    )


def draw(
    rng: Rng,
    B: int,
    sampler: Callable[[np.random.Generator, int], np.ndarray],
    rows: np.ndarray | None = None,
) -> np.ndarray:
    """Draw one random block for the filters in ``rows`` (all ``B`` when None).

    ``sampler(generator, k)`` must return an array whose first axis has length ``k``. With one
    Generator it is called once with ``k = len(rows)``; with a sequence it is called once per
    drawing filter ``b`` with ``rng[b]`` and ``k = 1`` and the rows are stacked, so filter
    ``b``'s values depend only on ``rng[b]``.

    Returns:
        The stacked block, first axis ``len(rows)`` (or ``B``).
    """
    gens = check_rng(rng, B)
    idx = np.arange(B) if rows is None else np.asarray(rows)
    if isinstance(gens, np.random.Generator):
        return sampler(gens, int(idx.size))
    if idx.size == 0:
        return sampler(np.random.default_rng(0), 0)
    return np.concatenate([sampler(gens[int(b)], 1) for b in idx], axis=0)


def uniform(rng: Rng, B: int, shape: tuple[int, ...], rows: np.ndarray | None = None) -> np.ndarray:
    """Uniforms on ``(0, 1]`` (Touil & Ghadi 2012, eq. 17's convention), shape ``(len(rows), *shape)``.

    ``1 - Generator.random``; for a sequence of PCG64 generators from their raw words in one
    compiled call (:func:`filters.core.pcg64.raw_words` and :func:`~filters.core.pcg64.doubles`,
    the same doubles) instead of one ``random`` call per drawing filter.
    """

    def sampler(g: np.random.Generator, k: int) -> np.ndarray:
        u = g.random((k, *shape))
        np.subtract(1.0, u, out=u)
        return u

    gens = check_rng(rng, B)
    if not isinstance(gens, np.random.Generator):
        idx = np.arange(B) if rows is None else np.asarray(rows)
        size = 1
        for s in shape:
            size *= int(s)
        if size > 0 and idx.size and compiled_applies(gens):  # g.random's doubles from the same words
            u = doubles(raw_words(gens, size, None if rows is None else idx))
            np.subtract(1.0, u, out=u)
            return u.reshape(int(idx.size), *shape)
    return draw(rng, B, sampler, rows)


def standard_normal(
    rng: Rng,
    B: int,
    shape: tuple[int, ...],
    rows: np.ndarray | None = None,
    dtype: type | np.dtype = np.float64,
) -> np.ndarray:
    """Standard normal variates, shape ``(len(rows), *shape)`` (all ``B`` rows by default).

    Box-Muller from raw 64-bit words (:mod:`filters.core.normal`, about 3x faster than
    ``Generator.standard_normal``), with the batching semantics of :func:`draw`: one Generator
    draws the whole ``(len(rows), *shape)`` block; a sequence gives row ``b`` from ``rng[b]``
    only, the words of ``rng[b].bit_generator.random_raw`` (:func:`filters.core.pcg64.raw_words`:
    one compiled loop over the drawing filters' PCG64 generators) and one batched transform.
    ``dtype``: float64 or float32 (the same variates, rounded).
    """
    gens = check_rng(rng, B)
    idx = np.arange(B) if rows is None else np.asarray(rows)
    if isinstance(gens, np.random.Generator):
        return standard_normal_block(gens, (int(idx.size), *shape), dtype)[0]
    return _normal_rows(gens, None if rows is None else idx, shape, dtype)


def _normal_rows(
    gens: Sequence[np.random.Generator],
    rows: np.ndarray | None,
    shape: tuple[int, ...],
    dtype: type | np.dtype,
) -> np.ndarray:
    """``standard_normal_block`` of ``gens[rows]`` (all when None), words by ``raw_words``.

    The same words as one ``random_raw`` per generator (compiled for ``PCG64`` generators, four
    at a time), so the same variates and generator states.
    """
    if any(s < 0 for s in shape):
        raise ValueError(f"shape must be non-negative; got {shape}")
    size = 1
    for s in shape:
        size *= int(s)
    words = raw_words(gens, (size + 1) // 2, rows)
    return box_muller(words, dtype)[:, :size].reshape(words.shape[0], *shape)


# --------------------------------------------------------------------------------------------
# validation and weights
# --------------------------------------------------------------------------------------------
def check_log_weights(log_w: object, name: str = "log_w") -> np.ndarray:
    """Check log-weights ``(B, N)``: ``N >= 1``, no NaN or ``+inf``, a finite entry per row.

    ``-inf`` entries (zero weight) are allowed. The weights need not be normalized.
    """
    try:
        lw = np.asarray(log_w, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array: {exc}") from None
    if lw.ndim != 2:
        raise ValueError(f"{name} must have shape (B, N); got {lw.shape}")
    if lw.shape[1] < 1:
        raise ValueError(f"{name} must have N >= 1 particles; got shape {lw.shape}")
    # one pass on the valid path: the row maximum is finite iff the row has no NaN, no +inf
    # and at least one finite entry
    if np.isfinite(lw.max(axis=1)).all():
        return lw
    if np.isnan(lw).any() or (lw == np.inf).any():
        raise ValueError(f"{name} has NaN or +inf entries (weights must be finite)")
    raise ValueError(f"{name} has a row whose weights are all zero (all -inf)")


def check_decision(decision: object, B: int, name: str = "decision") -> np.ndarray:
    """A per-filter boolean ``(B,)`` (a scalar broadcasts); None means every filter."""
    if decision is None:
        return np.ones(B, dtype=bool)
    d = np.asarray(decision)
    if d.ndim == 0:
        d = np.full(B, bool(d))
    if d.shape != (B,):
        raise ValueError(f"{name} must be a scalar or have shape ({B},); got {d.shape}")
    if d.dtype != bool:
        if not np.isin(d, (0, 1)).all():
            raise ValueError(f"{name} must be boolean (or 0/1)")
        d = d.astype(bool)
    return d


#: Log-weight ratios below this give linear weights of exactly 0 (:func:`exp_weights`).
EXP_FLUSH = -700.0


def exp_weights(a: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``exp(a)`` for log-weights shifted to a maximum of 0, with ``exp(a) := 0`` for ``a < -700``.

    A flushed weight is below ``e^-700 = 1e-304`` of the largest one, far under one ulp of any
    sum that contains the largest, so normalized weights, their sums and the ESS are unchanged;
    ``-inf`` (zero weight) maps to 0 and NaN stays NaN. Why: NumPy's SIMD ``exp`` leaves its
    fast path for arguments <= -708 (denormal or underflowing results, and ``-inf``), which
    makes it an order of magnitude or two slower on the log-weights of a degenerate particle
    cloud (``docs/performance.md``, "Figures behind the code").

    Args:
        a: shifted log-weights (any shape).
        out: optional output array (may be ``a`` itself).

    Returns:
        ``exp(a)`` with the flush applied.
    """
    if a.size and a.min() >= EXP_FLUSH:  # the common case: one reduction, then the fast exp
        return np.exp(a, out=out)
    keep = a >= EXP_FLUSH  # False below the flush (and for NaN, which the product keeps NaN)
    out = np.maximum(a, EXP_FLUSH, out=out)
    np.exp(out, out=out)
    # times the 0/1 mask: several times cheaper than the masked assignment out[~keep] = 0, and
    # the same values
    np.multiply(out, keep, out=out)
    return out


def normalized_weights(log_w: np.ndarray) -> np.ndarray:
    """Weights ``w_i = exp(l_i - max l) / sum_j exp(l_j - max l)`` per row, shape ``(B, N)``."""
    w = log_w - log_w.max(axis=1, keepdims=True)
    exp_weights(w, out=w)
    w /= w.sum(axis=1, keepdims=True)
    return w


def _cdf(w: np.ndarray) -> np.ndarray:
    """Row-wise cumulative weights with last entry exactly 1 (monotone after the division)."""
    c = np.cumsum(w, axis=1)
    c /= c[:, -1:]
    return c


def _ancestors_from_bounds(le: np.ndarray) -> np.ndarray:
    """Sorted ancestors from cumulative offspring counts ``le (B, N)`` (rows end at N).

    Particle ``i`` takes the points ``le_{i-1} <= k < le_i``, so point ``k`` goes to the first
    ``i`` with ``le_i > k``: ``a_k = #{i : le_i <= k}`` (``le`` is nondecreasing). One
    ``bincount`` of the bounds and a running sum, instead of ``np.repeat`` of the counts (about
    twice as fast, the same ancestors). ``le`` is modified.
    """
    B, N = le.shape
    if le.size and (le[:, -1] != N).any():
        raise AssertionError("offspring counts do not sum to N")  # pragma: no cover
    le += (np.arange(B) * (N + 1))[:, None]  # each row's bounds in its own N + 1 bins
    hist = np.bincount(le.ravel(), minlength=B * (N + 1)).reshape(B, N + 1)
    return np.cumsum(hist[:, :N], axis=1)


def _batched_searchsorted(c: np.ndarray, u: np.ndarray) -> np.ndarray:
    """First index ``i`` with ``c[b, i] >= u[b, j]`` (eq. 17), exact, for ``u`` in ``(0, 1]``.

    One flattened ``np.searchsorted`` with row offsets ``2 b`` (rounding is monotone, so the
    flattened array stays sorted), then an exact correction with the unshifted values.
    """
    B, N = c.shape
    off = 2.0 * np.arange(B, dtype=np.float64)[:, None]
    idx = np.searchsorted((c + off).ravel(), (u + off).ravel(), side="left").reshape(u.shape)
    idx -= (np.arange(B) * N)[:, None]
    np.clip(idx, 0, N - 1, out=idx)
    while True:
        too_low = np.take_along_axis(c, idx, axis=1) < u
        prev = np.maximum(idx - 1, 0)
        too_high = (idx > 0) & (np.take_along_axis(c, prev, axis=1) >= u)
        if not (too_low.any() or too_high.any()):
            return idx
        idx += too_low
        idx -= too_high


# --------------------------------------------------------------------------------------------
# the schemes: (w (B, N), u (B, U)) -> ancestors (B, N)
# --------------------------------------------------------------------------------------------
def multinomial_ancestors(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Multinomial resampling (Touil & Ghadi 2012, eq. 17): ``a_j = min{i : sum_{l<=i} w_l >= u_j}``.

    Args:
        w: normalized weights ``(B, N)``.
        u: i.i.d. uniforms on ``(0, 1]``, ``(B, N)``.

    Returns:
        Ancestors ``(B, N)`` in draw order.
    """
    return _batched_searchsorted(_cdf(w), u)


def systematic_ancestors(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Systematic resampling: points ``u_j = (j + U) / N``, ``j = 0..N-1``, one ``U`` per filter.

    The number of points at or below a cumulative weight ``c`` is
    ``clip(floor(N c - U) + 1, 0, N)``; offspring counts are its increments (Carpenter et al.
    1999; Douc et al. 2005).

    Args:
        w: normalized weights ``(B, N)``.
        u: uniforms ``U`` on ``(0, 1]``, shape ``(B, 1)`` (or ``(B,)``).

    Returns:
        Ancestors ``(B, N)``, nondecreasing per row.
    """
    B, N = w.shape
    U = np.asarray(u, dtype=np.float64).reshape(B, 1)
    t = _cdf(w)
    t *= N
    t -= U
    np.floor(t, out=t)
    t += 1.0
    np.clip(t, 0.0, N, out=t)
    le = t.astype(np.int64)
    le[:, -1] = N
    return _ancestors_from_bounds(le)


def stratified_ancestors(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Stratified resampling: one point ``u_j = (j + U_j) / N`` in each stratum (Kitagawa 1996).

    With ``t = N c`` and ``k = floor(t)``, the number of points at or below ``c`` is
    ``k + [k < N and U_k <= t - k]`` (``t - k`` is exact in floating point).

    Args:
        w: normalized weights ``(B, N)``.
        u: uniforms ``U_j`` on ``(0, 1]``, ``(B, N)``.

    Returns:
        Ancestors ``(B, N)``, nondecreasing per row.
    """
    B, N = w.shape
    t = _cdf(w)
    t *= N
    k = np.floor(t)
    ki = k.astype(np.int64)
    np.minimum(ki, N - 1, out=ki)
    t -= k
    extra = (np.take_along_axis(u, ki, axis=1) <= t) & (k < N)
    le = k.astype(np.int64) + extra
    le[:, -1] = N
    return _ancestors_from_bounds(le)


def residual_ancestors(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Residual resampling (Liu & Chen 1998): deterministic copies, multinomial remainder.

    Particle ``i`` gets ``floor(N w_i)`` copies; the remaining ``R = N - sum_i floor(N w_i)``
    ancestors are drawn by eq. 17 from the residual weights ``(N w_i - floor(N w_i)) / R``,
    using the first ``R`` of the uniforms ``u[b]``.

    Args:
        w: normalized weights ``(B, N)``.
        u: i.i.d. uniforms on ``(0, 1]``, ``(B, N)`` (only the first ``R_b`` of row ``b`` used).

    Returns:
        Ancestors ``(B, N)``, nondecreasing per row.
    """
    B, N = w.shape
    Nw = w * N
    det = np.floor(Nw)
    resid = Nw - det
    counts = det.astype(np.int64)
    R = N - counts.sum(axis=1)
    if R.any():
        # rows with R == 0 draw nothing; give them a harmless CDF (their residuals may be 0)
        resid = np.where(R[:, None] > 0, resid, 1.0)
        c = _cdf(resid)
        idx = _batched_searchsorted(c, u)
        used = np.arange(N)[None, :] < R[:, None]
        flat = (idx + (np.arange(B) * N)[:, None])[used]
        counts += np.bincount(flat, minlength=B * N).reshape(B, N)
    return _ancestors_from_bounds(np.cumsum(counts, axis=1))


class Resampler(NamedTuple):
    """A registered scheme: its kernel and how many uniforms per filter it consumes."""

    kernel: Callable[[np.ndarray, np.ndarray], np.ndarray]
    n_uniforms: Callable[[int], int]


#: Resampling schemes by name: ``RESAMPLERS[name].kernel(w, u) -> ancestors``.
RESAMPLERS: dict[str, Resampler] = {
    "multinomial": Resampler(multinomial_ancestors, lambda N: N),
    "stratified": Resampler(stratified_ancestors, lambda N: N),
    "systematic": Resampler(systematic_ancestors, lambda N: 1),
    "residual": Resampler(residual_ancestors, lambda N: N),
}


def resample(
    log_w: np.ndarray,
    rng: Rng,
    method: str = "systematic",
    decision: np.ndarray | bool | None = None,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Ancestor indices for B filters; filters with ``decision`` False keep their particles.

    Implements the resampling step of the bootstrap filter (Touil & Ghadi 2012, eq. 16-17; the
    "redistribution" of Carvalho et al. 1997, §III-D). Weights are normalized internally
    (``w = exp(log_w - logsumexp(log_w))``), so unnormalized log-weights are fine.

    Args:
        log_w: log-weights ``(B, N)``; ``-inf`` (zero weight) allowed, NaN and ``+inf`` not.
        rng: one ``np.random.Generator`` or a sequence of ``B`` (see the module docstring for
            the batching semantics).
        method: a key of :data:`RESAMPLERS`.
        decision: ``(B,)`` booleans (or a scalar); None resamples every filter.
        weights: ``exp(log_w)`` normalized per row, when the caller already has it (saves the
            exponentiation; not re-checked).

    Returns:
        Ancestors ``(B, N)`` int64: ``x_new[b, j] = x[b, a[b, j]]``; rows with decision False
        are ``0..N-1``.

    Raises:
        ValueError: naming ``log_w``, ``method``, ``decision`` or ``rng`` on bad input.
    """
    lw = check_log_weights(log_w)
    B, N = lw.shape
    try:
        scheme = RESAMPLERS[method]
    except (KeyError, TypeError):
        raise ValueError(f"method must be one of {sorted(RESAMPLERS)}; got {method!r}") from None
    d = check_decision(decision, B)
    check_rng(rng, B)
    if weights is not None and np.shape(weights) != (B, N):
        raise ValueError(f"weights must have shape {(B, N)} like log_w; got {np.shape(weights)}")
    rows = np.flatnonzero(d)
    if rows.size == B:
        u = uniform(rng, B, (scheme.n_uniforms(N),), rows)
        return scheme.kernel(normalized_weights(lw) if weights is None else weights, u)
    anc = np.broadcast_to(np.arange(N), (B, N)).copy()
    if rows.size == 0:
        return anc
    u = uniform(rng, B, (scheme.n_uniforms(N),), rows)
    anc[rows] = scheme.kernel(normalized_weights(lw[rows]) if weights is None else weights[rows], u)
    return anc
