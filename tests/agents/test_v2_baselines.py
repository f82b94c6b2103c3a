"""Baselines of the v2 tasks: NoiseScale (``*NoiseScale-v2``) and per-row Mixture (``*Mixture-v2``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401
from agents.baselines import (
    BASELINES,
    IaeScale,
    RowChiSquare,
    RowConstant,
    RowInnovationAverage,
    SageHusaScale,
    baseline_specs,
    baseline_task,
    make_baseline,
)
from agents.evaluation.runner import OneEpisodeStepper, make_vector_env
from agents.seeds import seeds

NOISE = "navgym/Robot2dNoiseScale-v2"
MIXTURE = "navgym/Robot2dMixture-v2"


@pytest.fixture(scope="module")
def envs():
    out = {eid: gym.make(eid) for eid in (NOISE, MIXTURE)}
    yield out
    for e in out.values():
        e.close()


def _cases():
    return [(NOISE, n) for n in BASELINES["NoiseScale"]] + [(MIXTURE, n) for n in BASELINES["RowMixture"]]


def _obs(env, B: int, **cols: np.ndarray) -> np.ndarray:
    """``(B, d)`` observations: zeros except the named columns."""
    f = env.unwrapped.observation_features
    obs = np.zeros((B, f.dim))
    for name, v in cols.items():
        obs[:, f.index(name)] = np.asarray(v, dtype=np.float64).reshape(B, -1)
    return obs


def test_specs_list_the_v2_baselines_with_grids(envs):
    assert baseline_task(NOISE) == "NoiseScale"
    assert baseline_task(MIXTURE) == "RowMixture"
    assert baseline_task(envs[MIXTURE]) == "RowMixture"
    ns = baseline_specs(NOISE)
    assert set(ns) == {"plain", "constant", "iae", "sage_husa", "iae_q"}
    rm = baseline_specs(envs[MIXTURE])
    assert set(rm) == {"zero", "constant", "chi_square", "innovation_avg", "huber"}
    for specs in (ns, rm):
        for name, spec in specs.items():
            assert spec.tunable == (name not in ("plain", "zero"))
            for k, vals in spec.grid.items():
                assert k in spec.cls.defaults and len(vals) >= 2
    # v1 Mixture ids keep their single-weight baselines
    assert baseline_specs("Mixture") is BASELINES["Mixture"]


@pytest.mark.parametrize(("env_id", "name"), _cases())
def test_actions_finite_and_in_space(envs, env_id, name):
    env = envs[env_id]
    pol = make_baseline(env, name)
    space = env.action_space
    obs0, _ = env.reset(seed=seeds("eval", 1)[0])
    a, _ = pol.predict(obs0)
    assert a.shape == space.shape and a.dtype == np.float32 and np.isfinite(a).all() and space.contains(a)
    rng = np.random.default_rng(0)
    low, high = env.observation_space.low, env.observation_space.high
    for _ in range(5):
        obs = rng.uniform(low, high, size=(16, low.shape[0]))
        a, _ = pol.predict(obs)
        assert a.shape == (16, *space.shape) and np.isfinite(a).all()
        assert (a >= -1).all() and (a <= 1).all()


@pytest.mark.parametrize(("s_q", "s_r"), [(1.0, 1.0), (0.1, 100.0), (3.0, 0.3), (10.0, 30.0)])
def test_constant_scale_gives_the_asked_scales(envs, s_q, s_r):
    env = envs[NOISE]
    pol = make_baseline(env, "constant", s_q=s_q, s_r=s_r)
    obs, _ = env.reset(seed=seeds("eval", 1)[0])
    a, _ = pol.predict(np.stack([obs, obs]))
    knob, clipped = env.unwrapped.task.knob(a, 2)
    np.testing.assert_allclose(knob, [[s_q, s_r]] * 2, rtol=1e-5)
    assert not np.any(clipped)
    if s_q == s_r == 1.0:  # the neutral action: exactly the plain filter
        np.testing.assert_array_equal(knob, 1.0)
        np.testing.assert_allclose(a[0], env.unwrapped.task.neutral_action(), atol=1e-7)


@pytest.mark.parametrize("cls", [IaeScale, SageHusaScale])
def test_iae_and_sage_husa_are_neutral_on_white_unit_innovations(envs, cls):
    env = envs[NOISE]
    pol = cls(env)
    task = env.unwrapped.task
    B, m = 4, 5
    nu = np.ones((B, m))
    nu[:, ::2] = -1.0  # |nu_i| = 1: mean nu^2 = 1 exactly
    for t in range(40):  # past the window
        a, _ = pol.predict(
            _obs(env, B, innovation=nu, log_r_scale=np.zeros(B)), episode_start=np.full(B, t == 0)
        )
    np.testing.assert_array_equal(task.knob(a, B)[0], 1.0)


def test_iae_estimates_the_r_ratio_and_undoes_the_applied_scale(envs):
    env = envs[NOISE]
    task = env.unwrapped.task
    pol = IaeScale(env, window=10, gain=1.0)
    B = 2
    # true R = 4 R: nu^2 = 4 under s_r = 1; nu^2 = 1 under s_r = 4 (the same R estimate)
    nu = np.stack([np.full(5, 2.0), np.full(5, 1.0)])
    lr = np.log10([1.0, 4.0])
    for t in range(12):
        a, _ = pol.predict(_obs(env, B, innovation=nu, log_r_scale=lr), episode_start=np.full(B, t == 0))
    np.testing.assert_allclose(task.knob(a, B)[0][:, 1], 4.0, rtol=1e-5)
    np.testing.assert_allclose(task.knob(a, B)[0][:, 0], 1.0)
    # gain 0.5: halfway, s_r = 1 + 0.5 (4 - 1)
    pol = IaeScale(env, window=5, gain=0.5)
    for t in range(6):
        a, _ = pol.predict(_obs(env, B, innovation=nu, log_r_scale=lr), episode_start=np.full(B, t == 0))
    np.testing.assert_allclose(task.knob(a, B)[0][:, 1], 2.5, rtol=1e-5)


def test_iae_window_forgets(envs):
    env = envs[NOISE]
    task = env.unwrapped.task
    pol = IaeScale(env, window=np.array([3.0, 30.0]))
    B = 2
    for t in range(10):
        a, _ = pol.predict(_obs(env, B, innovation=np.full((B, 5), 3.0)), episode_start=np.full(B, t == 0))
    for _ in range(3):
        a, _ = pol.predict(_obs(env, B, innovation=np.full((B, 5), 1.0)))
    s_r = task.knob(a, B)[0][:, 1]
    np.testing.assert_allclose(s_r[0], 1.0, rtol=1e-5)  # the 3-step window holds only unit ones
    np.testing.assert_allclose(s_r[1], (9 * 9 + 3 * 1) / 12, rtol=1e-5)  # the reset step is not absorbed


def test_reset_observation_gives_the_plain_filter(envs):
    env = envs[NOISE]
    obs, _ = env.reset(seed=seeds("eval", 1)[0])
    for name in ("iae", "sage_husa", "iae_q"):
        a, _ = make_baseline(env, name).predict(obs)
        np.testing.assert_array_equal(env.unwrapped.task.knob(a[None], 1)[0], 1.0)


def test_row_constant_gives_one_eps_on_the_outlier_rows(envs):
    env = envs[MIXTURE]
    task = env.unwrapped.task
    pol = RowConstant(env, eps=0.2)
    obs, _ = env.reset(seed=seeds("eval", 1)[0])
    a, _ = pol.predict(obs)
    eps, _ = task.knob(a[None], 1)
    np.testing.assert_allclose(eps[0], 0.2 * task.row_weights, rtol=1e-6)


def test_chi_square_flags_exactly_the_10_sigma_row(envs):
    env = envs[MIXTURE]
    task = env.unwrapped.task
    pol = RowChiSquare(env, alpha=0.01, eps_low=0.02)
    z = np.array([[0.5, -0.8, 10.0, 0.3, 0.4], [0.5, -0.8, 0.7, 0.3, 0.4], [10.0, 0, 0, 0, 0]])
    B = z.shape[0]
    prev = np.full((B, 5), 2 * 0.02 / task.eps_max - 1)  # eps_low applied at the step
    obs = _obs(env, B, innovation=z / np.sqrt(1 + 0.02 * (task.variance_ratio - 1)), previous_action=prev)
    a, _ = pol.predict(obs, episode_start=np.zeros(B, bool), state=pol.init_memory(B))
    eps, _ = task.knob(a, B)
    expect = np.array(
        [[0.02, 0.02, 0.5, 0.02, 0.0], [0.02, 0.02, 0.02, 0.02, 0.0], [0.02, 0.02, 0.02, 0.02, 0.0]]
    )
    # the last episode has one row only: one row is always kept (no exclusion), as RAIM does
    np.testing.assert_allclose(eps, expect, rtol=1e-5, atol=1e-7)


def test_chi_square_keeps_flagging_a_row_it_inflated(envs):
    """De-normalization: at eps_max the row's innovation shrinks by sqrt(1 + eps (ratio - 1))."""
    env = envs[MIXTURE]
    task = env.unwrapped.task
    pol = RowChiSquare(env)
    B = 1
    infl = np.sqrt(1 + task.eps_max * (task.variance_ratio - 1))
    z = np.array([[0.5, -0.8, 10.0 / infl, 0.3, 0.4]])
    prev = np.array([[-1.0, -1.0, 1.0, -1.0, -1.0]])
    a, _ = pol.predict(_obs(env, B, innovation=z, previous_action=prev), state=pol.init_memory(B))
    np.testing.assert_allclose(task.knob(a, B)[0][0], [0, 0, task.eps_max, 0, 0], atol=1e-7)


