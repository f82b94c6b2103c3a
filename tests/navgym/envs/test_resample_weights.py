"""The Resample task's carried linear weights stay exp(log_w) through steps and autoresets."""

import gymnasium as gym
import numpy as np
import pytest

from filters.core.compiled import numpy_only
from filters.particle import estimates


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("env_id", ["navgym/Robot2dResample-v2", "navgym/GpsInsResample-v2"])
def test_the_carried_weights_are_the_normalized_exp_of_the_log_weights(env_id, compiled):
    with numpy_only() if not compiled else np.errstate():
        env = gym.make_vec(
            env_id, num_envs=5, vectorization_mode="vector_entry_point", n_particles=200, max_episode_steps=15
        )
        env.reset(seed=3)
        core = env.unwrapped.core
        rng = np.random.default_rng(0)
        for t in range(40):
            env.step(rng.integers(0, 2, 5))
            state = core.state
            np.testing.assert_allclose(
                state.weights,
                estimates.weights(state.particles.log_w),
                rtol=1e-9,
                atol=1e-300,
                err_msg=f"step {t}",
            )
        env.close()
