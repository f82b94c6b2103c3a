"""Quadrotor v3 context (navgym.quadrotor.context): physics, batching, no truth in it, v2 unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from navgym.quadrotor import context as cx
from navgym.quadrotor.env_v2 import QUADROTOR_V2
from navgym.quadrotor.env_v3 import QUADROTOR_V3
from navgym.quadrotor.flight import quadrotor_imu
from navgym.quadrotor.imu_kernel import N_STATS, preintegrated_imu
from navgym.quadrotor.platform import QuadrotorPlatform
from navgym.scenarios import Jamming, MotionBurst, Multipath, Scenario, UrbanCanyon, stack_scenarios
from tests.navgym.envs.no_truth import assert_truth_not_observed
from tests.navgym.quadrotor.test_imu_kernel import DELTA, DT, N_SUB, _inputs
from tests.navgym.quadrotor.test_imu_kernel import B as KB
from tests.navgym.quadrotor.test_imu_kernel import T as KT

T = 600
TT = np.arange(T + 1) * DT


def _phys(scenarios, cap=12):
    batch = stack_scenarios(scenarios)
    seeds = np.arange(len(scenarios)) + 7
    tt = np.broadcast_to(TT, (len(scenarios), T + 1))
    cap = np.broadcast_to(np.asarray(cap), tt.shape)
    return cx.receiver_physics(seeds, batch, tt, cap, 2.0)


def _core(task="noisescale", B=3, scenarios=None, seed=11):
    core = QUADROTOR_V3.core(task, num_envs=B, kwargs={})
    core.reset(np.arange(B), [np.random.default_rng(seed + i) for i in range(B)], scenarios or [None] * B)
    return core


def _act(core, B):
    a = core.task.neutral_action()
    return np.tile(a, (B, 1)) if np.ndim(a) else np.full(B, a)


# ------------------------------------------------------------------------------- GNSS physics
def test_jamming_lowers_cn0_and_raises_the_fix_noise():
    quiet = _phys([Scenario(duration=60.0)] * 2)
    jam = _phys([Scenario(duration=60.0, jamming=(Jamming(10.0, 40.0, jam_sigma=30.0),))] * 2)
    inside = (TT >= 20) & (TT < 30)
    assert (jam.cn0_true[:, inside] < quiet.cn0_true[:, inside] - 15.0).all()
    assert (jam.cn0_reported[:, inside] < quiet.cn0_reported[:, inside] - 10.0).all()
    np.testing.assert_array_equal(jam.cn0_true[:, TT < 10], quiet.cn0_true[:, TT < 10])
    assert (jam.uere_factor[:, inside] > 50 * quiet.uere_factor[:, inside]).all()


def test_jamming_reproduces_the_v2_variance_at_the_reference_cn0():
    """J/S of v2's jam_sigma multiplies the SIGMA-epsilon variance at 42 dB-Hz by 1 + (jam / 2 m)^2."""
    from navgym.gnss.receiver_report import jammer_to_signal_db
    from navgym.gnss.signal_quality import effective_cn0_dbhz

    js = jammer_to_signal_db(np.array([5.0, 30.0]), 2.0, cx.CN0_REF_DBHZ, cx.JAMMER_Q)
    eff = effective_cn0_dbhz(cx.CN0_REF_DBHZ, js, q=cx.JAMMER_Q)
    np.testing.assert_allclose(10 ** ((cx.CN0_REF_DBHZ - eff) / 10), 1 + (np.array([5.0, 30.0]) / 2) ** 2)


def test_nlos_lowers_cn0_and_los_multipath_keeps_it():
    mp = (Multipath(10.0, 40.0, row=0, bias=20.0),)
    base = _phys([Scenario(duration=60.0)] * 32)
    seg = _phys([Scenario(duration=60.0, multipath=mp)] * 32)
    inside = (TT >= 10) & (TT < 40)
    drop = (base.cn0_true[:, inside] - seg.cn0_true[:, inside]).mean(axis=1)
    np.testing.assert_array_equal(seg.cn0_true[:, TT < 10], base.cn0_true[:, TT < 10])
    assert (drop > 3.0).mean() > 0.5  # NLOS: most segments lose several dB
    assert ((drop < 1.5).mean() > 0.1) and (drop >= 0).all()  # line-of-sight multipath: C/N0 ~ normal


