"""Memory layout and precision of batched particle clouds ``x (B, N, n)``.

A cloud may be stored C-ordered (``(B, N, n)``, "array of structures") or as the transposed
view of a C-contiguous ``(B, n, N)`` buffer ("structure of arrays", component-major): then every
element-wise pass runs along the N particles instead of along the short state axis. A cloud is
float64, or float32 where its numbers are metres-sized (:mod:`filters.particle.bootstrap`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["cloud_dtype", "is_component_major", "weights_in"]


def is_component_major(x: np.ndarray) -> bool:
    """True when ``x (B, N, n)`` is the transposed view of a C-contiguous ``(B, n, N)`` buffer."""
    return x.ndim == 3 and not x.flags.c_contiguous and x.transpose(0, 2, 1).flags.c_contiguous


def cloud_dtype(x: np.ndarray) -> np.dtype:
    """The precision a cloud's steps keep: float32 for a float32 cloud, float64 otherwise."""
    return np.dtype(np.float32) if x.dtype == np.float32 else np.dtype(np.float64)


def weights_in(w: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Normalized weights ``w`` (float64) in a cloud's precision, with tiny weights set to 0.

    Casting to float32 turns weights below ``finfo(float32).tiny`` (1.2e-38; log-weights
    below about -87, common in a degenerate cloud) into subnormal numbers, and a weight just
    above it gives subnormal products with small centred values; arithmetic with subnormal
    operands or results takes microcode assists on many x86 cores (on one, a never-resampled
    float32 filter's weighted moments, ``w^T h(x)`` and the ``(B, N, m)`` outer products, ran
    2-3x slower). Weights below ``tiny / eps`` (1e-31: products with numbers down to ``eps``
    stay normal) are therefore set to zero; together they change a moment by less than
    ``N * 1e-31`` of its size, far below float32 rounding. float64 weights pass through (their
    ``exp`` already flushes: :func:`filters.core.resampling.exp_weights`).
    """
    dtype = np.dtype(dtype)
    if w.dtype == dtype:
        return w
    out = w.astype(dtype)
    info = np.finfo(dtype)
    floor = info.tiny / info.eps
    if out.size and out.min() < floor:  # zero weights also land here; they stay 0
        out[out < floor] = 0.0
    return out
