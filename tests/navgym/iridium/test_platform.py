"""The Iridium platform under the v2 events: truth, fixes and ``StepModels.truth`` (known answers).

Pinned scenarios: an outage or a fully masked segment removes the fixes there and only there; an
impulsive segment with ``eps = 1`` multiplies the fix variance by its ratio; a jamming step adds its
variance; a burst widens the truth's velocity changes by its sigma; the constellation decides (an
89 deg mask leaves no fix); the true noise handed to the evaluation is what the simulator drew;
the clairvoyant filter beats the plain one; the observation carries no truth.
"""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.envs.registration import V2_ENVIRONMENTS
from navgym.iridium.env import IRIDIUM_V2, V2_EVENTS
from navgym.iridium.platform import IridiumPlatform
from navgym.iridium.sensors import IridiumFixNoise, cep_sigma
from navgym.scenarios import ImpulsiveNoise, Jamming, MotionBurst, Outage, Scenario, UrbanCanyon
from tests.navgym.envs.no_truth import assert_truth_not_observed
from tests.navgym.envs.vector_twins import assert_vector_equals_singles

T = 360
DT = 10.0
B = 24
SEEDS = list(range(700, 700 + B))
TIMES = np.arange(T + 1) * DT
CLEAN = IridiumFixNoise(outlier_rate=0.0, gross_rate=0.0)
BASE = Scenario(duration=T * DT, mask_deg=8.2)


def _sim(scenario: Scenario, seeds=SEEDS, **kw):
    p = IridiumPlatform(true_noise=True, **kw)
    return p, p.simulate([np.random.default_rng(s) for s in seeds], [scenario] * len(seeds), T)


def _inside(start: float, end: float) -> np.ndarray:
    return (TIMES >= start - 1e-9) & (TIMES < end - 1e-9)


def _residual_var(ep, sel: np.ndarray) -> float:
    """Per-axis variance of the fix errors at the steps ``sel`` (delivered fixes only)."""
    e = (ep.z - ep.truth_pos)[:, sel][ep.mask[:, sel]]
    return float(np.mean(e**2))


def test_the_constellation_gives_a_fix_every_step_at_its_mask_and_none_at_89_deg():
    _, ep = _sim(BASE, fixes=CLEAN)
    assert ep.mask.all()  # 8.2 deg: continuous coverage
    _, high = _sim(dataclasses.replace(BASE, mask_deg=89.0), fixes=CLEAN)
    assert high.mask[:, 0].all() and high.mask[:, 1:].mean() < 0.01  # the start fix only
    assert np.all(high.fix_age[:, -1] > 0)


def test_an_outage_and_a_fully_masked_segment_remove_the_fixes_there_only():
    pinned = dataclasses.replace(
        BASE,
        outages=(Outage(600.0, 900.0),),
        canyons=(UrbanCanyon(1500.0, 1800.0, max_satellites=0, noise_scale=1.0),),
    )
    _, a = _sim(BASE, fixes=CLEAN)
    _, b = _sim(pinned, fixes=CLEAN)
    gone = _inside(600.0, 900.0) | _inside(1500.0, 1800.0)
    assert not b.mask[:, gone].any() and b.mask[:, ~gone].all()
    np.testing.assert_array_equal(a.truth_pos, b.truth_pos)
    ok = b.mask
    np.testing.assert_array_equal(a.z[ok], b.z[ok])  # nothing else changes
    assert b.fix_age[0, int(900 / DT) - 1] == pytest.approx(300.0)  # the last fix at 590 s


def test_an_impulsive_segment_multiplies_the_fix_variance_by_its_ratio():
    pinned = dataclasses.replace(BASE, impulsive=(ImpulsiveNoise(1000.0, 2500.0, eps=1.0, var_ratio=25.0),))
    _, a = _sim(BASE, fixes=CLEAN)
    _, b = _sim(pinned, fixes=CLEAN)
    inside = _inside(1000.0, 2500.0)
    # the same normals: the errors are exactly 5 times larger inside, equal outside
    d_a, d_b = a.z - a.truth_pos, b.z - b.truth_pos
    np.testing.assert_allclose(d_b[:, inside], 5.0 * d_a[:, inside], rtol=1e-9)
    np.testing.assert_allclose(d_b[:, ~inside], d_a[:, ~inside], rtol=1e-12)
    np.testing.assert_allclose(b.true_r[:, inside], 25.0 * a.true_r[:, inside])


def test_jamming_adds_its_variance_and_the_truth_says_so():
    pinned = dataclasses.replace(BASE, jamming=(Jamming(1000.0, 2000.0, jam_sigma=2000.0),))
    _, a = _sim(BASE, fixes=CLEAN)
    _, b = _sim(pinned, fixes=CLEAN)
    inside = _inside(1000.0, 2000.0)
    np.testing.assert_allclose(b.true_r[:, inside] - a.true_r[:, inside], 2000.0**2)
    # residuals: 2400 errors per axis, the sample variance within 10 % of the drawn one
    assert _residual_var(b, inside) == pytest.approx(float(b.true_r[:, inside].mean()), rel=0.1)


