"""The Jumps-task baselines (``agents.baselines.jumps``): known answers from crafted observations."""

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from agents.baselines import make_baseline
from agents.baselines.registry import BASELINES, baseline_task

ENV = "navgym/SignalTrackingJumps-v2"


def _obs(env, mean_ll):
    nav = env.unwrapped.core
    obs = np.zeros((len(mean_ll), nav.obs_features.dim))
    obs[:, nav.obs_features.index("mean_log_likelihood")] = np.asarray(mean_ll)[:, None]
    return obs


def test_the_registry_lists_the_jump_baselines():
    env = gym.make(ENV, n_particles=8)
    assert baseline_task(env) == "Jumps"
    assert list(BASELINES["Jumps"]) == ["plain", "constant", "likelihood"]


def test_plain_and_constant_probabilities():
    env = gym.make(ENV, n_particles=8)
    task = env.unwrapped.core.task
    obs = _obs(env, [-8.0, -8.0])
    plain, _ = make_baseline(env, "plain").predict(obs)
    np.testing.assert_allclose(plain, np.tile(task.neutral_action(), (2, 1)))
    const, _ = make_baseline(env, "constant", p=np.array([1e-4, 0.05])).predict(obs)
    np.testing.assert_allclose(task.probabilities(const[:, 0]), [1e-4, 0.05], rtol=1e-5)
    with pytest.raises(ValueError, match="p must lie"):
        make_baseline(env, "constant", p=0.0)


def test_the_likelihood_detector_raises_p_for_hold_plus_one_steps():
    env = gym.make(ENV, n_particles=8)
    task = env.unwrapped.core.task
    pol = make_baseline(env, "likelihood", threshold=-10.0, p_high=0.05, p_low=1e-4, hold=1.0)
    start = np.array([True, True])
    a, state = pol.predict(_obs(env, [-8.0, -20.0]), episode_start=start)
    np.testing.assert_allclose(task.probabilities(a[:, 0]), [1e-4, 1e-4], rtol=1e-5)  # reset obs: no test
    seq = [[-20.0, -8.0], [-8.0, -8.0], [-8.0, -8.0]]
    got = []
    for ll in seq:
        a, state = pol.predict(_obs(env, ll), state=state, episode_start=np.array([False, False]))
        got.append(task.probabilities(a[:, 0]))
    np.testing.assert_allclose(np.array(got)[:, 0], [0.05, 0.05, 1e-4], rtol=1e-5)
    np.testing.assert_allclose(np.array(got)[:, 1], [1e-4] * 3, rtol=1e-5)
