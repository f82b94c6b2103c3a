"""GpsIns v3 context (navgym.gps_ins.context, GpsInsPlatform(context=True)): physics, batching, no truth."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from navgym.gnss import signal_quality as sq
from navgym.gps_ins import context
from navgym.gps_ins import context as ctx
from navgym.gps_ins.env_v2 import GPS_INS_V2
from navgym.gps_ins.env_v3 import GPS_INS_V3
from navgym.gps_ins.platform import GpsInsPlatform
from navgym.scenarios import Jamming, MotionBurst, Multipath, Scenario, UrbanCanyon
from tests.navgym.envs.no_truth import assert_truth_not_observed


def test_sigma_matches_v2_nominal_at_reference_elevation():
    cn0 = sq.nominal_cn0_dbhz(context.REFERENCE_ELEVATION_RAD)
    np.testing.assert_allclose(context.pseudorange_sigma_m(cn0, 5.0), 5.0, rtol=1e-12)


def test_sigma_falls_with_cn0_like_sigma_epsilon():
    cn0 = np.array([35.0, 45.0])
    s = context.pseudorange_sigma_m(cn0, 5.0)
    assert s[0] > s[1]
    # 10 dB less C/N0: ~10x the variance (SIGMA-epsilon), a little more from the squaring loss
    ratio = (s[0] / s[1]) ** 2
    assert 10.0 <= ratio < 11.0


def test_jammer_reproduces_v2_jamming_variance():
    sigma_pr, jam = 5.0, np.array([0.0, 5.0, 20.0])
    js = context.jammer_to_signal_db(jam, sigma_pr)
    assert js[0] == -np.inf
    cn0 = sq.effective_cn0_dbhz(sq.nominal_cn0_dbhz(context.REFERENCE_ELEVATION_RAD), js, q=context.JAMMER_Q)
    var = context.pseudorange_sigma_m(cn0, sigma_pr) ** 2
    np.testing.assert_allclose(var, sigma_pr**2 + jam**2, rtol=1e-9)


def test_process_noise_states_are_the_velocity_errors():
    assert GpsInsPlatform().process_noise_states == (2, 3)


def test_row_cn0_falls_with_elevation_attenuation_and_jamming():
    el = np.deg2rad([[10.0, 45.0, 80.0]])
    open_sky = context.row_cn0_dbhz(el, 0.0, -np.inf)
    assert np.all(np.diff(open_sky) > 0)
    nlos = context.row_cn0_dbhz(el, np.array([[0.0, 10.0, 0.0]]), -np.inf)
    np.testing.assert_allclose(nlos[0, [0, 2]], open_sky[0, [0, 2]])
    np.testing.assert_allclose(nlos[0, 1], open_sky[0, 1] - 10.0)
    js = context.jammer_to_signal_db(np.array([[20.0]]), 5.0)
    jammed = context.row_cn0_dbhz(el, 0.0, js)
    assert np.all(jammed < open_sky - 1.0)


def test_window_stats_shorten_at_start():
    x = np.arange(10.0)[None, :]
    m, s = context.window_stats(x, 0, 3)
    assert m[0] == 0.0 and s[0] == 0.0
    m, s = context.window_stats(x, 5, 3)
    assert m[0] == 4.0
    np.testing.assert_allclose(s[0], np.std([3.0, 4.0, 5.0]))


# ------------------------------------------------------------------ the v3 build (context=True)
T = 160
SEEDS = list(range(300, 316))
BASE = Scenario(duration=float(T))


def _sim(scenario, seeds=SEEDS, **kw):
    p = GpsInsPlatform(true_noise=True, context=True, **kw)
    scen = scenario if isinstance(scenario, list) else [scenario] * len(seeds)
    return p, p.simulate([np.random.default_rng(s) for s in seeds], scen, T)


def _cn0(p, ep, steps=T):
    """Reported C/N0 ``(steps, B, m_max)`` and masks of every epoch (0 on rows not received)."""
    n = ep.gps_t0.shape[0]
    models = [p.step_models(ep, np.full(n, t)) for t in range(steps)]
    return np.stack([m.context.cn0_reported for m in models]), models


def _core(task="rowscale", B=3, seed=11):
    core = GPS_INS_V3.core(task, B, {})
    core.reset(np.arange(B), [np.random.default_rng(seed + i) for i in range(B)], [None] * B)
    return core


def _act(core, B):
    return np.tile(core.task.neutral_action(), (B, 1))


def test_jamming_lowers_every_rows_cn0():
    p, quiet = _sim(BASE)
    _, jam = _sim(dataclasses.replace(BASE, jamming=(Jamming(40.0, 100.0, jam_sigma=30.0),)))
    a, ma = _cn0(p, quiet, 110)
    b, _ = _cn0(p, jam, 110)
    both = (a > 0) & (b > 0)
    inside = (np.arange(110) + 1 >= 40) & (np.arange(110) + 1 < 100)
    drop = (a - b)[inside][both[inside]]
    assert drop.size > 1000 and (drop >= 4.0).all() and np.median(drop) > 10.0  # every row, every epoch
    np.testing.assert_array_equal(a[~inside], b[~inside])
    # and the true noise grows with it: the truth's R on the jammed rows
    assert all((m.mask.sum(axis=1) >= 4).all() for m in ma[:5])


def test_nlos_lowers_its_satellites_row_and_los_multipath_leaves_cn0_normal():
    p, a = _sim(BASE)
    _, b = _sim(dataclasses.replace(BASE, multipath=(Multipath(50.0, 120.0, row=7, bias=12.0),)))
    ca, _ = _cn0(p, a, 130)
    cb, mb = _cn0(p, b, 130)
    k = np.arange(130) + 1
    inside = (k >= 50) & (k < 120)
    np.testing.assert_array_equal(ca[~inside], cb[~inside])
    d = ca - cb
    assert (d >= 0).all()
    assert ((np.abs(d) > 0).sum(axis=2) <= 1).all()  # one satellite's row at most
    los = b.context.seg_loss_db[:, 0] <= ctx.LOS_LOSS_DB[1]
    assert los.any() and (~los).any()
    drop = d[inside].sum(axis=2).mean(axis=0)  # (B,) mean drop of the segment's row
    used = b.mp_sat[:, 0] >= 0
    assert (drop[used & ~los] > 3.0).all()  # NLOS: several dB (4-12 dB, fading, rounding)
    assert (drop[used & los] < 2.0).all()  # LOS multipath: within the fading (2 dB) of normal ...
    bias = np.stack([m.truth.bias for m in mb])[inside]  # ... while its bias acts
    assert (np.abs(bias[:, used & los]).max(axis=(0, 2)) == 12.0).all()


def test_pseudorange_variance_follows_cn0():
    """The compiled epoch's true variance is the DLL law at its C/N0 (plus the troposphere model's)."""
    from navgym.gnss.orbit_cache import default_orbit_cache
    from navgym.gnss.troposphere import TROPO_NOISE_FRACTION, goad_goodman_coefficients
    from navgym.gps_ins.epoch_kernel import pseudorange_epoch

    sc = dataclasses.replace(
        BASE,
        jamming=(Jamming(20.0, 60.0, jam_sigma=20.0),),
        canyons=(UrbanCanyon(30.0, 80.0, max_satellites=6, noise_scale=3.0),),
    )
    p, ep = _sim(sc)
    cache = default_orbit_cache()
    for t in (5, 25, 40, 70):
        k = np.full(len(SEEDS), t + 1)
        found = cache.interval_coefficients(ep.gps_t0 + k, ep.orbit)
        out = pseudorange_epoch(
            *found, cache.step, k, ep, p.almanac.prn, p.sigma_pr, p.m_max, goad_goodman_coefficients(),
            TROPO_NOISE_FRACTION, 1.0, ep.context,
        )  # fmt: skip
        mask, true_var, cn0 = out[1], out[7][out[1]], out[9][out[1]]  # the rows received
        assert mask.sum() > 50
        model = ctx.pseudorange_sigma_m(cn0, p.sigma_pr) ** 2
        extra = true_var - model  # the troposphere model's variance (0.05 T)^2: T < 100 m down to 1 deg
        assert (extra > -1e-9 * model).all() and (extra < 25.0).all() and np.median(extra) < 2.0
    lo = ctx.pseudorange_sigma_m(np.array([30.0, 45.0]), 5.0)
    assert lo[0] > 3 * lo[1]


def test_compiled_context_epoch_equals_the_numpy_reference():
    sc = dataclasses.replace(
        BASE,
        jamming=(Jamming(10.0, 60.0, jam_sigma=20.0, loss_prob=0.2),),
        canyons=(UrbanCanyon(5.0, 40.0, max_satellites=6, noise_scale=3.0),),
        multipath=(Multipath(2.0, 50.0, row=2, bias=8.0), Multipath(4.0, 50.0, row=5, bias=-9.0)),
    )
    p, ep = _sim(sc, seeds=SEEDS[:6])
    twin = copy.deepcopy(ep)
    for t in range(0, 45, 3):
        tt = np.full(6, t)
        a = p.step_models(ep, tt)
        b = p.step_models_reference(twin, tt)
        np.testing.assert_array_equal(a.mask, b.mask)
        np.testing.assert_allclose(a.z[a.mask], b.z[b.mask], rtol=0, atol=1e-6)
        np.testing.assert_allclose(a.truth.R, b.truth.R, rtol=1e-9, atol=1e-9)
        np.testing.assert_array_equal(a.context.cn0_reported, b.context.cn0_reported)


def test_bursts_raise_imu_activity():
    sc = dataclasses.replace(BASE, bursts=(MotionBurst(60.0, 90.0, velocity_sigma=0.02),))
    _, ep = _sim(sc)
    act = ep.context.imu[..., 1]
    k = np.arange(T + 1)
    inside, outside = (k > 61) & (k <= 90), (k > 2) & (k < 59)
    assert (np.median(act[:, inside], axis=1) > 4 * np.median(act[:, outside], axis=1)).all()
    assert (act[:, outside] < 0.2).mean() > 0.95
    # the same statistic as window_stats of the samples would give: mean |f| near g
    np.testing.assert_allclose(np.median(ep.context.imu[:, 1:, 0]), ctx.GRAVITY, atol=0.1)


def test_v3_batch_equals_single_episodes():
    B = 3
    batch = _core(B=B)
    for i in range(B):
        single = GPS_INS_V3.core("rowscale", 1, {})
        single.reset(np.arange(1), [np.random.default_rng(11 + i)], [None])
        for f in batch.episodes.context._fields:
            np.testing.assert_array_equal(
                getattr(batch.episodes.context, f)[i], getattr(single.episodes.context, f)[0]
            )
        o1, *_ = batch.step(_act(batch, B), [np.random.default_rng(i) for i in range(B)])
        o2, *_ = single.step(_act(single, 1), [np.random.default_rng(i)])
        np.testing.assert_allclose(o1[i], o2[0], rtol=1e-6, atol=1e-6)
        batch = _core(B=B)


def test_context_features_carry_no_truth():
    """Perturb the truth-only arrays: the observation, context features included, is unchanged."""
    B = 3
    core = _core(B=B)
    rngs = [np.random.default_rng(50 + i) for i in range(B)]
    for _ in range(35):  # past the start margin: events may be on
        core.step(_act(core, B), rngs)
    names = core.obs_features.names
    assert {"row_cn0", "row_elevation", "row_reported_sigma", "imu_activity"} <= set(names)

    def perturb(ep):
        return ep._replace(ins_err=ep.ins_err + 50.0, truth_ne=ep.truth_ne - 30.0, true_q=ep.true_q + 1.0)

    assert_truth_not_observed(core, rngs, _act(core, B), perturb)


def test_multipath_bias_reaches_no_cn0():
    """A segment's bias (a label the receiver cannot see) leaves the reported C/N0 unchanged."""
    a = dataclasses.replace(BASE, multipath=(Multipath(10.0, 60.0, row=6, bias=5.0),))
    b = dataclasses.replace(BASE, multipath=(Multipath(10.0, 60.0, row=6, bias=-30.0),))
    p, ea = _sim(a, seeds=SEEDS[:4])
    _, eb = _sim(b, seeds=SEEDS[:4])
    np.testing.assert_array_equal(_cn0(p, ea, 70)[0], _cn0(p, eb, 70)[0])


