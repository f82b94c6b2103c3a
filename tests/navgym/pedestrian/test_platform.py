"""The Pedestrian platform: IMU, ZUPTs, fixes, the v2 events and ``StepModels.truth`` (known answers).

A perfect IMU's preintegrated strides carry the truth from epoch to epoch through the Quadrotor's
strapdown transition; the ZUPT rows are at every epoch with their sigma, the fix rows follow
theirs; an outage removes the fix rows there only; multipath biases its row; a shock burst is in
the true ``Q``; B episodes at once equal B single ones; the plain EKF tracks at the fix noise on
clean episodes; the clairvoyant beats the plain filter; the observation carries no truth.
"""

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.envs.registration import V2_ENVIRONMENTS
from navgym.ins import PERFECT
from navgym.pedestrian.env import PEDESTRIAN_V2, V2_EVENTS
from navgym.pedestrian.platform import PedestrianPlatform
from navgym.quadrotor.platform import vibration_q
from navgym.scenarios import MotionBurst, Multipath, Outage, Scenario
from tests.navgym.envs.no_truth import assert_truth_not_observed
from tests.navgym.envs.vector_twins import assert_vector_equals_singles

T = 60
B = 6
SEEDS = list(range(900, 900 + B))
TIMES = np.arange(T + 1) * 1.0
BASE = Scenario(duration=float(T))


def _sim(scenario: Scenario = BASE, seeds=SEEDS, **kw):
    p = PedestrianPlatform(true_noise=True, **kw)
    return p, p.simulate([np.random.default_rng(s) for s in seeds], [scenario] * len(seeds), T)


def test_a_perfect_imu_carries_the_truth_from_epoch_to_epoch():
    """Preintegration + the Quadrotor's transition reproduce the walk (measured: 1.4 mm, 3 mm/s)."""
    p, ep = _sim(imu=PERFECT)
    worst = np.zeros(9)
    for k in range(T):
        x1 = p.step_models(ep, np.full(B, k)).transition.f(ep.truth[:, k].copy())
        worst = np.maximum(worst, np.abs(x1 - ep.truth[:, k + 1])[:, :9].max(axis=0))
    assert worst[:3].max() < 5e-3 and worst[3:6].max() < 6e-3 and worst[6:].max() < 1e-4
    assert np.linalg.norm(ep.truth[:, -1, :2], axis=-1).max() > 30.0  # the walker did walk


def test_zupt_rows_are_always_there_and_fix_rows_follow_their_sigma():
    p, ep = _sim(seeds=range(40))
    e = ep.z[:, 1:] - ep.truth[:, 1:, :6]
    assert ep.mask[:, 1:].all()
    np.testing.assert_allclose(e[..., :2].std(), p.sigma_pos, rtol=0.05)
    np.testing.assert_allclose(e[..., 3:].std(), p.sigma_zupt, rtol=0.05)
    np.testing.assert_allclose(ep.truth[..., 3:6], 0.0)  # the foot rests at every epoch


def test_an_outage_removes_the_fix_rows_there_only():
    p, ep = _sim(BASE.__class__(duration=float(T), outages=(Outage(20.0, 30.0),)))
    inside = (TIMES >= 20.0) & (TIMES < 30.0)
    assert not ep.mask[:, inside, :3].any() and ep.mask[:, ~inside, :3].all()
    assert ep.mask[..., 3:].all() and np.isnan(ep.z[:, inside, :3]).all()
    m = p.step_models(ep, np.full(B, 22))
    assert not m.mask[:, :3].any() and m.mask[:, 3:].all()


def test_multipath_biases_its_row_and_the_truth_says_so():
    p, ep = _sim(Scenario(duration=float(T), multipath=(Multipath(10.0, 40.0, row=1, bias=25.0),)))
    inside = (TIMES >= 10.0) & (TIMES < 40.0)
    np.testing.assert_allclose(ep.true_bias[:, inside, 1], 25.0)
    assert np.all(ep.true_bias[:, ~inside] == 0.0) and np.all(ep.true_bias[..., [0, 2, 3, 4, 5]] == 0.0)
    e = (ep.z - ep.truth[..., :6])[:, inside, 1]
    assert abs(e.mean() - 25.0) < 1.0
    m = p.step_models(ep, np.full(B, 14))
    np.testing.assert_allclose(m.truth.bias[:, 1], 25.0)
    np.testing.assert_allclose(np.diagonal(m.truth.R, axis1=1, axis2=2), np.tile(p.row_sigma**2, (B, 1)))


def test_a_shock_burst_is_in_the_true_process_noise_and_in_the_imu():
    burst = Scenario(
        duration=float(T), bursts=(MotionBurst(10.0, 20.0, velocity_sigma=0.1, yaw_rate_sigma=0.004),)
    )
    p, ep = _sim(burst)
    _, clean = _sim()
    m_in = p.step_models(ep, np.full(B, 12))
    extra = 0.1**2 * vibration_q(1.0, p.n_sub) + np.diag([0] * 6 + [0.004**2] * 3 + [0] * 6)
    np.testing.assert_allclose(m_in.truth.Q - p.Q, np.broadcast_to(extra, (B, 15, 15)), atol=1e-15)
    np.testing.assert_allclose(p.step_models(ep, np.full(B, 30)).truth.Q, np.broadcast_to(p.Q, (B, 15, 15)))
    # the IMU itself is noisier inside the burst (same draws otherwise)
    d_in = np.abs(ep.d6[:, 10:20, :3] - clean.d6[:, 10:20, :3]).mean()
    assert d_in > 0.03 and np.array_equal(ep.d6[:, 30:], clean.d6[:, 30:])


