"""The Jpa platform (Belles et al. 2022, §5) and its Robust task: known answers.

The DDs carry exactly the filter's covariance; cycle slips bias only the base-master phase DDs
of their satellites by whole cycles and multipath only the base-master code DDs; the true noise
handed to the evaluation is what the simulator used; the plain iterated ESKF is consistent on
episodes without events; ``c = inf`` is the plain iterated EKF; the clairvoyant beats the plain
and the seed's robust filter; the observation carries no truth; batches equal single episodes.
"""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from filters import GaussianState, kalman
from navgym.envs.registration import V2_ENVIRONMENTS
from navgym.envs.tasks import RobustTask
from navgym.jpa.env import JPA
from navgym.jpa.models import WAVELENGTH_L1, dd_values
from navgym.jpa.platform import JpaPlatform
from navgym.scenarios import Scenario
from tests.navgym.envs.no_truth import assert_truth_not_observed
from tests.navgym.envs.vector_twins import assert_vector_equals_singles

T = 60
QUIET = Scenario(duration=T * 1.0)


def _sim(seeds, scenario=QUIET, **kw):
    p = JpaPlatform(**kw)
    return p, p.simulate([np.random.default_rng(s) for s in seeds], [scenario] * len(seeds), T)


def _clean(p, ep):
    B = ep.z.shape[0]
    return dd_values(
        ep.truth_R.reshape(-1, 3, 3),
        ep.truth_p.reshape(-1, 3),
        np.repeat(ep.truth_a, T + 1, axis=0),
        ep.U.reshape(-1, p.config.n_dd, 3),
        np.asarray(p.config.baselines).T,
    ).reshape(B, T + 1, -1)