def test_innovation_average_flags_a_biased_row(envs):
    env = envs[MIXTURE]
    task = env.unwrapped.task
    pol = RowInnovationAverage(env, threshold=0.5, gain=100.0)
    avg = np.array([[0.1, -0.2, 2.0, 0.0, 3.0]])  # row 4 is no outlier row: eps 0 there
    a, _ = pol.predict(_obs(env, 1, innovation_avg=avg, previous_action=-np.ones((1, 5))), state={})
    np.testing.assert_allclose(task.knob(a, 1)[0][0], [0, 0, task.eps_max, 0, 0], atol=1e-7)
    pol = RowInnovationAverage(env, threshold=0.5, gain=1.0)
    a, _ = pol.predict(_obs(env, 1, innovation_avg=avg, previous_action=-np.ones((1, 5))), state={})
    np.testing.assert_allclose(task.knob(a, 1)[0][0], [0, 0, task.eps_max, 0, 0], atol=1e-7)
    avg = np.array([[0.1, -0.2, 1.0, 0.0, 0.0]])
    a, _ = pol.predict(_obs(env, 1, innovation_avg=avg, previous_action=-np.ones((1, 5))), state={})
    np.testing.assert_allclose(task.knob(a, 1)[0][0], [0, 0, 0.5 * task.eps_max, 0, 0], rtol=1e-5, atol=1e-7)