def test_a_burst_widens_the_velocity_changes_of_the_truth_by_its_sigma():
    pinned = dataclasses.replace(BASE, bursts=(MotionBurst(1000.0, 3000.0, velocity_sigma=4.0),))
    p, ep = _sim(pinned, fixes=CLEAN)
    dv = np.diff(ep.truth_vel, axis=1)  # step k -> k + 1
    inside = _inside(1000.0, 3000.0)[:-1]
    nominal = p.accel_psd * DT  # variance of the velocity change per step and axis
    assert np.var(dv[:, inside]) == pytest.approx(nominal + 16.0, rel=0.1)
    assert np.var(dv[:, ~inside]) == pytest.approx(nominal, rel=0.1)
    np.testing.assert_allclose(ep.true_q[:, :-1][:, inside], 16.0 / DT)
    # the true Q handed to the evaluation holds it
    m = p.step_models(ep, np.full(B, 150))
    np.testing.assert_allclose(m.truth.Q[:, 2, 2], (p.accel_psd + 1.6) * DT)
    assert m.transition.Q[0, 2, 2] == pytest.approx(p.accel_psd * DT)


def test_fixes_follow_their_cep_and_the_step_models_truth_is_what_was_drawn():
    p, ep = _sim(BASE)
    m = p.step_models(ep, np.zeros(B, dtype=np.int64))
    np.testing.assert_allclose(m.observation.R[:, 0, 0], cep_sigma(ep.cep[:, 1]) ** 2)
    np.testing.assert_allclose(m.truth.R[:, [0, 1], [0, 1]], ep.true_r[:, 1])
    np.testing.assert_array_equal(m.truth.bias, 0.0)
    # nominal fixes: errors / sigma from the CEP are standard normal (outliers excluded)
    nominal = ep.true_r[..., 0] == cep_sigma(ep.cep) ** 2
    e = ((ep.z - ep.truth_pos) / cep_sigma(np.maximum(ep.cep, 1.0))[..., None])[nominal & ep.mask[..., 0]]
    assert np.var(e) == pytest.approx(1.0, abs=0.05)
    # the source's outliers occur at their rate and are not in the reported CEP
    rate = np.mean(~nominal[:, 1:] & ep.mask[:, 1:, 0])
    assert rate == pytest.approx(p.fixes.outlier_rate + p.fixes.gross_rate, abs=0.01)


def test_the_average_fix_error_is_about_1_km():
    """Benzerrouk 2014, §2.7d: "an average error of 1 km" (nominal fixes, the default mask range)."""
    _, ep = _sim(dataclasses.replace(BASE, mask_deg=11.0), fixes=CLEAN)
    d = ep.z - ep.truth_pos
    assert 800.0 < np.nanmean(np.hypot(d[..., 0], d[..., 1])) < 1200.0


def test_episodes_are_the_same_alone_and_in_a_batch():
    p = IridiumPlatform(true_noise=True)
    scen = [Scenario(duration=T * DT, mask_deg=12.0, bursts=(MotionBurst(400.0, 900.0, 3.0),))] * 3
    batch = p.simulate([np.random.default_rng(s) for s in (1, 2, 3)], scen, T)
    one = p.simulate([np.random.default_rng(2)], scen[1:2], T)
    for a, b in zip(batch, one, strict=True):
        np.testing.assert_array_equal(a[1], b[0])


def test_episode_bytes_estimates_the_peak_of_a_reset():
    import tracemalloc

    T_, B_ = 720, 3
    rngs = [np.random.default_rng(i) for i in range(B_)]
    IRIDIUM_V2.core("noisescale", B_, {"episode_steps": T_}).reset(np.arange(B_), rngs, [None] * B_)
    core = IRIDIUM_V2.core("noisescale", B_, {"episode_steps": T_})
    tracemalloc.start()
    try:
        core.reset(np.arange(B_), rngs, [None] * B_)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak <= B_ * core.platform.episode_bytes(T_) <= 4 * peak


def _rmse(clairvoyant: bool, B_: int = 32) -> float:
    core = IRIDIUM_V2.core("noisescale", B_, {"clairvoyant": clairvoyant})
    rngs = [np.random.default_rng(3000 + i) for i in range(B_)]
    core.reset(np.arange(B_), rngs, [None] * B_)
    act = np.tile(core.task.neutral_action(), (B_, 1))
    err = np.array([core.step(act, rngs)[4]["pos_err_m"] for _ in range(core.T)])
    return float(np.sqrt(np.mean(err**2, axis=0)).mean())


