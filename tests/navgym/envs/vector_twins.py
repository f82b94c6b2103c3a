"""The vector-equals-singles check shared by the platforms' tests (event-heavy settings)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np


def assert_vector_equals_singles(env_id: str, n: int, seed: int, steps: int, **kwargs: Any) -> None:
    """Sub-env ``i`` of the native vector env seeded ``seed`` equals a single env seeded ``seed + i``.

    Both made with ``kwargs``, stepped ``steps`` times with the same random actions: the
    observations bit for bit, the rewards, episode ends and position errors equal.
    """
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(env_id, **kwargs) for _ in range(n)]
    vobs, _ = venv.reset(seed=seed)
    for i, e in enumerate(singles):
        np.testing.assert_array_equal(vobs[i], e.reset(seed=seed + i)[0])
    rng = np.random.default_rng(0)
    for _ in range(steps):
        a = rng.uniform(-1.0, 1.0, (n, *venv.single_action_space.shape)).astype(np.float32)
        vobs, vr, vterm, vtrunc, vinfo = venv.step(a)
        for i, e in enumerate(singles):
            o, r, term, trunc, info = e.step(a[i])
            np.testing.assert_array_equal(vobs[i], o)
            assert vr[i] == r and vterm[i] == term and vtrunc[i] == trunc
            assert vinfo["pos_err_m"][i] == info["pos_err_m"]
    venv.close()
    for e in singles:
        e.close()
