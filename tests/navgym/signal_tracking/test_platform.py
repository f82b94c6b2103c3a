"""The SignalTracking platform (Dirac-Gauss DPF n.d., §3-4) and its Jumps task: known answers.

The correlators the task sees are the model's outputs for the replica it asks for; the jump
flags handed to the clairvoyant are the truth's jumps; the knob maps log-linearly and inverts;
batches equal single episodes; the observation carries no truth; the clairvoyant reads the
truth only when asked; a loss of lock terminates with the penalty; the reward adds the weighted
Doppler error.
"""

import copy

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.envs.registration import V2_ENVIRONMENTS
from navgym.envs.tasks import NoTruthError, make_task
from navgym.scenarios import Scenario
from navgym.signal_tracking.env import SIGNAL_TRACKING
from navgym.signal_tracking.models import CHIP_M, G0, LAMBDA_L1, SignalModel, observe
from navgym.signal_tracking.platform import HALF_CHIP_M, SignalTrackingPlatform
from navgym.signal_tracking.task import NOMINAL_JUMP_PROBABILITY, JumpModel, JumpsTask
from tests.navgym.envs.no_truth import assert_truth_not_observed
from tests.navgym.envs.vector_twins import assert_vector_equals_singles

ID = "navgym/SignalTrackingJumps-v2"
T = 20


def _sim(seeds, T=T, **kw):
    p = SignalTrackingPlatform(**kw)
    scen = [Scenario(duration=T * p.dt)] * len(seeds)
    return p, p.simulate([np.random.default_rng(s) for s in seeds], scen, T)


def test_the_correlators_are_the_models_outputs_for_the_replica_asked():
    p, ep = _sim([1, 2, 3])
    t = np.array([0, 5, T - 1])
    models = p.step_models(ep, t)
    prompt = np.array([3.0, -20.0, 100.0])
    rows = np.arange(3)
    for j in (0, p.codes_per_step - 1):
        k = t * p.codes_per_step + j
        want = observe(p.filter_model, ep.x[rows, k], ep.mode[rows, k], prompt, ep.noise[rows, k])
        np.testing.assert_array_equal(models.observation.outputs(j, prompt), want)
    # the prompt of a replica on the true range: A D cos/sin(Phi) (plus noise); half a chip off: A/2
    x = np.array([[2.0, 0.3, 50.0, 0.0, 0.0]] * 2)
    h = p.filter_model.h(x, np.array([0, 20]), np.array([50.0, 50.0 + CHIP_M / 2]))
    assert h[0, 1] == pytest.approx(2.0 * np.cos(0.3)) and h[0, 4] == pytest.approx(2.0 * np.sin(0.3))
    assert h[1, 1] == pytest.approx(-1.0 * np.cos(0.3))  # bit -1, half a chip: half the amplitude
    assert np.all(models.z != models.z) and models.mask.all()  # no precomputed measurement


def test_the_jump_flags_are_the_truths_jumps():
    p, ep = _sim(range(8), T=100)
    da = np.diff(ep.x[..., 4], axis=1)  # da[:, k - 1]: from code period k - 1 to k
    assert ep.jump.shape == ep.mode.shape and ep.jump.sum() > 0 and not ep.jump[:, 0].any()
    assert np.all(np.abs(da[ep.jump[:, 1:]]) > 1.0) and np.all(np.abs(da[~ep.jump[:, 1:]]) < 1.0)
    assert np.abs(da[ep.jump[:, 1:]]).max() <= 10 * G0 + 1.0
    # two per second over 8 s of episodes: about 16 (Poisson)
    assert 4 <= ep.jump.sum() <= 32
    m = p.step_models(ep, np.full(8, 3))
    np.testing.assert_array_equal(m.truth.jump, ep.jump[:, 30:40])


def test_episodes_are_the_same_alone_and_in_a_batch():
    _, batch = _sim([1, 2, 3])
    _, one = _sim([2])
    for a, b in zip(batch, one, strict=True):
        np.testing.assert_array_equal(a[1], b[0])


def test_the_knob_maps_log_linearly_inverts_and_the_plain_filter_is_neutral():
    task = JumpsTask()
    a = np.array([-1.0, -0.5, 0.0, 0.5, 1.0])
    p = task.probabilities(a)
    np.testing.assert_allclose(p[[0, 2, 4]], [1e-5, 10**-3, 0.1])
    np.testing.assert_allclose(task.action_of(p)[:, 0], a, atol=1e-6)
    assert task.probabilities(task.neutral_action()) == pytest.approx(NOMINAL_JUMP_PROBABILITY, rel=1e-6)
    knob, clipped = task.knob(np.array([[2.0], [0.0]], np.float32), 2)
    assert knob[0] == pytest.approx(0.1) and clipped.tolist() == [True, False]
    with pytest.raises(ValueError, match="jump_range"):
        JumpsTask(jump_range=(0.01, 0.1))  # the nominal 2e-3 out of range
    with pytest.raises(ValueError, match="n_particles"):
        make_task("jumps", n_particles=0)


def test_the_jump_model_draws_jumps_at_the_knobs_rate():
    model = JumpModel(SignalModel(SignalTrackingPlatform().signal), np.array([0.0, 0.5, 1.0]))
    jumps = model.sample_jump([np.random.default_rng(i) for i in range(3)], 3, 4000)[..., 4]
    frac = (jumps != 0).mean(axis=1)
    assert frac[0] == 0.0 and abs(frac[1] - 0.5) < 0.03 and frac[2] == 1.0
    assert np.abs(jumps).max() <= 10 * G0 and jumps[2].std() == pytest.approx(20 * G0 / np.sqrt(12), rel=0.05)


