"""Robot2d v3 context (navgym.robot2d.context): physics, batching and no truth in it."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from navgym.robot2d import context as cx
from navgym.robot2d.env_v3 import ROBOT2D_V3
from navgym.scenarios import Jamming, MotionBurst, Multipath, Scenario, UrbanCanyon, stack_scenarios

T = 600
DT = 0.1
TT = np.arange(T + 1) * DT


def _phys(scenarios, seeds=None):
    batch = stack_scenarios(scenarios)
    seeds = np.arange(len(scenarios)) + 7 if seeds is None else seeds
    tt = np.broadcast_to(TT, (len(scenarios), T + 1))
    return cx.receiver_physics(seeds, batch, tt, (3.0, 5.0)), tt


def _core(task="noisescale", B=3, kwargs=None):
    core = ROBOT2D_V3.core(task, num_envs=B, kwargs=kwargs or {})
    core.reset(np.arange(B), [np.random.default_rng(11 + i) for i in range(B)], [None] * B)
    return core


def _act(core, B):
    a = core.task.neutral_action()
    return np.tile(a, (B, 1)) if np.ndim(a) else np.full(B, a)


def test_jamming_lowers_cn0_of_both_receivers():
    quiet, _ = _phys([Scenario(duration=60.0)] * 2)
    jam, _ = _phys([Scenario(duration=60.0, jamming=(Jamming(10.0, 40.0, jam_sigma=30.0),))] * 2)
    inside = (TT >= 20) & (TT < 30)
    assert (jam.cn0_true[:, inside] < quiet.cn0_true[:, inside] - 10.0).all()  # both receivers, all epochs
    np.testing.assert_array_equal(jam.cn0_true[:, TT < 10], quiet.cn0_true[:, TT < 10])
    assert (jam.fix_var[:, inside] > 10 * quiet.fix_var[:, inside]).all()


def test_nlos_segment_lowers_cn0_of_its_receiver_only():
    mp = [Multipath(10.0, 40.0, row=0, bias=20.0)]
    base, _ = _phys([Scenario(duration=60.0)] * 32)
    seg, _ = _phys([Scenario(duration=60.0, multipath=tuple(mp))] * 32)
    inside = (TT >= 10) & (TT < 40)
    drop = (base.cn0_true[:, inside, 0] - seg.cn0_true[:, inside, 0]).mean(axis=1)
    np.testing.assert_array_equal(seg.cn0_true[..., 1], base.cn0_true[..., 1])  # GLONASS untouched
    assert (drop > 3.0).mean() > 0.5  # NLOS: most segments lose several dB
    assert (drop < 1.5).any()  # line-of-sight multipath: some keep C/N0 nearly normal


def test_canyon_lowers_n_sv_and_raises_hdop():
    can, _ = _phys([Scenario(duration=60.0, canyons=(UrbanCanyon(10.0, 40.0, max_satellites=5),))] * 8)
    inside, before = (TT >= 10) & (TT < 40), TT < 10
    assert (can.n_sv[:, inside] <= 5).all() and (can.n_sv[:, before] >= 5).all()
    assert (can.hdop[:, inside].min(axis=1) >= can.hdop[:, before].max(axis=1) - 1e-12).all()


def test_fix_noise_follows_hdop_uere_law():
    """Delivered fixes' errors divided by the simulated sigma (HDOP sigma_UERE, plus v2's multipath
    noise) have unit variance over ~1.4e4 samples: within 10 % (the sampling error is ~1.2 %)."""
    core = _core(B=8)
    ep = core.episodes
    d = ep.z[..., :4] - ep.truth_pos[..., [0, 1, 0, 1]] - ep.true_bias[..., :4]
    r = (d / np.sqrt(ep.true_r[..., :4]))[ep.mask[..., :4]]
    assert r.size > 5000
    assert abs(np.var(r) - 1.0) < 0.1


def test_fix_variance_is_hdop_squared_uere_squared():
    phys, _ = _phys([Scenario(duration=60.0)])
    ci = np.array([3.0, 5.0]) ** 2 * 10 ** (cx.CN0_REF_DBHZ / 10)
    # with every satellite at C/N0_ref and HDOP 1, the nominal sigma (the scaling)
    np.testing.assert_allclose(
        cx.hdop(np.array(4.0), 1.0) ** 2 * ci * 10 ** (-cx.CN0_REF_DBHZ / 10), [9.0, 25.0]
    )
    assert np.all(phys.fix_var >= phys.hdop**2 * ci * 10 ** (-phys.cn0_true.max() / 10) * 0.999)


def test_gyro_discrepancy_rises_in_slip_bursts():
    sc = Scenario(duration=60.0, bursts=(MotionBurst(20.0, 35.0, velocity_sigma=1.0, yaw_rate_sigma=0.2),))
    core = ROBOT2D_V3.core("noisescale", num_envs=4)
    core.reset(np.arange(4), [np.random.default_rng(i) for i in range(4)], [sc] * 4)
    imu = core.episodes.context.imu_activity
    inside, outside = (TT > 22) & (TT < 35), (TT > 2) & (TT < 19)
    assert (np.median(imu[:, inside], axis=1) > 3 * np.median(imu[:, outside], axis=1)).all()


def test_batch_equals_single_envs():
    B = 3
    batch = _core(B=B)
    for i in range(B):
        single = ROBOT2D_V3.core("noisescale", num_envs=1)
        single.reset(np.arange(1), [np.random.default_rng(11 + i)], [None])
        for f in batch.episodes.context._fields:
            np.testing.assert_array_equal(
                getattr(batch.episodes.context, f)[i], getattr(single.episodes.context, f)[0]
            )


def test_context_features_carry_no_truth():
    """Perturb every truth-only field: the observation (with the context) is unchanged."""
    B = 3
    core = _core(B=B)
    rngs = [np.random.default_rng(50 + i) for i in range(B)]
    act = _act(core, B)
    twin, twin_rngs = copy.deepcopy((core, rngs))
    ep = twin.episodes
    twin.episodes = ep._replace(
        truth_pos=ep.truth_pos + 40.0, truth_heading=ep.truth_heading + 0.5, truth_scale=ep.truth_scale + 0.1,
        true_q=ep.true_q + 1.0, true_r=ep.true_r * 9.0, true_bias=ep.true_bias + 30.0,
    )  # fmt: skip
    for _ in range(4):
        o1, *_ = core.step(act, rngs)
        o2, *_ = twin.step(act, twin_rngs)
        np.testing.assert_array_equal(o1, o2)


def test_scenario_labels_reach_context_only_through_sensors():
    """A multipath segment's bias (a label the receiver cannot see) leaves the context unchanged."""
    a = Scenario(duration=60.0, multipath=(Multipath(10.0, 40.0, row=1, bias=5.0),))
    b = Scenario(duration=60.0, multipath=(Multipath(10.0, 40.0, row=1, bias=-30.0),))
    pa, _ = _phys([a])
    pb, _ = _phys([b])
    for f in pa._fields:
        np.testing.assert_array_equal(getattr(pa, f), getattr(pb, f))


def test_context_off_draws_nothing():
    from navgym.robot2d.env_v2 import ROBOT2D_V2

    c2 = ROBOT2D_V2.core("noisescale", num_envs=2)
    c2.reset(np.arange(2), [np.random.default_rng(i) for i in range(2)], [None] * 2)
    assert c2.episodes.context is None
    assert "row_cn0" not in c2.obs_features.names


@pytest.mark.parametrize("task", ["rowscale", "fading"])
def test_core_builds(task):
    if task not in ROBOT2D_V3.tasks:
        pytest.skip("rowscale not registered")
    core = _core(task, B=2)
    o, *_ = core.step(_act(core, 2), [np.random.default_rng(i) for i in range(2)])
    assert np.isfinite(o).all() and "row_cn0" in core.obs_features.names
