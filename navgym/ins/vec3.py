"""Vectors as component triples: three arrays of one shape instead of one ``(..., 3)`` array.

The truth generators and the inverse mechanization evaluate millions of points at reset; on
``(..., 3)`` arrays every cross product, dot product or 3 x 3 product is a reduction over a
trailing axis of length 3, where NumPy's per-inner-loop overhead dominates. On component
triples each is a few element-wise passes over contiguous memory.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Vec3", "cross", "dot"]

#: Three arrays (or scalars), the components of a vector along its frame's axes.
Vec3 = tuple[np.ndarray, np.ndarray, np.ndarray]


def dot(a: Vec3, b: Vec3) -> np.ndarray:
    """``a . b``."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a: Vec3, b: Vec3) -> Vec3:
    """``a x b``."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
