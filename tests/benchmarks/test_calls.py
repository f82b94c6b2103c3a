"""``benchmarks._calls.count_calls``: the calls of a run and those into compiled kernels."""

from __future__ import annotations

import numba
import numpy as np

from benchmarks._calls import count_calls


@numba.njit(cache=False)
def _double(x):
    return 2.0 * x


def _python_helper(x):
    return x + 1


def test_kernel_calls_are_told_from_python_calls():
    x = np.ones(4)
    _double(x)  # compile outside the counted run

    def work():
        for _ in range(3):
            _double(x)
        for _ in range(5):
            _python_helper(x)

    counted = count_calls(work)
    assert counted.kernel_calls == 3
    assert counted.calls >= 3 + 5 + 1  # the kernels, the helper, work itself
    assert 0 < counted.kernel_seconds <= counted.seconds


def test_work_without_kernels_counts_none():
    counted = count_calls(lambda: [np.sum(np.ones(3)) for _ in range(4)])
    assert counted.kernel_calls == 0 and counted.kernel_seconds == 0.0
    assert counted.calls >= 4