def test_episodes_are_the_same_alone_and_in_a_batch():
    p = PedestrianPlatform(true_noise=True)
    scen = [Scenario(duration=float(T), bursts=(MotionBurst(5.0, 15.0, 0.05),))] * 3
    batch = p.simulate([np.random.default_rng(s) for s in (1, 2, 3)], scen, T)
    one = p.simulate([np.random.default_rng(2)], scen[1:2], T)
    assert batch.context is None and one.context is None  # v0-v2: no context
    for a, b in zip(batch, one, strict=True):
        if a is not None:
            np.testing.assert_array_equal(a[1], b[0])


def _rmse(task: str, clairvoyant: bool, B_: int = 16, **kw) -> float:
    core = PEDESTRIAN_V2.core(task, B_, {"clairvoyant": clairvoyant, **kw})
    rngs = [np.random.default_rng(3000 + i) for i in range(B_)]
    core.reset(np.arange(B_), rngs, [None] * B_)
    act = np.tile(core.task.neutral_action(), (B_, 1))
    err = np.array([core.step(act, rngs)[4]["pos_err_m"] for _ in range(core.T)])
    return float(np.sqrt(np.mean(err**2, axis=0)).mean())


def test_the_plain_ekf_tracks_at_the_fix_noise_on_clean_episodes():
    """No events: the filter's model is right, the error is below the fix's 5 m per axis."""
    off = {k: 0.0 for k in V2_EVENTS if k.endswith("_probability")}
    rmse = _rmse("noisescale", False, B_=8, episode_steps=120, **off)
    assert rmse < 3.0


@pytest.mark.slow
def test_the_clairvoyant_filter_clearly_beats_the_plain_one():
    """What v2 is for: knowing the true noise pays."""
    plain, told = _rmse("noisescale", False), _rmse("noisescale", True)
    assert told < 0.6 * plain


def test_the_v2_events_are_drawn_and_the_card_says_them():
    env = gym.make("navgym/PedestrianFading-v2")
    env.reset(seed=4)
    assert env.unwrapped.core.T == 180
    doc = type(env.unwrapped).__doc__
    assert "v2 episodes" in doc and "§2.7c" in doc and "zero-velocity" in doc
    assert "{" not in doc.replace('{"scenario"', "")
    kinds = set()
    for seed in range(8):
        env.reset(seed=seed)
        s = env.unwrapped.core.scenarios[0]
        kinds |= {
            k for k in ("outages", "impulsive", "jamming", "bursts", "multipath", "canyons") if getattr(s, k)
        }
        assert all(m.row in (0, 1, 2) for m in s.multipath)
    assert kinds == {"outages", "impulsive", "jamming", "bursts", "multipath", "canyons"}
    with pytest.raises(ValueError, match="multipath_rows"):
        gym.make("navgym/PedestrianNoiseScale-v2", multipath_rows=(3,))


# ------------------------------------------------------------------------ no truth in the observation
V2_IDS = [e[0] for e in V2_ENVIRONMENTS if e[2] == "Pedestrian"]


def test_the_pedestrian_ids_are_registered():
    assert V2_IDS == [
        "navgym/PedestrianFading-v2",
        "navgym/PedestrianNoiseScale-v2",
        "navgym/PedestrianMixture-v2",
    ]


@pytest.mark.parametrize("env_id", V2_IDS)
def test_observation_carries_no_truth(env_id):
    """Perturb every truth-only array of the episodes in a copy: the observation is unchanged."""
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=5)
    core = venv.unwrapped.core
    act = np.tile(core.task.neutral_action(), (3, 1))
    for _ in range(25):  # past the events' start margin
        core.step(act, venv.unwrapped.rngs)

    def perturb(ep):
        assert ep.true_r is not None  # the v2 ids keep the truth
        truth = ep.truth.copy()
        truth[..., :6] += 3.0
        truth[..., 6:9] += 0.1
        truth[..., 9:] += 1e-3
        return ep._replace(
            truth=truth, true_q=ep.true_q + 1.0, true_r=ep.true_r * 9.0, true_bias=ep.true_bias + 30.0
        )

    assert_truth_not_observed(core, venv.unwrapped.rngs, act, perturb)


@pytest.mark.parametrize("env_id", V2_IDS)
def test_vector_sub_env_i_equals_a_single_env_seeded_s_plus_i_through_the_events(env_id):
    assert_vector_equals_singles(env_id, 2, 31, 60)


def test_the_event_ranges_and_own_arguments_are_keyword_arguments():
    """A shifted range gives scenarios inside it; a bad one is refused at ``make`` naming it."""
    env = gym.make(
        "navgym/PedestrianMixture-v2", burst_count=(1, 1), burst_duration=(30.0, 31.0), imu_rate_hz=50
    )
    assert env.unwrapped.core.platform.n_sub == 50
    for seed in (1, 2, 3):
        env.reset(seed=seed)
        s = env.unwrapped.core.scenarios[0]
        assert len(s.bursts) <= 1 and all(30.0 - 1e-9 <= b.end - b.start <= 31.0 + 1e-9 for b in s.bursts)
    for key, bad in {"burst_duration": (30.0, 10.0), "sigma_zupt": 0.0, "imu_rate_hz": 1}.items():
        with pytest.raises((ValueError, TypeError), match=key):
            gym.make("navgym/PedestrianNoiseScale-v2", **{key: bad})
