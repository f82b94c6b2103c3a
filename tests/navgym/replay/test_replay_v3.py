"""navgym/ReplayRowScale-v3: the Quadrotor v3 layout, IMU context from the recorded samples."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.recordings.platform import imu_sums
from navgym.scenarios import Jamming, Scenario

ENV_ID = "navgym/ReplayRowScale-v3"


def test_card_and_the_quadrotor_v3_observation_and_action():
    env = gym.make(ENV_ID)
    doc = type(env.unwrapped).__doc__
    assert "Context (v3)" in doc and "* v3:" in doc and "walk_0827" in doc
    quad = gym.make("navgym/QuadrotorRowScale-v3")
    assert env.unwrapped.core.obs_features.names == quad.unwrapped.core.obs_features.names
    assert env.observation_space == quad.observation_space
    assert env.action_space == quad.action_space


def test_imu_statistics_are_the_recorded_samples_over_the_last_second():
    """imu_activity at epoch k: the specific-force spread of the recorded samples of steps k-4..k-1."""
    env = gym.make(ENV_ID)
    env.reset(seed=11, options={"scenario": Scenario(duration=60.0)})  # nothing injected
    core = env.unwrapped.core
    ep, d = core.episodes, core.platform.data
    s0 = int(round(ep.t_start[0] / d.dt))
    k = 40  # epoch 40: the window is steps 36..39 (1 s of 0.25 s steps)
    f = d.samples[s0 + k - 4 : s0 + k, :, 3:].reshape(-1, 3)
    w = d.samples[s0 + k - 4 : s0 + k, :, :3].reshape(-1, 3)
    spread = np.sqrt(((f - f.mean(0)) ** 2).sum(1).mean())
    np.testing.assert_allclose(ep.context.imu_activity[0, k], spread, rtol=1e-9)
    np.testing.assert_allclose(ep.context.f_mean[0, k], f.mean(0), rtol=1e-9)
    np.testing.assert_allclose(ep.context.w_mean[0, k], w.mean(0), rtol=1e-9)
    assert ep.context.imu_activity[0, 0] == 0.0  # nothing before the first step
    # a walk: steps shake the IMU far above a quadrotor's hover (~0.02 m/s^2)
    assert np.median(ep.context.imu_activity[0, 5:]) > 0.3


def test_imu_sums_layout():
    g = np.random.default_rng(0).normal(size=(2, 3, 5, 6))
    s = imu_sums(g)
    np.testing.assert_allclose(s[..., 0:3], g[..., 3:].sum(2))
    np.testing.assert_allclose(s[..., 3], (g[..., 3:] ** 2).sum((2, 3)))
    np.testing.assert_allclose(s[..., 4:7], g[..., :3].sum(2))
    np.testing.assert_allclose(s[..., 7], (g[..., :3] ** 2).sum((2, 3)))


def test_jamming_lowers_the_reported_cn0_and_raises_the_injected_noise():
    env = gym.make(ENV_ID)
    jam = Scenario(duration=60.0, jamming=(Jamming(20.0, 40.0, jam_sigma=2.0, loss_prob=0.0),))
    env.reset(seed=2, options={"scenario": jam})
    ep = env.unwrapped.core.episodes
    t = np.arange(241) * 0.25
    inside, before = (t >= 25.0) & (t < 35.0) & ep.fix[0], (t < 15.0) & ep.fix[0]
    cn0 = ep.context.row_cn0[0, :, 0]
    assert cn0[inside].mean() < cn0[before].mean() - 10.0
    assert ep.true_r[0, inside, 0].mean() > 50 * ep.true_r[0, before, 0].mean()


def test_cn0_offset_shifts_only_the_report():
    e0, e1 = gym.make(ENV_ID), gym.make(ENV_ID, cn0_offset_db=-3.0)
    e0.reset(seed=4)
    e1.reset(seed=4)
    p0, p1 = e0.unwrapped.core.episodes, e1.unwrapped.core.episodes
    np.testing.assert_array_equal(p0.z, p1.z)
    fix = p0.fix[0]
    d = p1.context.row_cn0[0, fix, 0] - p0.context.row_cn0[0, fix, 0]
    assert abs(d.mean() + 3.0) < 0.5
    with pytest.raises(ValueError, match="cn0_offset_db"):
        gym.make(ENV_ID, cn0_offset_db=50.0)
