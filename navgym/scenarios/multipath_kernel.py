"""Compiled (Numba) twin of :func:`navgym.scenarios.batch.multipath_error`'s sums.

For every episode ``b``, time ``t`` and multipath segment ``k`` active at ``t``
(``start_k <= t < end_k``), the segment's bias and variance ``sigma_k^2`` are added to its row:
``bias[b, t, row_k] += bias_k``, ``var[b, t, row_k] += sigma_k^2``, the segments in order ``k =
0, 1, ...``, which is the order and rounding of the NumPy form's ``np.where(hit, bias,
0).sum(axis=2)`` over ``(B, T, K, m)`` (adding a zero changes nothing), so the two agree bit for
bit (``tests/navgym/scenarios/test_events.py``).

Why: the NumPy form builds four ``(B, T, K, m)`` temporaries; at a reset of 256 episodes of 601
steps, 4 segment slots and 5 rows (Robot2d), about 50-120 ms of a 250 ms reset. The loop
touches each ``(b, t, k)`` once: about a millisecond.
"""

from __future__ import annotations

from numba import njit

__all__ = ["multipath_pass"]


@njit(cache=True)
def multipath_pass(start, end, row, bias, sigma, tt, bias_out, var_out):  # pragma: no cover - compiled
    """Add the active segments of ``(B, K)`` ``start, end, row, bias, sigma`` at times ``tt (B, T)``.

    ``bias_out`` and ``var_out`` ``(B, T, m)`` start at zero. Unused slots (``start`` infinite
    or NaN) are never active.
    """
    B, T = tt.shape
    K = start.shape[1]
    for b in range(B):
        for t in range(T):
            x = tt[b, t]
            for k in range(K):
                if start[b, k] <= x and x < end[b, k]:
                    r = row[b, k]
                    bias_out[b, t, r] += bias[b, k]
                    s = sigma[b, k]
                    var_out[b, t, r] += s * s