def _core(B=3, steps=8, **kw):
    core = SIGNAL_TRACKING.core("jumps", B, {"episode_steps": steps, "n_particles": 16, **kw})
    rngs = [np.random.default_rng(40 + i) for i in range(B)]
    core.reset(np.arange(B), rngs, [None] * B)
    return core, rngs


def test_the_clairvoyant_reads_the_jump_steps_only_when_asked():
    core, rngs = _core(jump_rate=20.0)
    models = core.platform.step_models(core.episodes, core.t)
    told = JumpsTask(n_particles=16, clairvoyant=True)
    plain = JumpsTask(n_particles=16)
    # the clairvoyant: p_hi-capped 1/codes in steps with a jump, p_lo in the others
    step = told.step(core.state, told.knob(np.zeros((3, 1)), 3)[0], models, rngs)
    jumped = models.truth.jump.any(axis=1)
    want = np.where(jumped, 0.1, 1e-5)
    np.testing.assert_allclose(step.diagnostics.jump_probability, want)
    # the agent's task never reads it: the same step without the truth runs and ignores it
    s1 = plain.step(core.state, np.full(3, 2e-3), models._replace(truth=None), [np.random.default_rng(0)] * 3)
    s2 = plain.step(core.state, np.full(3, 2e-3), models, [np.random.default_rng(0)] * 3)
    np.testing.assert_array_equal(s1.state.m, s2.state.m)
    with pytest.raises(NoTruthError):
        told.step(core.state, np.full(3, 2e-3), models._replace(truth=None), rngs)


def test_the_observation_carries_no_truth():
    """Perturb, in a copy, every truth the correlators do not see (their outputs depend on the
    amplitude, phase, range and mode only): the range rate, the acceleration and the jump flags.
    The observations stay equal while the evaluation (the Doppler error) moves."""
    core, rngs = _core(jump_rate=20.0)
    act = np.tile(core.task.neutral_action(), (3, 1))
    twin, twin_rngs = copy.deepcopy((core, rngs))
    x = twin.episodes.x.copy()
    x[..., 3] += 5.0
    x[..., 4] -= 30.0
    twin.episodes = twin.episodes._replace(x=x, jump=~twin.episodes.jump)
    for _ in range(4):
        o1, *_, i1 = core.step(act, rngs)
        o2, *_, i2 = twin.step(act, twin_rngs)
        np.testing.assert_array_equal(o1, o2)
    assert not np.allclose(i1["extra_err"], i2["extra_err"])
    # and the range, which the correlators do see, reaches the evaluation only (shared check)
    core, rngs = _core()

    def perturb(ep):
        return ep._replace(jump=~ep.jump, x=ep.x + np.array([0.0, 0.0, 0.0, 1.0, 0.0]))

    with pytest.raises(AssertionError):  # pos_err_m is the range error: unchanged by v
        assert_truth_not_observed(core, rngs, act, perturb)


def test_loss_of_lock_terminates_with_the_penalty():
    core, rngs = _core(B=2, steps=6)
    core.state = core.state._replace(m=core.state.m + np.array([0.0, 0.0, 400.0, 0.0, 0.0]))
    act = np.tile(core.task.neutral_action(), (2, 1))
    _, r, term, _, info = core.step(act, rngs)
    assert term.all() and np.all(info["pos_err_m"] > HALF_CHIP_M)
    assert set(info["divergence_reason"]) == {"error bound"}
    # the clipped error and divergence_penalty (the registered id adds reward_clip x steps not played)
    np.testing.assert_allclose(r, -10.0 - 100.0, atol=1e-9)
    core, rngs = _core(B=2, steps=6, penalize_remaining_steps=True)
    core.state = core.state._replace(m=core.state.m + np.array([0.0, 0.0, -400.0, 0.0, 0.0]))
    _, r, term, _, info = core.step(act, rngs)
    np.testing.assert_allclose(r, -10.0 - (100.0 + 10.0 * 5), atol=1e-9)


def test_the_reward_adds_the_weighted_doppler_error():
    env = gym.make(ID, doppler_weight=2.0, n_particles=16)
    env.reset(seed=1)
    _, r, *_, info = env.step(env.unwrapped.core.task.neutral_action())
    core = env.unwrapped.core
    k = core.platform.codes_per_step - 1
    dv = abs(float(np.exp(core.state.log_w[0]) @ core.state.m[0, :, 3]) - core.episodes.x[0, k, 3])
    assert float(info["extra_err"]) == pytest.approx(2.0 * dv / LAMBDA_L1)
    dr = abs(float(np.exp(core.state.log_w[0]) @ core.state.m[0, :, 2]) - core.episodes.x[0, k, 2])
    assert float(info["pos_err_m"]) == pytest.approx(dr)
    assert r == pytest.approx(-min((dr + 2.0 * dv / LAMBDA_L1) / 10.0, 10.0))
    with pytest.raises(ValueError, match="codes_per_step"):
        gym.make(ID, codes_per_step=0)


V2_IDS = [e[0] for e in V2_ENVIRONMENTS if e[2] == "SignalTracking"]


def test_the_id_is_registered_with_its_card():
    assert V2_IDS == [ID]
    env = gym.make(ID)
    doc = type(env.unwrapped).__doc__
    assert (
        "Dirac-Gauss DPF n.d." in doc and "Loss of lock" in doc and "{" not in doc.replace('{"scenario"', "")
    )
    core = env.unwrapped.core
    assert core.T == 100 and core.task.n_particles == 128 and core.platform.dt == pytest.approx(0.01)


def test_vector_sub_env_i_equals_a_single_env_seeded_s_plus_i():
    assert_vector_equals_singles(ID, 2, 31, 12, n_particles=8, jump_rate=20.0)