def test_los_multipath_bias_acts_while_row_cn0_stays_normal():
    """In the platform: a segment whose C/N0 stays normal still biases its row (the fix's error)."""
    mp = (Multipath(10.0, 40.0, row=0, bias=20.0),)
    B = 16
    on = _core(B=B, scenarios=[Scenario(duration=60.0, multipath=mp)] * B)
    ep = on.episodes
    inside, before = (TT >= 12) & (TT < 40), (TT > 1) & (TT < 10)
    cn0 = np.where(ep.fix, ep.context.row_cn0[..., 0], np.nan)
    drop = np.nanmean(cn0[:, before], axis=1) - np.nanmean(cn0[:, inside], axis=1)
    los = drop < 1.0
    assert los.any() and (~los).any()
    assert (ep.true_bias[los][:, inside, 0] == 20.0).all()  # the bias acts on the LOS ones too


def test_canyon_lowers_n_sv_and_raises_hdop():
    cap = np.where((TT >= 10) & (TT < 40), 5, 12)
    can = _phys([Scenario(duration=60.0)] * 8, cap=cap)
    inside, before = (TT >= 10) & (TT < 40), TT < 10
    assert (can.n_sv[:, inside] <= 5).all() and (can.n_sv[:, before] >= 5).all()
    assert (can.hdop[:, inside].min(axis=1) >= can.hdop[:, before].max(axis=1) - 1e-12).all()


def test_platform_canyon_drops_satellites_and_cn0():
    sc = Scenario(duration=60.0, canyons=(UrbanCanyon(20.0, 40.0, max_satellites=5, noise_scale=4.0),))
    ep = _core(B=4, scenarios=[sc] * 4).episodes
    inside, before = (TT >= 21) & (TT < 40), (TT > 1) & (TT < 19)
    fix = ep.fix
    assert (ep.context.n_sv[:, inside] <= 5).all()
    cn0 = np.where(fix, ep.context.row_cn0[..., 0], np.nan)
    assert (np.nanmean(cn0[:, before], axis=1) - np.nanmean(cn0[:, inside], axis=1) > 8.0).all()


def test_fix_noise_follows_hdop_uere_law():
    """Delivered fixes' errors over the simulated sigma (HDOP sigma_nom sqrt(u), plus v2's multipath
    and outliers) have unit variance; that sigma is HDOP^2 u sigma_nom^2 on the rows without events."""
    B = 8
    core = _core(B=B)
    ep = core.episodes
    d = ep.z - ep.truth[..., :6] - ep.true_bias
    r = d[ep.fix] / np.sqrt(ep.true_r[ep.fix])
    assert r.size > 15000
    assert abs(np.var(r) - 1.0) < 0.1
    # the law itself, on an episode without events
    p = QuadrotorPlatform(true_noise=True, context=True)
    ep0 = p.simulate([np.random.default_rng(3)], [Scenario(duration=60.0)], T)
    batch = stack_scenarios([Scenario(duration=60.0)])
    seeds = np.random.default_rng(3).integers(0, 2**63 - 1, size=4)[None]
    phys = cx.receiver_physics(seeds[:, 2], batch, TT[None], np.full((1, T + 1), 12), 2.0)
    np.testing.assert_allclose(
        ep0.true_r, phys.hdop[..., None] ** 2 * phys.uere_factor[..., None] * p.row_sigma**2
    )


def test_reported_sigma_is_informative_not_perfect():
    """The receiver's accuracy estimate tracks the true fix sigma (blind to multipath) within ~30 %."""
    B = 8
    ep = _core(B=B).episodes
    no_mp = ep.fix & (ep.true_bias == 0).all(-1)
    true_sig = np.sqrt(ep.true_r[..., 0])[no_mp]
    rep = ep.context.row_sigma[..., 0][no_mp]
    lr = np.log(rep / true_sig)
    assert abs(np.median(lr)) < 0.15 and 0.01 < np.std(lr) < 0.5
    assert np.corrcoef(np.log(rep), np.log(true_sig))[0, 1] > 0.9


def test_scenario_labels_reach_context_only_through_sensors():
    """A multipath segment's bias (a label the receiver cannot see) leaves the receiver unchanged."""
    a = _phys([Scenario(duration=60.0, multipath=(Multipath(10.0, 40.0, row=1, bias=5.0),))])
    b = _phys([Scenario(duration=60.0, multipath=(Multipath(10.0, 40.0, row=2, bias=-30.0),))])
    for f in a._fields:
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))


