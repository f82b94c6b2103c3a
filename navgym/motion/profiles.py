"""Smooth motion profiles and batched piecewise evaluation shared by the truth generators.

Rest-to-rest moves use the septic "smootherstep" ``s(tau) = 35 tau^4 - 84 tau^5 + 70 tau^6 -
20 tau^7`` on ``tau in [0, 1]``, whose first three derivatives vanish at both ends: chaining
such moves gives trajectories with continuous velocity, acceleration and jerk, hence continuous
attitude and angular rate for a quadrotor, whose tilt follows its acceleration.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "smootherstep",
    "SMOOTHERSTEP_PEAK_RATE",
    "SMOOTHERSTEP_PEAK_ACCEL",
    "segment_index",
    "gauss_legendre_partial",
]

#: max s'(tau) = s'(1/2) = 35/16.
SMOOTHERSTEP_PEAK_RATE = 35.0 / 16.0
#: max |s''(tau)|, at tau = 1/2 -+ sqrt(5)/10 (84 sqrt(5)/25).
SMOOTHERSTEP_PEAK_ACCEL = 84.0 * np.sqrt(5.0) / 25.0


def smootherstep(tau: ArrayLike, order: int = 0) -> NDArray[np.float64]:
    """Septic smootherstep and its derivatives, with ``tau`` clipped to [0, 1].

    ``s = 35 t^4 - 84 t^5 + 70 t^6 - 20 t^7``, ``s' = 140 t^3 (1 - t)^3``,
    ``s'' = 420 t^2 (1 - t)^2 (1 - 2 t)``, ``s''' = 840 t (1 - t) (1 - 5 t + 5 t^2)``;
    ``order = -1`` gives the antiderivative
    ``S = 7 t^5 - 14 t^6 + 10 t^7 - 5/2 t^8`` (with ``S(tau) = S(1) + tau - 1`` beyond 1).

    Args:
        tau: Normalized time, any shape.
        order: -1 (integral), 0, 1, 2 or 3.

    Returns:
        Values of the same shape; derivatives vanish outside [0, 1].

    """
    t = np.clip(np.asarray(tau, np.float64), 0.0, 1.0)
    u = 1.0 - t
    # products instead of ``**`` (NumPy's float power is several times slower)
    if order == 0:
        t2 = t * t
        return t2 * t2 * (35.0 + t * (-84.0 + t * (70.0 - 20.0 * t)))
    if order == 1:
        tu = t * u
        return 140.0 * tu * tu * tu
    if order == 2:
        tu = t * u
        return 420.0 * tu * tu * (1.0 - 2.0 * t)
    if order == 3:
        return 840.0 * t * u * (1.0 - 5.0 * t + 5.0 * t * t)
    if order == -1:
        t2 = t * t
        s_int = t2 * t2 * t * (7.0 + t * (-14.0 + t * (10.0 - 2.5 * t)))
        return s_int + np.maximum(np.asarray(tau, np.float64) - 1.0, 0.0)
    raise ValueError(f"order must be -1, 0, 1, 2 or 3, got {order!r}")


#: :func:`segment_index` compares every query with every start when there are at most this
#: many starts or queries per episode (a comparison costs a small fraction of a query of the
#: batched search over time-sorted queries; ``docs/performance.md``, "Figures behind the code").
_DIRECT_STARTS = 6
_DIRECT_QUERIES = 4
#: Booleans held at once by the direct comparison.
_DIRECT_CHUNK = 1 << 22


def segment_index(t_start: ArrayLike, t: ArrayLike) -> NDArray[np.intp]:
    """Index of the active segment for each query time, batched over episodes.

    ``idx[b, k] = max{i : t_start[b, i] <= t[b, k]}`` (0 before the first start); rows of
    ``t_start`` must be non-decreasing (``inf`` pads unused segments).

    With very few segments or query times per episode (a step at a time) every start is
    compared with every time, ``O(B T S)`` in chunks; otherwise (a whole episode at reset) one
    ``np.searchsorted`` runs over all rows at once, ``O(B T log(B S))``, fastest when each row's
    times are sorted: row ``r`` is shifted by ``r * span`` so that the flattened
    starts stay sorted (rounding is monotone), and the rounding of the shift is then undone by
    an exact comparison with the unshifted starts.

    Args:
        t_start: Segment start times, shape ``(B, S)``.
        t: Query times, shape ``(B, T)``.

    Returns:
        Integer indices of shape ``(B, T)``.

    Raises:
        ValueError: If the shapes do not match or a time is not finite.

    """
    ts = np.asarray(t_start, np.float64)
    t = np.asarray(t, np.float64)
    if ts.ndim != 2 or t.ndim != 2 or t.shape[0] != ts.shape[0]:
        raise ValueError(f"t_start must be (B, S) and t (B, T); got {ts.shape} and {t.shape}")
    b, s = ts.shape
    if t.size == 0:
        return np.zeros(t.shape, dtype=np.intp)
    if not np.isfinite(t).all():
        raise ValueError("t must be finite")
    if s <= _DIRECT_STARTS or t.shape[1] <= _DIRECT_QUERIES:
        n = t.shape[1]
        step = max(1, _DIRECT_CHUNK // max(1, b * s))
        out = np.empty((b, n), dtype=np.intp)
        for k in range(0, n, step):
            out[:, k : k + step] = (ts[:, None, :] <= t[:, k : k + step, None]).sum(axis=-1) - 1
        return np.maximum(out, 0)
    finite = np.isfinite(ts)
    lo = min(float(t.min()), float(ts[finite].min()) if finite.any() else 0.0)
    hi = max(float(t.max()), float(ts[finite].max()) if finite.any() else 0.0)
    width = hi - lo + 1.0
    off = (2.0 * width) * np.arange(b, dtype=np.float64)[:, None]
    keys = np.where(finite, ts - lo, width) + off  # pads sit between a row's times and the next row
    flat = np.searchsorted(keys.ravel(), ((t - lo) + off).ravel(), side="right")
    idx = flat.reshape(t.shape) - 1 - s * np.arange(b)[:, None]
    np.clip(idx, 0, s - 1, out=idx)
    while True:  # exact correction of the shift's rounding (at most a step or two)
        nxt = np.minimum(idx + 1, s - 1)
        up = (idx < s - 1) & (np.take_along_axis(ts, nxt, axis=1) <= t)
        down = (idx > 0) & (np.take_along_axis(ts, idx, axis=1) > t)
        if not (up.any() or down.any()):
            return idx
        idx += up
        idx -= down


_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)


def gauss_legendre_partial(f, upper: ArrayLike, leading: int = 0) -> NDArray[np.float64]:
    """Integral of ``f`` from 0 to ``upper`` by 16-point Gauss-Legendre quadrature.

    Args:
        f: Vectorized integrand taking ``x`` of shape ``upper.shape + (16,)`` and returning an
            array of shape ``upper.shape + (16,) + rest`` (``leading = 0``) or
            ``rest + upper.shape + (16,)`` (``leading = len(rest)``: the node axis last, so the
            weighted sum runs along contiguous memory).
        upper: Upper limits, any shape.
        leading: Number of leading output axes of ``f`` (see ``f``).

    Returns:
        Integrals of shape ``upper.shape + rest`` (``leading = 0``) or ``rest + upper.shape``.

    """
    up = np.asarray(upper, np.float64)
    x = 0.5 * up[..., None] * (_GL_NODES + 1.0)
    fx = f(x)
    w = 0.5 * up[..., None] * _GL_WEIGHTS
    if leading:
        return np.einsum("...k,...k->...", fx, np.broadcast_to(w, fx.shape))
    w = w.reshape(w.shape + (1,) * (fx.ndim - w.ndim))
    return (fx * w).sum(axis=up.ndim)
