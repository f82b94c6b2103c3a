"""Pedestrian v3 context (navgym.pedestrian.context): physics, batching, no truth in it, v2 unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from navgym.gnss.receiver_report import jammer_to_signal_db
from navgym.gnss.signal_quality import effective_cn0_dbhz
from navgym.pedestrian import context as cx
from navgym.pedestrian.env import PEDESTRIAN_V2
from navgym.pedestrian.env_v3 import PEDESTRIAN_V3, PEDESTRIAN_V3_CARD
from navgym.pedestrian.platform import PedestrianPlatform
from navgym.scenarios import Jamming, MotionBurst, Multipath, Scenario, UrbanCanyon, stack_scenarios
from tests.navgym.envs.no_truth import assert_truth_not_observed

T = 180
TT = np.arange(T + 1) * 1.0
SIGMA_POS = 5.0


def _phys(scenarios, cap=12):
    batch = stack_scenarios(scenarios)
    seeds = np.arange(len(scenarios)) + 7
    tt = np.broadcast_to(TT, (len(scenarios), T + 1))
    cap = np.broadcast_to(np.asarray(cap), tt.shape)
    return cx.receiver_physics(seeds, batch, tt, cap, SIGMA_POS)


def _core(task="noisescale", B=3, scenarios=None, seed=11):
    core = PEDESTRIAN_V3.core(task, num_envs=B, kwargs={})
    core.reset(np.arange(B), [np.random.default_rng(seed + i) for i in range(B)], scenarios or [None] * B)
    return core


def _sim(scenarios, seed=0, **kw):
    p = PedestrianPlatform(true_noise=True, context=True, **kw)
    return p, p.simulate([np.random.default_rng(seed + i) for i in range(len(scenarios))], scenarios, T)


def _act(core, B):
    a = core.task.neutral_action()
    return np.tile(a, (B, 1)) if np.ndim(a) else np.full(B, a)


# ------------------------------------------------------------------------------- GNSS physics
def test_jamming_lowers_cn0_and_raises_the_fix_noise():
    quiet = _phys([Scenario(duration=180.0)] * 2)
    jam = _phys([Scenario(duration=180.0, jamming=(Jamming(30.0, 90.0, jam_sigma=30.0),))] * 2)
    inside = (TT >= 40) & (TT < 80)
    assert (jam.cn0_true[:, inside] < quiet.cn0_true[:, inside] - 10.0).all()
    assert (jam.cn0_reported[:, inside] < quiet.cn0_reported[:, inside] - 8.0).all()
    np.testing.assert_array_equal(jam.cn0_true[:, TT < 30], quiet.cn0_true[:, TT < 30])
    assert (jam.uere_factor[:, inside] > 20 * quiet.uere_factor[:, inside]).all()


def test_jamming_reproduces_the_v2_variance_at_the_reference_cn0():
    """J/S of v2's jam_sigma multiplies the SIGMA-epsilon variance at 38 dB-Hz by 1 + (jam / 5 m)^2."""
    jam = np.array([5.0, 30.0])
    js = jammer_to_signal_db(jam, SIGMA_POS, cx.CN0_REF_DBHZ, cx.JAMMER_Q)
    np.testing.assert_allclose(js[1], 40.67, atol=0.01)  # the figure of the docstring and the card
    eff = effective_cn0_dbhz(cx.CN0_REF_DBHZ, js, q=cx.JAMMER_Q)
    np.testing.assert_allclose(10 ** ((cx.CN0_REF_DBHZ - eff) / 10), 1 + (jam / SIGMA_POS) ** 2)


def test_nlos_lowers_cn0_and_los_multipath_keeps_it():
    mp = (Multipath(30.0, 90.0, row=0, bias=20.0),)
    base = _phys([Scenario(duration=180.0)] * 32)
    seg = _phys([Scenario(duration=180.0, multipath=mp)] * 32)
    inside = (TT >= 30) & (TT < 90)
    drop = (base.cn0_true[:, inside] - seg.cn0_true[:, inside]).mean(axis=1)
    np.testing.assert_array_equal(seg.cn0_true[:, TT < 30], base.cn0_true[:, TT < 30])
    assert (drop > 3.0).mean() > 0.5  # NLOS: most segments lose several dB
    assert ((drop < 1.5).mean() > 0.1) and (drop >= 0).all()  # line-of-sight multipath: C/N0 ~ normal


def test_los_multipath_bias_acts_while_row_cn0_stays_normal():
    """In the platform: a segment whose C/N0 stays normal still biases its row (the fix's error)."""
    mp = (Multipath(30.0, 90.0, row=0, bias=20.0),)
    B = 16
    _, ep = _sim([Scenario(duration=180.0, multipath=mp)] * B)
    fix = ep.mask[..., 0]
    inside, before = (TT >= 32) & (TT < 90), (TT > 1) & (TT < 30)
    cn0 = np.where(fix, ep.context.row_cn0[..., 0], np.nan)
    drop = np.nanmean(cn0[:, before], axis=1) - np.nanmean(cn0[:, inside], axis=1)
    los = drop < 1.0
    assert los.any() and (~los).any()
    assert (ep.true_bias[los][:, inside, 0] == 20.0).all()  # the bias acts on the LOS ones too
    assert (ep.context.row_cn0[..., 3:] == 0).all() and (ep.context.row_sigma[..., 3:] == 0).all()