def test_v2_draws_no_context():
    c2 = GPS_INS_V2.core("noisescale", 2, {})
    c2.reset(np.arange(2), [np.random.default_rng(i) for i in range(2)], [None] * 2)
    assert c2.episodes.context is None
    assert not {"row_cn0", "imu_activity"} & set(c2.obs_features.names)
    p0, e0 = _sim(BASE, seeds=SEEDS[:2])
    p1 = GpsInsPlatform(true_noise=True)
    e1 = p1.simulate([np.random.default_rng(s) for s in SEEDS[:2]], [BASE] * 2, T)
    for f in e1._fields:  # context=True adds the context and changes none of the v2 draws
        if f not in ("context", "gens", "orbit"):
            np.testing.assert_array_equal(getattr(e0, f), getattr(e1, f), err_msg=f)


def test_rowscale_core_runs_inside_its_observation_space():
    B = 4
    core = GPS_INS_V3.core("rowscale", B, {})
    core.reset(np.arange(B), [np.random.default_rng(i) for i in range(B)], [None] * B)
    space = core.obs_features.space
    act = _act(core, B)
    rngs = [np.random.default_rng(100 + i) for i in range(B)]
    for _ in range(50):
        o, *_ = core.step(act, rngs)
        assert np.isfinite(o).all()
        assert all(space.contains(row) for row in o)
    assert "row_cn0" in core.obs_features.names


def test_v3_filter_has_a_velocity_walk_for_the_process_scale_and_the_truth_does_not():
    from navgym.gps_ins.platform import VELOCITY_WALK

    v2, v3 = GpsInsPlatform(true_noise=True), GpsInsPlatform(true_noise=True, context=True)
    assert (v2._Q[[2, 3], [2, 3]] == 0).all()  # s_q on the velocity states would scale zeros
    np.testing.assert_allclose(v3._Q[[2, 3], [2, 3]], VELOCITY_WALK**2 * v3.dt)
    np.testing.assert_array_equal(v3._Q_sim, v2._Q)
    _, ep = _sim(BASE, seeds=SEEDS[:2])
    m = v3.step_models(ep, np.zeros(2, int))
    np.testing.assert_array_equal(m.truth.Q[:, 2:4, 2:4], np.zeros((2, 2, 2)))