@pytest.mark.slow
def test_the_clairvoyant_filter_clearly_beats_the_plain_one():
    """What v2 is for: knowing the true noise pays (measured 1975 -> 710 m on 64 episodes)."""
    plain, told = _rmse(False), _rmse(True)
    assert told < 0.6 * plain and plain > 1000.0


def test_the_v2_events_are_drawn_and_the_card_says_them():
    env = gym.make("navgym/IridiumMixture-v2")
    env.reset(seed=4)
    s = env.unwrapped.core.scenarios[0]
    assert s.bursts and 8.2 <= s.mask_deg <= 15.0 and not s.multipath
    doc = type(env.unwrapped).__doc__
    assert "v2 episodes" in doc and "eq. 83" in doc and "{" not in doc.replace('{"scenario"', "")
    assert env.unwrapped.core.T == 360 and V2_EVENTS["multipath_probability"] == 0.0


def test_biased_segments_when_switched_on():
    env = gym.make(
        "navgym/IridiumNoiseScale-v2",
        multipath_probability=1.0,
        multipath_rows=(1,),
        multipath_sigma=(0.0, 0.0),
    )
    env.reset(seed=2)
    core = env.unwrapped.core
    ep, s = core.episodes, core.scenarios[0]
    assert s.multipath and all(m.row == 1 for m in s.multipath)
    assert np.all(ep.true_bias[..., 0] == 0.0) and np.abs(ep.true_bias[0, :, 1]).max() >= 1000.0
    with pytest.raises(ValueError, match="multipath_rows"):
        gym.make("navgym/IridiumNoiseScale-v2", multipath_probability=1.0, multipath_rows=(2,))


# ------------------------------------------------------------------------ no truth in the observation
V2_IDS = [e[0] for e in V2_ENVIRONMENTS if e[2] == "Iridium"]


def test_the_iridium_ids_are_registered():
    assert V2_IDS == ["navgym/IridiumMixture-v2", "navgym/IridiumNoiseScale-v2"]


@pytest.mark.parametrize("env_id", V2_IDS)
def test_observation_carries_no_truth(env_id):
    """Perturb every truth-only array of the episodes in a copy: the observation is unchanged."""
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=5)
    core = venv.unwrapped.core
    act = np.tile(core.task.neutral_action(), (3, 1))
    for _ in range(5):
        core.step(act, venv.unwrapped.rngs)

    def perturb(ep):
        assert ep.true_r is not None  # the v2 ids keep the truth
        return ep._replace(
            truth_pos=ep.truth_pos + 4000.0,
            truth_vel=ep.truth_vel + 5.0,
            true_q=ep.true_q + 1.0,
            true_r=ep.true_r * 9.0,
            true_bias=ep.true_bias + 3000.0,
        )

    assert_truth_not_observed(core, venv.unwrapped.rngs, act, perturb)


@pytest.mark.parametrize("env_id", V2_IDS)
def test_vector_sub_env_i_equals_a_single_env_seeded_s_plus_i_through_the_events(env_id):
    assert_vector_equals_singles(env_id, 2, 31, 60)  # 600 s: past the 300 s start margin of the events


def test_the_event_ranges_are_keyword_arguments():
    """A shifted range gives scenarios inside it; a bad one is refused at ``make`` naming it."""
    shifted = {
        "burst_count": (1, 1),
        "burst_duration": (400.0, 410.0),
        "burst_velocity_sigma": (7.0, 8.0),
        "canyon_probability": 1.0,
        "canyon_satellites": (1, 1),
        "jamming_probability": 1.0,
        "jamming_sigma": (100.0, 110.0),
    }
    env = gym.make("navgym/IridiumMixture-v2", **shifted)
    for seed in (1, 2, 3):
        env.reset(seed=seed)
        s = env.unwrapped.core.scenarios[0]
        assert len(s.bursts) <= 1 and all(400.0 - 1e-9 <= b.end - b.start <= 410.0 + 1e-9 for b in s.bursts)
        assert all(7.0 <= b.velocity_sigma <= 8.0 for b in s.bursts)
        assert s.canyons and all(c.max_satellites == 1 for c in s.canyons)
        assert s.jamming and all(100.0 <= j.jam_sigma <= 110.0 for j in s.jamming)
    bad_values = {"burst_duration": (30.0, 10.0), "canyon_probability": 1.5, "jamming_ramp": (-1.0, 2.0)}
    for key, bad in bad_values.items():
        with pytest.raises(ValueError, match=key):
            gym.make("navgym/IridiumNoiseScale-v2", **{key: bad})
    with pytest.raises(ValueError, match="cep_zenith"):
        gym.make("navgym/IridiumNoiseScale-v2", cep_zenith=-1.0)
