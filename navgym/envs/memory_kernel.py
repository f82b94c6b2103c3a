"""Compiled (Numba) twin of :meth:`navgym.envs.memory.InnovationMemory.update`.

:func:`memory_pass` advances the innovation memory of B episodes by one filter step and writes
its observation columns, one episode per loop iteration (the equations are the module
docstring's of :mod:`navgym.envs.memory`: the exponentially weighted averages ``s <- (1 - alpha)
s + alpha x``, ``w <- (1 - alpha) w + alpha`` of ``log(1 + NIS / rows)`` and of each row's
clipped normalized innovation ``v_i / sqrt(S_ii)``, and Mehra's lag-1 whiteness over a ring of
window sums).

Why: the NumPy form is about forty passes over ``(B, m)`` and ``(B, window, 3)`` arrays, which
at training's batch sizes (1-64 episodes) cost their per-call overhead (110-130 us of a 0.9 ms
GpsIns step at B = 1 and 16, ``navgym bench step_profile``); one compiled pass costs a few
microseconds. The NumPy form stays the reference (``filters.core.compiled.numpy_only`` forces
it); ``tests/navgym/envs/test_memory_kernel.py`` holds the two equal to rounding, NaN and
masked rows included.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["memory_pass"]


@njit(cache=True, error_model="numpy")
def memory_pass(
    S, innovation, nis, n_meas, used, slot, alphas, beta, bound_y, bound_x,
    nis_sum, nis_weight, innovation_sum, innovation_weight, last_innovation, last_used, pairs,
    nis_avg, innovation_avg, whiteness,
):  # pragma: no cover - compiled  # fmt: skip
    """One step of the memory of every episode, in place, and its columns.

    Inputs: ``S (B, m, m)`` (its diagonal read), ``innovation (B, m)``, ``nis (B,)``,
    ``n_meas (B,)``, ``used (B, m)`` rows received, ``slot (B,)`` the whiteness ring's slot of
    this step, ``alphas (K,)`` the NIS averages' factors, ``beta`` the row averages' factor,
    the clipping bounds of ``y`` and ``x``. State (updated in place): ``nis_sum``,
    ``nis_weight (B, K)``, ``innovation_sum``, ``innovation_weight``, ``last_innovation``,
    ``last_used (B, m)``, ``pairs (B, window, 3)``. Columns out: ``nis_avg (B, K)``,
    ``innovation_avg (B, m)``, ``whiteness (B,)``.
    """
    B, m = used.shape
    K = alphas.shape[0]
    window = pairs.shape[1]
    for b in range(B):
        q = nis[b]
        cnt = n_meas[b]
        if np.isnan(q):
            x = bound_x
        else:
            x = np.log1p((q if q > 0.0 else 0.0) / (cnt if cnt > 1 else 1))
            x = min(max(x, 0.0), bound_x)
        for k in range(K):
            if cnt > 0:
                a = alphas[k]
                nis_sum[b, k] = (1.0 - a) * nis_sum[b, k] + a * x
                nis_weight[b, k] = (1.0 - a) * nis_weight[b, k] + a
            w = nis_weight[b, k]
            nis_avg[b, k] = nis_sum[b, k] / w if w > 0.0 else 0.0
        c = 0.0
        aa = 0.0
        bb = 0.0
        for i in range(m):
            y = 0.0
            if used[b, i]:
                d = S[b, i, i]
                d = d if d > 1e-12 or np.isnan(d) else 1e-12
                y = innovation[b, i] / np.sqrt(d)
                if np.isnan(y):
                    y = 0.0
                y = min(max(y, -bound_y), bound_y)
                innovation_sum[b, i] = (1.0 - beta) * innovation_sum[b, i] + beta * y
                innovation_weight[b, i] = (1.0 - beta) * innovation_weight[b, i] + beta
                if last_used[b, i]:
                    yl = last_innovation[b, i]
                    c += y * yl
                    aa += y * y
                    bb += yl * yl
            w = innovation_weight[b, i]
            innovation_avg[b, i] = innovation_sum[b, i] / w if w > 0.0 else 0.0
            last_innovation[b, i] = y
            last_used[b, i] = used[b, i]
        s = slot[b]
        pairs[b, s, 0] = c
        pairs[b, s, 1] = aa
        pairs[b, s, 2] = bb
        c = 0.0
        aa = 0.0
        bb = 0.0
        for j in range(window):
            c += pairs[b, j, 0]
            aa += pairs[b, j, 1]
            bb += pairs[b, j, 2]
        den = np.sqrt(aa * bb)
        r = c / den if den > 0.0 else 0.0
        whiteness[b] = min(max(r, -1.0), 1.0)
