"""The particle ids give the same numbers on one thread and split over several (filters.core.threads).

The row-parallel passes are forced to split even these small batches (``min_work=0``), with more
threads than the machine may have cores; the observations, rewards and position errors must
equal the one-thread run's bit for bit.
"""

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)
from filters.core.threads import num_threads


def _run(env_id: str, n: int, steps: int) -> list[tuple[np.ndarray, ...]]:
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    out = [(venv.reset(seed=11)[0],)]
    venv.action_space.seed(3)
    for _ in range(steps):
        a = venv.action_space.sample()
        obs, r, term, trunc, info = venv.step(a)
        out.append((obs, r, term, trunc, info["pos_err_m"]))
    venv.close()
    return out


@pytest.mark.parametrize("env_id", ["navgym/Robot2dResample-v2", "navgym/GpsInsResample-v2"])
def test_a_split_batch_steps_like_one_thread(env_id):
    with num_threads(1):
        serial = _run(env_id, 5, 30)
    with num_threads(3, min_work=0):
        split = _run(env_id, 5, 30)
    for a, b in zip(serial, split, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
