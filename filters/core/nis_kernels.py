"""Compiled (Numba) twin of the NIS over a subset of rows, ``v_k^T S_kk^-1 v_k``.

:func:`masked_nis_pass` gives, per filter, the normalized innovation squared over the kept rows
``k`` of ``v (m,)`` with covariance ``S (m, m)``: the kept block ``S_kk = L L^T`` (Cholesky), then
``|L^-1 v_k|^2``. It is the quadratic form of the chi-square test
(:func:`filters.innovation_adaptive.chi_square_exclusion`), whose NumPy form replaces the rows
not kept by an identity block and solves with ``np.linalg.solve``.

Why: ``np.linalg.solve`` on a ``(B, m, m)`` stack calls LAPACK once per matrix (about 200 us
at B = 1024, m = 5, and up to three solves an epoch); one compiled pass costs a few
microseconds. A filter whose kept block is not positive definite (only a broken ``S``) is
reported and the caller runs the NumPy form for the batch.

:func:`quadratic_form_pass` is the same quadratic form over every row, ``e^T P^-1 e``, with a
per-filter flag: the environments' NEES (:func:`navgym.envs.core._nees`), whose NumPy form
(``np.linalg.cholesky`` and a forward substitution) also calls LAPACK once per matrix. A filter
whose ``P`` is not positive definite is flagged for the caller's per-filter fallback, so every
other filter's value is the same whatever that one holds.

:func:`masked_sum_of_squares_pass` is the NIS of whitened innovations (``S = I``), the test the
per-row baselines run on their normalized innovations.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.gaussian_kernels import cholesky_small

__all__ = ["masked_nis_pass", "masked_sum_of_squares_pass", "quadratic_form_pass"]


@njit(cache=True, error_model="numpy")
def masked_nis_pass(v, S, keep, nis):  # pragma: no cover - compiled
    """``nis[b] = v_k^T S_kk^-1 v_k`` over ``keep[b]``; False where some ``S_kk`` is not PD."""
    B, m = v.shape
    Sk = np.empty((m, m))
    L = np.empty((m, m))
    idx = np.empty(m, dtype=np.int64)
    e = np.empty(m)
    for b in range(B):
        k = 0
        for i in range(m):
            if keep[b, i]:
                idx[k] = i
                k += 1
        for i in range(k):
            for j in range(k):
                Sk[i, j] = S[b, idx[i], idx[j]]
        if not cholesky_small(Sk[:k, :k], L[:k, :k]):
            return False
        q = 0.0
        for i in range(k):  # L e = v_k
            s = v[b, idx[i]]
            for p in range(i):
                s -= L[i, p] * e[p]
            e[i] = s / L[i, i]
            q += e[i] * e[i]
        nis[b] = q
    return True


@njit(cache=True, error_model="numpy")
def masked_sum_of_squares_pass(v, keep, nis):  # pragma: no cover - compiled
    """``nis[b] = sum_i v[b, i]^2`` over ``keep[b]`` in row order: :func:`masked_nis_pass` for ``S = I``.

    The same operations in the same order as ``masked_nis_pass`` on an identity block (its
    Cholesky factor is ``I``, its forward substitution subtracts zeros and divides by one), so
    the same bits, without forming and factoring ``B`` identity matrices.
    """
    B, m = v.shape
    for b in range(B):
        q = 0.0
        for i in range(m):
            if keep[b, i]:
                q += v[b, i] * v[b, i]
        nis[b] = q


@njit(cache=True, error_model="numpy")
def quadratic_form_pass(v, S, q, ok):  # pragma: no cover - compiled
    """``q[b] = v_b^T S_b^-1 v_b`` by ``S_b = L L^T``; ``ok[b]`` False (``q[b]`` NaN) where not PD."""
    B, m = v.shape
    L = np.empty((m, m))
    e = np.empty(m)
    for b in range(B):
        if not cholesky_small(S[b], L):
            ok[b] = False
            q[b] = np.nan
            continue
        acc = 0.0
        for i in range(m):  # L e = v
            s = v[b, i]
            for p in range(i):
                s -= L[i, p] * e[p]
            e[i] = s / L[i, i]
            acc += e[i] * e[i]
        q[b] = acc
        ok[b] = True