def test_the_dd_noise_has_the_filters_covariance():
    p, ep = _sim(range(40), slip_probability=0.0)
    e = (ep.z - _clean(p, ep))[:, 1:]  # (B, T, m)
    models = [p.step_models(ep, np.full(40, k)) for k in (0, T // 2, T - 2)]
    R = np.mean([np.asarray(mo.observation.R) for mo in models], axis=(0, 1))
    w = np.linalg.inv(np.linalg.cholesky(R))  # whitened with the filter's R: unit covariance
    ew = e.reshape(-1, e.shape[-1]) @ w.T
    cov = np.cov(ew.T)
    assert np.abs(np.diag(cov) - 1.0).max() < 0.12  # 2400 samples: sd of a variance ~0.03
    assert np.abs(cov - np.diag(np.diag(cov))).max() < 0.12


def test_cycle_slips_bias_the_base_master_phase_dds_by_whole_cycles_only():
    p, ep = _sim(range(12), slip_probability=1.0)
    n = p.config.n_dd
    assert np.all(ep.true_bias[..., n:] == 0.0) and np.all(ep.true_var == 0.0)
    cycles = ep.true_bias[..., :n] / WAVELENGTH_L1
    np.testing.assert_allclose(cycles, np.round(cycles), atol=1e-9)
    assert np.abs(cycles).max() <= 2 * p.slip_max_cycles  # two zones may overlap
    assert ep.slipped.any(axis=1).all() and np.all(ep.true_bias[~ep.slipped] == 0.0)
    residual = ep.z - _clean(p, ep) - ep.true_bias
    assert np.abs(residual[..., :n]).max() < 0.2  # phase DD noise: millimetres, no slip left
    _, quiet = _sim(range(12), slip_probability=0.0)
    assert np.all(quiet.true_bias == 0.0) and not quiet.slipped.any()


def test_multipath_biases_the_base_master_code_dds_and_the_truth_says_so():
    env = gym.make("navgym/JpaRobust-v2", slip_probability=0.0, multipath_probability=1.0)
    env.reset(seed=3)
    core = env.unwrapped.core
    ep, s, n = core.episodes, core.scenarios[0], core.platform.config.n_dd
    assert s.multipath
    code = ep.true_bias[0, :, n : 2 * n]
    assert np.abs(code).max() >= 1.0 and np.all(ep.true_bias[0, :, :n] == 0.0)
    assert np.all(ep.true_bias[0, :, 2 * n :] == 0.0)
    m = core.platform.step_models(ep, np.array([int(np.argmax(np.abs(code).max(axis=1))) - 1]))
    np.testing.assert_array_equal(
        m.truth.bias, ep.true_bias[0, int(np.argmax(np.abs(code).max(axis=1)))][None]
    )
    extra = np.diagonal(m.truth.R - np.asarray(m.observation.R), axis1=1, axis2=2)
    assert np.all(extra[:, :n] == 0.0) and np.all(extra[:, 2 * n :] == 0.0)
    with pytest.raises(ValueError, match="multipath_rows"):
        gym.make("navgym/JpaRobust-v2", multipath_probability=1.0, multipath_rows=(9,))


def test_episodes_are_the_same_alone_and_in_a_batch():
    p = JpaPlatform()
    batch = p.simulate([np.random.default_rng(s) for s in (1, 2, 3)], [QUIET] * 3, T)
    one = p.simulate([np.random.default_rng(2)], [QUIET], T)
    for a, b in zip(batch, one, strict=True):
        np.testing.assert_array_equal(a[1] if a.ndim else a, b[0] if b.ndim else b)


def _run(kwargs, B=16, steps=T, seed0=900, action=None):
    core = JPA.core("robust", B, {"episode_steps": steps, **kwargs})
    rngs = [np.random.default_rng(seed0 + i) for i in range(B)]
    core.reset(np.arange(B), rngs, [None] * B)
    act = np.tile(core.task.neutral_action() if action is None else action, (B, 1))
    infos = [core.step(act, rngs)[4] for _ in range(steps)]
    return core, infos


def test_the_plain_iterated_eskf_is_consistent_without_events():
    """NEES of the 30 error states about 30 (2.6-3.9 per 3 states measured): the model, the
    simulation and the manifold filter agree."""
    _, infos = _run({"slip_probability": 0.0, "multipath_probability": 0.0}, B=24)
    nees = np.array([i["nees"] for i in infos[10:]])
    assert 0.6 * 30 < np.mean(nees) < 1.6 * 30
    pos = np.array([i["pos_err_m"] for i in infos])
    assert np.sqrt(np.mean(pos**2)) < 0.1


def test_c_inf_is_the_plain_iterated_update_and_the_action_map_inverts():
    task = RobustTask()
    a = np.array([-1.0, -0.3, 0.0, 0.7, 1.0])
    c = task.thresholds(a)
    assert c[0] == pytest.approx(0.5) and np.isinf(c[-1]) and np.all(np.diff(c) > 0)
    np.testing.assert_allclose(task.action_of(c)[:, 0], a, atol=1e-6)
    np.testing.assert_array_equal(task.thresholds(task.neutral_action()), [np.inf])
    core = JPA.core("robust", 4, {"episode_steps": 5})
    rngs = [np.random.default_rng(i) for i in range(4)]
    core.reset(np.arange(4), rngs, [None] * 4)
    models = core.platform.step_models(core.episodes, np.zeros(4, dtype=int))
    step = task.step(core.state, np.full(4, np.inf), models, rngs)
    pred = kalman.predict(core.state, models.transition, None, 1.0)
    obs = models.observation
    post, _ = kalman.iterated_update(
        GaussianState(np.zeros_like(pred.m), pred.P), models.z, obs.error_state(pred.m), max_iter=3, tol=1e-6
    )
    m, P = obs.inject(pred.m, post.m, post.P)
    np.testing.assert_allclose(step.state.m, m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(step.state.P, P, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="threshold_range"):
        RobustTask(threshold_range=(2.0, 1.0))
    with pytest.raises(ValueError, match="weight"):
        RobustTask(weight="cauchy")


@pytest.mark.slow
def test_the_clairvoyant_beats_the_plain_and_the_seed_filters():
    """Measured on 32 episodes of 120 s: plain 0.15 m, Huber 1.345 0.13 m, clairvoyant 0.013 m."""

    def rmse(kw, action=None):
        _, infos = _run(kw, B=32, steps=120, seed0=5000, action=action)
        e = np.array([i["pos_err_m"] for i in infos])
        return float(np.sqrt(np.mean(e**2, axis=0)).mean())

    plain, told = rmse({}), rmse({"clairvoyant": True})
    seed = rmse({}, RobustTask().action_of(1.345)[0])
    assert told < 0.3 * seed and seed < plain


# ------------------------------------------------------------------------ no truth in the observation
V2_IDS = [e[0] for e in V2_ENVIRONMENTS if e[2] == "Jpa"]


def test_the_jpa_id_is_registered_with_its_card():
    assert V2_IDS == ["navgym/JpaRobust-v2"]
    env = gym.make(V2_IDS[0])
    doc = type(env.unwrapped).__doc__
    assert "cycle slips" in doc and "Belles et al. 2022" in doc and "{" not in doc.replace('{"scenario"', "")
    assert env.unwrapped.core.T == 120 and env.unwrapped.core.task.weight == "huber"


@pytest.mark.parametrize("env_id", V2_IDS)
def test_observation_carries_no_truth(env_id):
    """Perturb every truth-only array of the episodes in a copy: the observation is unchanged."""
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", slip_probability=1.0)
    venv.reset(seed=5)
    core = venv.unwrapped.core
    act = np.tile(core.task.action_of(1.345)[0], (3, 1))
    for _ in range(5):
        core.step(act, venv.unwrapped.rngs)

    def perturb(ep):
        return ep._replace(
            truth_p=ep.truth_p + 30.0,
            truth_v=ep.truth_v + 5.0,
            truth_R=np.swapaxes(ep.truth_R, -1, -2),
            truth_b=ep.truth_b + 1e-3,
            truth_a=ep.truth_a + 3.0,
            true_bias=ep.true_bias + 10.0,
            true_var=ep.true_var + 4.0,
            slipped=~ep.slipped,
        )

    assert_truth_not_observed(core, venv.unwrapped.rngs, act, perturb)


@pytest.mark.parametrize("env_id", V2_IDS)
def test_vector_sub_env_i_equals_a_single_env_seeded_s_plus_i_through_the_events(env_id):
    kw = {"slip_probability": 1.0, "multipath_probability": 1.0}
    assert_vector_equals_singles(env_id, 2, 31, 40, **kw)


def test_the_reward_adds_the_weighted_attitude_error():
    env = gym.make("navgym/JpaRobust-v2", attitude_weight=2.0)
    env.reset(seed=1)
    _, r, *_, info = env.step(env.unwrapped.core.task.neutral_action())
    core = env.unwrapped.core
    att = core.platform.attitude_error_deg(core.state.m, core.episodes, core.t)
    assert float(info["extra_err"]) == pytest.approx(2.0 * att[0])
    assert r == pytest.approx(-(float(info["pos_err_m"]) + 2.0 * att[0]))
    with pytest.raises(ValueError, match="slip_max_cycles"):
        gym.make("navgym/JpaRobust-v2", slip_max_cycles=0)
    assert dataclasses.replace(core.platform, slip_probability=0.5).slip_probability == 0.5
