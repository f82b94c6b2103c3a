"""The Robust-task baselines (``agents.baselines.robust``): known answers from crafted observations."""

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from agents.baselines import make_baseline
from agents.baselines.registry import BASELINES, baseline_task
from filters.robust import DEFAULT_THRESHOLDS

ENV = "navgym/JpaRobust-v2"


def _obs(env, log_nis, rows_used=1.0):
    nav = env.unwrapped.core
    obs = np.zeros((len(log_nis), nav.obs_features.dim))
    obs[:, nav.obs_features.index("log_nis")] = np.asarray(log_nis)[:, None]
    obs[:, nav.obs_features.index("rows_used")] = rows_used
    return obs


def test_the_registry_lists_the_robust_baselines():
    env = gym.make(ENV)
    assert baseline_task(env) == "Robust"
    assert list(BASELINES["Robust"]) == ["plain", "seed", "constant", "chi_square"]


@pytest.mark.parametrize("weight", ["huber", "tukey"])
def test_plain_seed_and_constant_thresholds(weight):
    env = gym.make(ENV, weight=weight)
    task = env.unwrapped.core.task
    obs = _obs(env, [0.0, 0.0])
    plain, _ = make_baseline(env, "plain").predict(obs)
    assert np.all(np.isinf(task.thresholds(plain[:, 0].astype(np.float64))))
    seed, _ = make_baseline(env, "seed").predict(obs)
    np.testing.assert_allclose(
        task.thresholds(seed[:, 0].astype(np.float64)), DEFAULT_THRESHOLDS[weight], rtol=1e-5
    )
    const, _ = make_baseline(env, "constant", c=np.array([2.0, 10.0])).predict(obs)
    np.testing.assert_allclose(task.thresholds(const[:, 0].astype(np.float64)), [2.0, 10.0], rtol=1e-5)


def test_chi_square_switches_to_c_low_while_the_nis_test_fails_then_holds():
    env = gym.make(ENV)
    task = env.unwrapped.core.task
    m = env.unwrapped.core.platform.m_max
    pol = make_baseline(env, "chi_square", alpha=0.01, c_low=2.0, hold=2.0)
    start = np.ones(2, dtype=bool)
    pol.predict(_obs(env, [0.0, 0.0]), episode_start=start)  # the reset observation: plain
    # NIS / n = 3 over m rows fails the 1 % chi-square test; NIS / n = 1 passes it
    big, small = np.log1p(3.0), np.log1p(1.0)
    a, _ = pol.predict(_obs(env, [big, small]))
    c = task.thresholds(a[:, 0].astype(np.float64))
    assert c[0] == pytest.approx(2.0, rel=1e-5) and np.isinf(c[1])
    for _ in range(2):  # held for two more steps
        a, _ = pol.predict(_obs(env, [small, small]))
        assert task.thresholds(a[:1, 0].astype(np.float64))[0] == pytest.approx(2.0, rel=1e-5)
    a, _ = pol.predict(_obs(env, [small, small]))
    assert np.all(np.isinf(task.thresholds(a[:, 0].astype(np.float64))))
    assert m == 36
    with pytest.raises(ValueError, match="alpha"):
        make_baseline(env, "chi_square", alpha=1.5)