def test_canyon_lowers_n_sv_and_raises_hdop():
    cap = np.where((TT >= 30) & (TT < 90), 5, 12)
    can = _phys([Scenario(duration=180.0)] * 8, cap=cap)
    inside, before = (TT >= 30) & (TT < 90), TT < 30
    assert (can.n_sv[:, inside] <= 5).all() and (can.n_sv[:, before] >= 5).all()
    assert (can.hdop[:, inside].min(axis=1) >= can.hdop[:, before].max(axis=1) - 1e-12).all()


def test_platform_canyon_drops_satellites_and_cn0():
    sc = Scenario(duration=180.0, canyons=(UrbanCanyon(40.0, 100.0, max_satellites=5, noise_scale=4.0),))
    _, ep = _sim([sc] * 4)
    fix = ep.mask[..., 0]
    inside, before = (TT >= 41) & (TT < 100), (TT > 1) & (TT < 39)
    assert (ep.context.n_sv[:, inside] <= 5).all()
    cn0 = np.where(fix, ep.context.row_cn0[..., 0], np.nan)
    assert (np.nanmean(cn0[:, before], axis=1) - np.nanmean(cn0[:, inside], axis=1) > 8.0).all()
    assert (np.nanmean(np.where(fix, ep.true_r[..., 0], np.nan)[:, inside], 1) > 4 * SIGMA_POS**2).all()


def test_fix_noise_follows_hdop_uere_law():
    """Delivered fixes' errors over the simulated sigma (HDOP sigma_nom sqrt(u), plus v2's multipath
    and outliers) have unit variance; that sigma is HDOP^2 u sigma_nom^2 on episodes without events."""
    ep = _core(B=8).episodes
    fix = ep.mask[..., 0]
    d = (ep.z - ep.truth[..., :6] - ep.true_bias)[..., :3]
    r = d[fix] / np.sqrt(ep.true_r[..., :3][fix])
    assert r.size > 2500
    assert abs(np.var(r) - 1.0) < 0.1
    # the law itself, on an episode without events
    sc = Scenario(duration=180.0)
    p, ep0 = _sim([sc], seed=3)
    seeds = np.random.default_rng(3).integers(0, 2**63 - 1, size=4)[None]
    phys = cx.receiver_physics(seeds[:, 2], stack_scenarios([sc]), TT[None], np.full((1, T + 1), 12), 5.0)
    np.testing.assert_allclose(
        ep0.true_r[..., :3], phys.hdop[..., None] ** 2 * phys.uere_factor[..., None] * p.row_sigma[:3] ** 2
    )
    np.testing.assert_array_equal(ep0.true_r[..., 3:], p.sigma_zupt**2)  # the ZUPTs are untouched
    np.testing.assert_array_equal(ep0.context.row_cn0[0, :, 0], phys.cn0_reported[0])


def test_reported_sigma_is_informative_not_perfect():
    """The receiver's accuracy estimate tracks the true fix sigma (blind to multipath) within ~30 %."""
    ep = _core(B=8).episodes
    ok = ep.mask[..., 0] & (ep.true_bias[..., 0] == 0)
    true_sig = np.sqrt(ep.true_r[..., 0])[ok]
    rep = ep.context.row_sigma[..., 0][ok]
    lr = np.log(rep / true_sig)
    assert abs(np.median(lr)) < 0.15 and 0.01 < np.std(lr) < 0.6
    assert np.corrcoef(np.log(rep), np.log(true_sig))[0, 1] > 0.8


def test_scenario_labels_reach_context_only_through_sensors():
    """A multipath segment's bias and row (labels the receiver cannot see) leave the receiver unchanged."""
    a = _phys([Scenario(duration=180.0, multipath=(Multipath(30.0, 90.0, row=1, bias=5.0),))])
    b = _phys([Scenario(duration=180.0, multipath=(Multipath(30.0, 90.0, row=2, bias=-30.0),))])
    for f in a._fields:
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))


