"""Compiled GDOP of the GpsIns observation: :func:`navgym.gnss.visibility.gdop`'s numbers.

Every GpsIns step observes ``log10 GDOP`` at the estimate (:meth:`GpsInsPlatform.feature_values
<navgym.gps_ins.platform.GpsInsPlatform.feature_values>`). :func:`~navgym.gnss.visibility.gdop`
forms ``A = G^T W G`` and ``tr A^-1`` by some 40 NumPy passes over ``(B,)`` and ``(B, m)``
arrays: cheap per member at large B, but at B = 1 their call overhead is a sizeable part of a
single env's step. :func:`gdop` here does the same arithmetic, in the same order, in two
compiled loops around the one matrix product ``A = Gw Gw^T``, which stays NumPy's
(:func:`filters.core.linalg.gram`: BLAS fixes its summation order): the line-of-sight matrix
``Gw``, then the element-wise Cholesky of :func:`filters.core.linalg.cholesky_unrolled`, the
forward substitution of :func:`~filters.core.linalg.solve_lower_rows` against the identity and
the sum of squares of :func:`~filters.core.linalg.trace_of_spd_inverse`. Every operation is an
IEEE add, multiply, divide or square root rounded as NumPy rounds it (no fused multiply-add),
so the result equals :func:`~navgym.gnss.visibility.gdop` bit for bit
(``tests/navgym/gps_ins/test_gdop_kernel.py``); the platform's ``compiled=False`` uses that
function itself.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.linalg import gram

__all__ = ["gdop"]


@njit(cache=True, error_model="numpy")
def _line_of_sight(rx, sat, w, Gw):  # pragma: no cover - compiled
    """``Gw[b] = [-u^T w; w]`` (``(4, m)``): minus the unit lines of sight, 0 where masked."""
    B, m = w.shape
    for b in range(B):
        for r in range(m):
            d0 = sat[b, r, 0] - rx[b, 0]
            d1 = sat[b, r, 1] - rx[b, 1]
            d2 = sat[b, r, 2] - rx[b, 2]
            scale = w[b, r] / np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            neg = -scale
            Gw[b, 0, r] = d0 * neg
            Gw[b, 1, r] = d1 * neg
            Gw[b, 2, r] = d2 * neg
            Gw[b, 3, r] = w[b, r]


@njit(cache=True, error_model="numpy")
def _gdop_of_gram(A, out):  # pragma: no cover - compiled
    """``sqrt(tr A^-1)`` per member, ``inf`` with fewer than 4 rows or a degenerate geometry."""
    B = A.shape[0]
    M = np.empty((4, 4))
    L = np.zeros((4, 4))
    Y = np.empty((4, 4))
    for b in range(B):
        enough = A[b, 3, 3] >= 4
        for i in range(4):
            for j in range(4):
                M[i, j] = A[b, i, j] if enough else (1.0 if i == j else 0.0)
        # cholesky_unrolled: Cholesky-Banachiewicz, pivot 1 where not positive
        chol_ok = True
        for i in range(4):
            for j in range(i + 1):
                acc = M[i, j] if j == 0 else M[i, j] - L[i, 0] * L[j, 0]
                for q in range(1, j):
                    acc -= L[i, q] * L[j, q]
                if i == j:
                    good = acc > 0
                    chol_ok = chol_ok and good
                    L[i, i] = np.sqrt(acc if good else 1.0)
                else:
                    L[i, j] = acc / L[j, j]
        # solve_lower_rows(L, I): Y[r, i] for the identity's rows r
        for r in range(4):
            for i in range(4):
                x = 1.0 if r == i else 0.0
                acc = x if i == 0 else x - Y[r, 0] * L[i, 0]
                for q in range(1, i):
                    acc -= Y[r, q] * L[i, q]
                Y[r, i] = acc / L[i, i]
        total = 0.0
        for j in range(4):
            for i in range(j, 4):
                total += Y[j, i] * Y[j, i]
        tr = total if chol_ok else np.nan
        if enough and np.isfinite(tr) and tr > 0:
            out[b] = np.sqrt(np.abs(tr))
        else:
            out[b] = np.inf


def gdop(rx_ecef: np.ndarray, sat_ecef: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """:func:`navgym.gnss.visibility.gdop` (same arguments, same values), compiled (module docstring).

    Args:
        rx_ecef: receiver positions ``(B, 3)`` [m].
        sat_ecef: satellite positions ``(B, m, 3)`` [m].
        mask: usable rows ``(B, m)`` (bool).

    Returns:
        ``(B,)`` GDOP values (``inf`` with fewer than 4 usable satellites or a degenerate geometry).
    """
    rx = np.ascontiguousarray(rx_ecef, dtype=np.float64)
    sat = np.ascontiguousarray(sat_ecef, dtype=np.float64)
    w = np.ascontiguousarray(np.asarray(mask).astype(np.float64))
    B, m = w.shape
    Gw = np.empty((B, 4, m))
    _line_of_sight(rx, sat, w, Gw)
    A = np.ascontiguousarray(gram(Gw))
    out = np.empty(B)
    _gdop_of_gram(A, out)
    return out
