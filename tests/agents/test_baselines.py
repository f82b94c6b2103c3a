"""Baselines: every baseline on every registered env of its task, formulas vs filters.adaptive."""

from __future__ import annotations

import importlib.util

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401
from agents.baselines import (
    BASELINES,
    ConstantFading,
    EssThreshold,
    SageHusaFading,
    StrongTracking,
    SuboptimalFading,
    baseline_specs,
    baseline_task,
    eps_to_action,
    lambda_to_action,
    make_baseline,
    make_baselines,
    nominal_contamination,
)
from agents.baselines.base import navigation_env
from agents.evaluation.runner import make_vector_env, rollout
from filters.adaptive import FadingTerms, init_fading_memory, strong_tracking_factor, suboptimal_fading_factor
from filters.particle.estimates import ess
from filters.particle.triggers import ess_trigger
from navgym.envs.registration import ENVIRONMENTS

STEPS = 12
B = 3
RTOL = 1e-4  # float32 observations and actions


def _available(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        return False


ENV_CASES = [(env_id, task, module) for env_id, module, _, task, _, _ in ENVIRONMENTS]


def _kwargs(task: str) -> dict:
    kw = {"max_episode_steps": STEPS}
    if task == "resample":
        kw["n_particles"] = 64
    return kw


@pytest.mark.parametrize("env_id,task,module", ENV_CASES, ids=[c[0] for c in ENV_CASES])
def test_every_baseline_runs_on_every_env_of_its_task(env_id, task, module):
    if not _available(module):
        pytest.skip(f"{module} not present yet")
    env = make_vector_env(env_id, B, _kwargs(task))
    pols = make_baselines(env)
    # every baseline of the task whose context features the env's observation has
    assert set(pols) == set(baseline_specs(env))
    assert set(pols) <= set(BASELINES[baseline_task(env)])
    seeds = list(range(1_000_000, 1_000_000 + B))
    for name, pol in pols.items():
        roll = rollout(env, pol, seeds)
        assert roll.length.max() == STEPS, name
        assert np.isfinite(roll.steps["reward"]).all(), name
        obs, _ = env.reset(seed=seeds)
        a, state = pol.predict(obs, episode_start=np.ones(B, dtype=bool))
        assert env.action_space.contains(np.asarray(a, dtype=env.action_space.dtype)), name
    # a single env and a single observation
    single = gym.make(env_id, **_kwargs(task))
    obs, _ = single.reset(seed=1_000_000)
    pol = make_baseline(single, next(iter(baseline_specs(single))))
    for _ in range(3):
        a, _ = pol.predict(obs)
        assert single.action_space.contains(np.asarray(a, dtype=single.action_space.dtype))
        obs, *_ = single.step(a)


def test_plain_constant_reproduces_the_plain_filter():
    env = make_vector_env("navgym/GpsInsFading-v0", 4, {"max_episode_steps": 40})
    seeds = list(range(1_000_100, 1_000_104))
    a = rollout(env, make_baseline(env, "plain"), seeds)

    class Minus1:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return -np.ones((obs.shape[0], 1), dtype=np.float32), None

    b = rollout(env, Minus1(), seeds)
    np.testing.assert_array_equal(a.steps["reward"], b.steps["reward"])
    np.testing.assert_array_equal(a.steps["pos_err_m"], b.steps["pos_err_m"])
    np.testing.assert_array_equal(a.steps["knob"], 1.0)


def _synthetic(rng, K, Bn, m):
    """K steps of full-mask fading terms with SPD M, HQH, R and innovations (B, m)."""
    out = []
    for _ in range(K):
        v = rng.normal(0.0, 3.0, (Bn, m))
        A = rng.normal(size=(3, Bn, m, m))
        M, HQH, R = (a @ np.swapaxes(a, -1, -2) / m + 0.1 * np.eye(m) for a in A)
        out.append(FadingTerms(v, M, 0.3 * HQH, R, np.ones((Bn, m), dtype=bool)))
    return out


def _obs_from_terms(core, terms):
    f = core.observation_features
    Bn = terms.v.shape[0]
    obs = np.zeros((Bn, f.dim), dtype=np.float32)
    tr = {
        "log_tr_vv": (terms.v**2).sum(axis=1),
        "log_tr_R": np.trace(terms.R, axis1=1, axis2=2),
        "log_tr_HQH": np.trace(terms.HQH, axis1=1, axis2=2),
        "log_tr_M": np.trace(terms.M, axis1=1, axis2=2),
    }
    for k, x in tr.items():
        obs[:, f.index(k)] = np.log10(x)[:, None]
    return obs


def _lam(action, lambda_max=10.0):
    return lambda_max ** ((np.asarray(action, dtype=np.float64)[:, 0] + 1.0) / 2.0)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize(
    "cls,params,formula",
    [
        (SuboptimalFading, {"rho": 0.6, "beta": 0.8, "gamma": 1.7}, suboptimal_fading_factor),
        (StrongTracking, {"rho": 0.9, "beta": 1.3}, strong_tracking_factor),
    ],
    ids=["suboptimal", "strong_tracking"],
)
def test_fading_formula_baselines_equal_filters_adaptive(seed, cls, params, formula):
    rng = np.random.default_rng(seed)
    env = gym.make("navgym/GpsInsFading-v0")
    core = navigation_env(env)
    Bn, m, K = 5, 4, 12
    steps = _synthetic(rng, K, Bn, m)
    pol = cls(env, **params)
    reset_obs = np.zeros((Bn, core.observation_features.dim), dtype=np.float32)
    a, state = pol.predict(reset_obs, episode_start=np.ones(Bn, dtype=bool))
    np.testing.assert_allclose(_lam(a), 1.0)  # the reset observation carries no innovation
    mem = init_fading_memory(Bn, m)
    for terms in steps:
        lam_ref, mem = formula(mem, terms, **params)
        a, state = pol.predict(_obs_from_terms(core, terms), state)
        np.testing.assert_allclose(_lam(a), np.minimum(lam_ref, core.task.lambda_max), rtol=RTOL)


def test_sage_husa_fading_matches_its_documented_recursion():
    rng = np.random.default_rng(3)
    env = gym.make("navgym/GpsInsFading-v0")
    core = navigation_env(env)
    Bn, m, K = 4, 3, 10
    b, beta = 0.7, 0.9
    pol = SageHusaFading(env, b=b, beta=beta)
    pol.predict(
        np.zeros((Bn, core.observation_features.dim), dtype=np.float32), episode_start=np.ones(Bn, dtype=bool)
    )
    C = np.zeros(Bn)
    for k, terms in enumerate(_synthetic(rng, K, Bn, m)):
        tr = lambda A: np.trace(A, axis1=1, axis2=2)  # noqa: E731
        d = (1 - b) / (1 - b ** (k + 1))
        C = (1 - d) * C + d * (terms.v**2).sum(axis=1)
        lam_ref = np.clip((C - beta * tr(terms.R) - tr(terms.HQH)) / tr(terms.M), 1.0, core.task.lambda_max)
        a, _ = pol.predict(_obs_from_terms(core, terms))
        np.testing.assert_allclose(_lam(a), lam_ref, rtol=RTOL)


def test_memory_in_state_equals_internal_memory_and_resets():
    rng = np.random.default_rng(5)
    env = gym.make("navgym/GpsInsFading-v0")
    core = navigation_env(env)
    steps = _synthetic(rng, 6, 2, 3)
    p1, p2 = SuboptimalFading(env, rho=0.5), SuboptimalFading(env, rho=0.5)
    state = None
    for t, terms in enumerate(steps):
        obs = _obs_from_terms(core, terms)
        start = np.full(2, t == 0)
        a1, state = p1.predict(obs, state, start)
        a2, _ = p2.predict(obs, None, start)
        np.testing.assert_array_equal(a1, a2)
    # episode_start resets one row's memory: that row acts like a fresh policy
    a, state = p1.predict(obs, state, np.array([True, False]))
    assert (
        a[0, 0] == -1.0 and state["k"][0] == 0 and state["k"][1] == len(steps)
    )  # the first (reset) step is not absorbed


def test_actions_map_back_to_knobs():
    lam = np.array([1.0, 2.0, 10.0, 50.0])
    np.testing.assert_allclose(_lam(lambda_to_action(lam, 10.0)), np.minimum(lam, 10.0), rtol=1e-6)
    eps = np.array([0.0, 0.1, 0.5, 0.9])
    a = eps_to_action(eps, 0.5)
    np.testing.assert_allclose(0.5 * (a[:, 0] + 1) / 2, np.minimum(eps, 0.5), rtol=1e-6)


def test_constant_rejects_lambda_below_one_and_unknown_params():
    env = gym.make("navgym/GpsInsFading-v0")
    with pytest.raises(ValueError):
        ConstantFading(env, lam=0.5)
    with pytest.raises(TypeError):
        ConstantFading(env, rho=0.5)
    with pytest.raises(ValueError):
        make_baseline(gym.make("navgym/GpsInsMixture-v0"), "suboptimal")


def test_nominal_contamination_is_a_configuration_constant():
    env = gym.make("navgym/GpsInsMixture-v0")
    dist = navigation_env(env).platform.scenarios
    assert nominal_contamination(navigation_env(env)) == pytest.approx(np.mean(dist.impulsive_eps))
    pol = make_baseline(env, "nominal")
    obs, _ = env.reset(seed=1_000_000)
    a, _ = pol.predict(obs)
    assert 0.5 * (a[0] + 1) / 2 == pytest.approx(np.mean(dist.impulsive_eps), rel=1e-6)


def test_ess_threshold_equals_filters_ess_trigger():
    rng = np.random.default_rng(2)
    env = gym.make("navgym/GpsInsResample-v0", n_particles=64)
    core = navigation_env(env)
    log_w = rng.normal(0.0, 2.0, (50, 64))
    log_w -= np.log(np.exp(log_w).sum(axis=1, keepdims=True))
    obs = np.zeros((50, core.observation_features.dim), dtype=np.float64)
    obs[:, core.observation_features.index("ess_frac")] = (ess(log_w) / 64)[:, None]
    for thr in (0.1, 0.3, 0.5):
        a, _ = EssThreshold(env, threshold=thr).predict(obs, episode_start=np.zeros(50, dtype=bool))
        np.testing.assert_array_equal(a.astype(bool), ess_trigger(log_w, thr))


def test_mixture_baselines_count_only_the_platforms_outlier_rows():
    """Robot2d's compass is not an outlier row: the innovation baseline reads the GNSS rows only."""
    env = gym.make("navgym/Robot2dMixture-v1")
    assert navigation_env(env).task.outlier_rows == (0, 1, 2, 3)
    assert make_baseline(env, "innovation").outlier_rows == (0, 1, 2, 3)
    quad = gym.make("navgym/QuadrotorMixture-v1")
    assert make_baseline(quad, "innovation").outlier_rows == tuple(range(6))