# -------------------------------------------------------------------------- foot IMU context
def test_shocks_raise_the_stance_statistic_and_imu_activity():
    sc = Scenario(
        duration=180.0, bursts=(MotionBurst(40.0, 70.0, velocity_sigma=0.05, yaw_rate_sigma=0.002),)
    )
    _, ep = _sim([sc] * 4)
    ctx = ep.context
    # epoch k's window is the end of stride k - 1, which starts at t = k - 1
    inside, outside = (TT >= 41) & (TT <= 70), (TT >= 1) & ((TT < 40) | (TT > 71))
    assert (ctx.stance_statistic[:, inside].min(1) > ctx.stance_statistic[:, outside].max(1) + 1.5).all()
    assert (ctx.imu_activity[:, inside].min(1) > 10 * ctx.imu_activity[:, outside].max(1)).all()
    # the documented figures: a still foot's log10 T about 1-2, |f| spread ~ N_a / sqrt(delta)
    assert 0.5 < np.median(ctx.stance_statistic[:, outside]) < 2.5
    na = PedestrianPlatform().imu.accel_noise * 10.0
    np.testing.assert_allclose(np.median(ctx.imu_activity[:, outside]), na, rtol=0.25)
    np.testing.assert_allclose(np.median(ctx.imu_activity[:, inside]), np.hypot(na, 0.05 * 10.0), rtol=0.2)
    assert (ctx.stance_statistic[:, 0] == 0).all() and (ctx.imu_activity[:, 0] == 0).all()


def test_shoe_statistic_of_a_still_noisy_foot_is_chi_square():
    """Bias-free white noise at the detector's sigmas: T averages 6 - 2/W (two directions fitted)."""
    rng = np.random.default_rng(0)
    B, S, W = 4, 200, 20
    g = np.full(B, 9.8)
    sa, sw = 0.007, 6.6e-4
    f = np.array([0.0, 0.0, -9.8]) + sa * rng.standard_normal((B, S, W, 3))
    w = sw * rng.standard_normal((B, S, W, 3))
    log_t, act = cx.stance_stats(f, w, g, sa, sw)
    np.testing.assert_allclose(np.mean(10**log_t), 6.0 - 2.0 / W, rtol=0.05)
    np.testing.assert_allclose(np.median(act), sa, rtol=0.1)


def test_stance_window_is_the_rest_of_the_foot():
    assert cx.stance_window(100) == 20 and cx.stance_window(2) == 2


# -------------------------------------------------------------------- batching, truth, v2 kept
def test_batch_equals_single_envs():
    B = 3
    batch = _core(B=B)
    for i in range(B):
        single = _core(B=1, seed=11 + i)
        for f in batch.episodes.context._fields:
            np.testing.assert_array_equal(
                getattr(batch.episodes.context, f)[i], getattr(single.episodes.context, f)[0]
            )
        np.testing.assert_array_equal(batch.episodes.z[i], single.episodes.z[0])


def test_context_features_carry_no_truth():
    """Perturb every truth-only field: the observation, context included, is unchanged."""
    B = 3
    core = _core("rowscale", B=B)
    names = core.obs_features.names
    for f in ("row_cn0", "row_reported_sigma", "gnss_n_sv", "gnss_hdop", "gnss_report_age",
              "stance_statistic", "imu_activity"):  # fmt: skip
        assert f in names
    rngs = [np.random.default_rng(50 + i) for i in range(B)]

    def perturb(ep):
        return ep._replace(
            truth=ep.truth + 40.0, true_q=ep.true_q + 1.0, true_r=ep.true_r * 9.0,
            true_bias=ep.true_bias + 30.0,
        )  # fmt: skip

    assert_truth_not_observed(core, rngs, _act(core, B), perturb)


def test_v2_unchanged_and_draws_no_context():
    """v2 has no context; v3 walks the same walks with the same IMU (only the fixes' noise differs)."""
    c2 = PEDESTRIAN_V2.core("noisescale", num_envs=2)
    c2.reset(np.arange(2), [np.random.default_rng(11 + i) for i in range(2)], [None] * 2)
    c3 = _core(B=2)
    assert c2.episodes.context is None and "row_cn0" not in c2.obs_features.names
    for f in ("truth", "dR", "phi", "d6", "J6", "mask", "m0", "true_bias", "true_q"):
        np.testing.assert_array_equal(getattr(c2.episodes, f), getattr(c3.episodes, f))
    assert not np.array_equal(c2.episodes.z[..., :3], c3.episodes.z[..., :3])
    np.testing.assert_array_equal(c2.episodes.z[..., 3:], c3.episodes.z[..., 3:])  # the ZUPTs


def test_process_noise_states_are_position_velocity_and_attitude():
    assert PedestrianPlatform().process_noise_states == tuple(range(9))


def test_the_card_has_the_context_paragraph():
    assert "**Context (v3)**" in PEDESTRIAN_V3_CARD and "stance_statistic" in PEDESTRIAN_V3_CARD


@pytest.mark.parametrize("task", ["rowscale", "fading"])
def test_core_runs_inside_the_observation_space(task):
    if task not in PEDESTRIAN_V3.tasks:
        pytest.skip("rowscale not registered")
    B = 4
    core = PEDESTRIAN_V3.core(task, B, {})
    core.reset(np.arange(B), [np.random.default_rng(i) for i in range(B)], [None] * B)
    space = core.obs_features.space
    act = _act(core, B)
    rngs = [np.random.default_rng(i) for i in range(B)]
    for _ in range(50):
        o, *_ = core.step(act, rngs)
        assert np.isfinite(o).all()
        assert all(space.contains(row.astype(np.float32)) for row in o)
