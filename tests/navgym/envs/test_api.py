"""The public API of navgym envs for baselines, oracles and evaluation (navgym.envs.base)."""

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401
from navgym.envs.base import NavEnv, NavVectorEnv, navigation_env
from navgym.envs.sb3 import NavSB3VecEnv


def test_navigation_env_finds_the_env_through_wrappers_and_the_sb3_adapter():
    single = gym.make("navgym/Robot2dFading-v1")
    assert isinstance(navigation_env(single), NavEnv)
    venv = gym.make_vec("navgym/Robot2dFading-v1", num_envs=2, vectorization_mode="vector_entry_point")
    assert navigation_env(venv) is venv.unwrapped
    sb3 = NavSB3VecEnv(venv)
    assert navigation_env(sb3) is venv.unwrapped
    assert isinstance(navigation_env("navgym/GpsInsFading-v1"), NavEnv)
    with pytest.raises(ValueError, match="not a navgym environment"):
        navigation_env(gym.make("CartPole-v1"))


def test_api_members_describe_task_platform_and_observation():
    env = gym.make("navgym/GpsInsMixture-v1", max_episode_steps=50)
    nav = navigation_env(env)
    assert nav.task.name == "Mixture" and nav.task.eps_max == 0.5
    assert nav.platform.name == "GpsIns" and nav.platform.dt == 1.0
    assert nav.observation_features.dim == env.observation_space.shape[0]
    assert nav.observation_features.index("outlier_posterior") == slice(19, 20)  # 12 innovations + 7 columns
    assert nav.horizon == 300  # gym.make's TimeLimit truncates; the env simulates episode_steps
    venv = gym.make_vec("navgym/GpsInsMixture-v1", num_envs=2, vectorization_mode="vector_entry_point",
                        max_episode_steps=50)  # fmt: skip
    assert navigation_env(venv).horizon == 50


def test_episode_stepper_equals_env_step_until_the_episode_ends_and_never_autoresets():
    kw = {"num_envs": 3, "vectorization_mode": "vector_entry_point", "max_episode_steps": 6}
    a = gym.make_vec("navgym/Robot2dFading-v1", **kw)
    b = gym.make_vec("navgym/Robot2dFading-v1", **kw)
    a.reset(seed=3)
    b.reset(seed=3)
    stepper = navigation_env(b).episode_stepper()
    actions = np.zeros((3, 1), dtype=np.float32)
    for _ in range(6):
        ra = a.step(actions)
        rb = stepper.step(actions)
        np.testing.assert_array_equal(ra[0], rb[0])
        np.testing.assert_array_equal(ra[1], rb[1])
    assert rb[3].all()  # truncated at the horizon
    rb = stepper.step(actions)  # no autoreset: rows restart from the stepper's start, not a new episode
    assert navigation_env(b).core.scenarios == navigation_env(a).core.scenarios
    assert isinstance(navigation_env(b), NavVectorEnv)