def test_row_baselines_refuse_a_single_weight_mixture():
    with pytest.raises(ValueError, match="per-row"):
        RowConstant(gym.make("navgym/Robot2dMixture-v1"))


@pytest.mark.parametrize(("env_id", "name"), _cases())
def test_short_rollout_on_the_v2_id(env_id, name):
    B = 2
    env = make_vector_env(env_id, B, None)
    pol = make_baseline(env, name)
    obs, _ = env.reset(seed=seeds("eval", B))
    stepper = OneEpisodeStepper(env)
    state, start = None, np.ones(B, bool)
    for _ in range(8):
        a, state = pol.predict(obs, state=state, episode_start=start)
        start[:] = False
        assert np.isfinite(a).all() and (np.abs(a) <= 1).all()
        obs, r, term, trunc, info = stepper.step(a)
        assert np.isfinite(r).all()
    env.close()


def test_iae_q_counts_the_satellites_on_gps_ins():
    """GpsIns names its rows-used column ``satellites``: ``iae_q`` reads it there."""
    env = gym.make("navgym/GpsInsNoiseScale-v2")
    pol = make_baseline(env, "iae_q")
    m = env.unwrapped.platform.m_max
    few = _obs(env, 2, satellites=[2 / m, 10 / m], log_nis_avg_1s=[np.log(5.0)] * 2)
    _, state = pol.predict(few, episode_start=np.ones(2, bool))  # the reset observation
    a, _ = pol.predict(few, state=state, episode_start=np.zeros(2, bool))
    assert a[0, 0] > a[1, 0] + 0.1  # Q raised with 2 satellites, not with 10
    env.close()
