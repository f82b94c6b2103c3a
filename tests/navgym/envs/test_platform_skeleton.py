"""Tests of the toy platform of ``toy.py``, written as docs/add_a_platform.md says."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from tests.navgym.envs.toy import ToyEnv, ToyVectorEnv


@pytest.mark.parametrize("task", ["fading", "mixture"])
def test_a_platform_written_as_the_readme_says_passes_the_checker(task):
    env = ToyEnv(task=task)
    check_env(env, skip_render_check=True)
    venv = ToyVectorEnv(num_envs=3, task=task)
    obs, _ = venv.reset(seed=11)
    for i in range(3):
        single, _ = ToyEnv(task=task).reset(seed=11 + i)
        np.testing.assert_array_equal(obs[i], single)
    actions = np.zeros((3, 1), dtype=np.float32)
    for _ in range(5):
        obs, reward, term, trunc, info = venv.step(actions)
    assert np.isfinite(reward).all() and np.isfinite(info["pos_err_m"]).all()


def test_the_skeleton_fills_the_card_and_checks_the_arguments():
    doc = ToyEnv.__doc__
    assert "{" not in doc.replace('{"scenario"', "")  # every placeholder filled
    assert "``ToyFading`` (" in doc and "| 0-1 | innovation |" in doc
    assert "error_scale_m = 5`` m" in doc and "``outage_duration=(5, 20)``" in doc
    with pytest.raises(TypeError, match="sigma"):
        ToyEnv(sigma="3")
    with pytest.raises(ValueError, match="task must be one of"):
        ToyEnv(task="resample")
    with pytest.raises(TypeError, match="unexpected keyword arguments"):
        ToyEnv(no_such_argument=1)
    with pytest.raises(TypeError, match="episode_steps must be an integer"):
        ToyEnv(episode_steps=1.5)
    with pytest.raises(TypeError, match="num_envs must be an integer"):
        ToyVectorEnv(num_envs=1.5)


def test_registered_like_the_others():
    env_id = "navgym-test/ToyFading-v0"
    if env_id not in gym.registry:
        gym.register(env_id, entry_point=ToyEnv, vector_entry_point=ToyVectorEnv, max_episode_steps=60)
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    assert obs.shape == (2, venv.single_observation_space.shape[0])
