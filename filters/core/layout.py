"""Memory layout and precision of batched particle clouds ``x (B, N, n)``.

A cloud may be stored C-ordered (``(B, N, n)``, "array of structures") or as the transposed
view of a C-contiguous ``(B, n, N)`` buffer ("structure of arrays", component-major): then every
element-wise pass runs along the N particles instead of along the short state axis. A cloud is
float64, or float32 where its numbers are metres-sized (:mod:`filters.particle.bootstrap`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["cloud_dtype", "is_component_major"]


def is_component_major(x: np.ndarray) -> bool:
    """True when ``x (B, N, n)`` is the transposed view of a C-contiguous ``(B, n, N)`` buffer."""
    return x.ndim == 3 and not x.flags.c_contiguous and x.transpose(0, 2, 1).flags.c_contiguous


def cloud_dtype(x: np.ndarray) -> np.dtype:
    """The precision a cloud's steps keep: float32 for a float32 cloud, float64 otherwise."""
    return np.dtype(np.float32) if x.dtype == np.float32 else np.dtype(np.float64)
