"""SignalTrackingJumps on the compiled path: the same error statistics as the NumPy form.

The Dirac-Gauss PF runs one EKF per particle; their updates (6 correlator rows on at most three
states) take the compiled observed-subspace kernel (:mod:`filters.core.observed_kernels`), equal
to the NumPy form to rounding (``tests/filters/core/test_observed_kernels.py``). Systematic
resampling is discontinuous in rounding, so particle paths branch and the trace test cannot hold
the errors equal; here the same 32 episodes (40 steps) run with the kernel and without it, and the
paired difference of their mean position errors must be small and its bootstrap CI must hold 0.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import navgym  # noqa: F401  (registers the ids)
from filters.core import observed_kernels

EPISODES, STEPS = 32, 40


def _mean_errors(monkeypatch, kernel: bool, calls: list[int]) -> np.ndarray:
    real = observed_kernels.observed_update

    def counted(*a):
        calls.append(1)
        return real(*a) if kernel else None  # None: kalman.update runs the NumPy form

    monkeypatch.setattr(observed_kernels, "observed_update", counted)
    env = gym.make_vec(
        "navgym/SignalTrackingJumps-v2", num_envs=EPISODES, vectorization_mode="vector_entry_point"
    )
    env.reset(seed=2024)
    action = np.full((EPISODES, 1), 0.1505, dtype=np.float32)  # the plain filter's p
    errors = np.array([env.step(action)[4]["pos_err_m"] for _ in range(STEPS)])
    env.close()
    return errors.mean(axis=0)


def test_the_compiled_path_keeps_the_error_statistics(monkeypatch):
    calls: list[int] = []
    with_kernel = _mean_errors(monkeypatch, True, calls)
    assert calls, "the kernel did not run"
    without = _mean_errors(monkeypatch, False, calls)
    d = with_kernel - without
    rng = np.random.default_rng(0)
    boot = d[rng.integers(0, EPISODES, (2000, EPISODES))].mean(axis=1)
    low, high = np.percentile(boot, [2.5, 97.5])
    assert low <= 0.0 <= high, (d.mean(), low, high)
    assert abs(d.mean()) < 0.1 * without.mean(), (d.mean(), without.mean())