# -------------------------------------------------------------------------------- IMU context
def test_kernel_stats_are_the_samples_sums_and_change_nothing_else():
    plans, t0, bias, noise, na, ng, omega, gamma = _inputs(1e-3)
    shapes = [(3, 3), (3, 3), (6,), (6, 6)]
    plain = tuple(np.empty((KB, KT) + s) for s in shapes)
    preintegrated_imu(plans, t0, 0, DT, N_SUB, omega, gamma, bias, noise, na, ng, plain)
    out = tuple(np.empty((KB, KT) + s) for s in shapes)
    stats = np.empty((KB, KT, N_STATS))
    preintegrated_imu(plans, t0, 0, DT, N_SUB, omega, gamma, bias, noise, na, ng, out, stats)
    for a, b in zip(plain, out, strict=True):
        np.testing.assert_array_equal(a, b)
    times = t0[:, None, None] + (np.arange(KT) * DT)[None, :, None] + (np.arange(N_SUB) + 0.5) * DELTA
    f_ib, w_ib = quadrotor_imu(plans, times.reshape(KB, -1))
    f = np.stack(f_ib, -1).reshape(KB, KT, N_SUB, 3) + bias[:, :KT, None, :3] + 0.02 * noise[..., :3]
    w = np.stack(w_ib, -1).reshape(KB, KT, N_SUB, 3) + bias[:, :KT, None, 3:] + 1e-3 * noise[..., 3:]
    np.testing.assert_allclose(stats[..., 0:3], f.sum(2), atol=1e-9)
    np.testing.assert_allclose(stats[..., 3], (f * f).sum((2, 3)), rtol=1e-12)
    np.testing.assert_allclose(stats[..., 4:7], w.sum(2), atol=1e-11)
    np.testing.assert_allclose(stats[..., 7], (w * w).sum((2, 3)), rtol=1e-9)


def test_vibration_bursts_raise_imu_activity():
    sc = Scenario(duration=60.0, bursts=(MotionBurst(20.0, 35.0, velocity_sigma=0.05, yaw_rate_sigma=0.001),))
    ctx = _core(B=4, scenarios=[sc] * 4, seed=0).episodes.context
    inside, outside = (TT > 21.1) & (TT < 35), (TT > 2) & (TT < 19)
    assert (ctx.imu_activity[:, inside].min(axis=1) > 10 * ctx.imu_activity[:, outside].max(axis=1)).all()
    # the gyro's: a yaw turn (a manoeuvre) raises it too, so medians
    assert (
        np.median(ctx.gyro_activity[:, inside], 1) > 5 * np.median(ctx.gyro_activity[:, outside], 1)
    ).all()
    # about sqrt(3) s sqrt(f_s) = 1.22 m/s^2 inside (module docstring)
    np.testing.assert_allclose(np.median(ctx.imu_activity[:, inside]), np.sqrt(3 * 200) * 0.05, rtol=0.1)
    assert (ctx.imu_activity[:, 0] == 0).all()
    np.testing.assert_allclose(np.median(ctx.f_mean[:, outside, 2]), -9.81, atol=0.3)


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
    assert "row_cn0" in core.obs_features.names and "imu_activity" in core.obs_features.names
    rngs = [np.random.default_rng(50 + i) for i in range(B)]

    def perturb(ep):
        return ep._replace(
            truth=ep.truth + 40.0, t_start=ep.t_start + 3.0, imu_scale=ep.imu_scale * 3.0,
            true_q=ep.true_q + 1.0, true_r=ep.true_r * 9.0, true_bias=ep.true_bias + 30.0,
        )  # fmt: skip

    assert_truth_not_observed(core, rngs, _act(core, B), perturb)


def test_v2_unchanged_and_draws_no_context():
    """v2 has no context; v3 flies the same flights with the same IMU (only the fixes' noise differs)."""
    c2 = QUADROTOR_V2.core("noisescale", num_envs=2)
    c2.reset(np.arange(2), [np.random.default_rng(11 + i) for i in range(2)], [None] * 2)
    c3 = _core(B=2)
    assert c2.episodes.context is None and "row_cn0" not in c2.obs_features.names
    for f in ("truth", "dR", "phi", "d6", "J6", "fix", "m0", "true_bias", "true_q"):
        np.testing.assert_array_equal(getattr(c2.episodes, f), getattr(c3.episodes, f))
    assert not np.array_equal(c2.episodes.z, c3.episodes.z)


def test_process_noise_states_are_position_and_velocity():
    assert QuadrotorPlatform().process_noise_states == (0, 1, 2, 3, 4, 5)


@pytest.mark.parametrize("task", ["rowscale", "fading"])
def test_core_runs_inside_the_observation_space(task):
    if task not in QUADROTOR_V3.tasks:
        pytest.skip("rowscale not registered")
    B = 4
    core = _core(task, B=B)
    space = core.obs_features.space
    act = _act(core, B)
    rngs = [np.random.default_rng(i) for i in range(B)]
    for _ in range(50):
        o, *_ = core.step(act, rngs)
        assert np.isfinite(o).all()
        assert all(space.contains(row.astype(np.float32)) for row in o)
