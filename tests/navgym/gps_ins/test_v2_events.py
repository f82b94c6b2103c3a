"""GpsIns under the v2 within-episode events: truth, measurements and ``StepModels.truth``.

Known answers on pinned scenarios (a multipath bias moves exactly one pseudo-range, its
satellite's, by its size there and nowhere else; a manoeuvre burst adds velocity error only
inside it; a canyon's cap, noise and losses), the true noise handed to the evaluation against
what the simulator drew (residual statistics over many episodes), the bias features, and the
cheap path: without ``true_noise`` the truth is None, and an episode without events is
simulated bit for bit as before.
"""

import copy
import dataclasses

import numpy as np
import pytest

from navgym.geo import C_LIGHT
from navgym.gps_ins.env import V2_EVENTS
from navgym.gps_ins.platform import BIAS_BOUNDS, GpsInsPlatform
from navgym.scenarios import Jamming, MotionBurst, Multipath, Scenario, ScenarioDistribution, UrbanCanyon

T = 200
DT = 1.0
B = 16
SEEDS = list(range(700, 700 + B))
TIMES = np.arange(T + 1) * DT
BASE = Scenario(duration=float(T))


def _sim(scenario, true_noise=True, seeds=SEEDS, **kw):
    p = GpsInsPlatform(true_noise=true_noise, **kw)
    scen = scenario if isinstance(scenario, list) else [scenario] * len(seeds)
    return p, p.simulate([np.random.default_rng(s) for s in seeds], scen, T)


def _run(p, ep, steps=T):
    """Every step's StepModels (the episodes' noise cursor advances)."""
    n = ep.gps_t0.shape[0]
    return [p.step_models(ep, np.full(n, t)) for t in range(steps)]


def _x_true(ep, k):
    return np.concatenate([ep.ins_err[:, k], C_LIGHT * ep.clock[:, k]], axis=1)


# ------------------------------------------------------------------------------ multipath
def test_multipath_moves_one_satellites_pseudorange_by_its_bias_there_and_nowhere_else():
    """A 12 m bias on the satellite ranked 7 at 50 s, until 120 s: one row moves by 12 m."""
    pinned = dataclasses.replace(BASE, multipath=(Multipath(50.0, 120.0, row=7, bias=12.0),))
    p, a = _sim(BASE)
    _, b = _sim(pinned)
    assert (b.mp_sat[:, 0] >= 0).all() and (b.mp_sat[:, 1:] == -1).all()
    ma, mb = _run(p, a), _run(p, b)
    hits = 0
    for t in range(T):
        np.testing.assert_array_equal(ma[t].mask, mb[t].mask)
        d = np.where(mb[t].mask, mb[t].z - ma[t].z, 0.0)
        inside = 50.0 <= (t + 1) * DT < 120.0
        moved = np.abs(d) > 1e-6
        assert moved.sum(axis=1).max() <= (1 if inside else 0), t
        np.testing.assert_allclose(d[moved], 12.0, atol=1e-6)
        # the truth says so, on that row only (and the same satellite's row before: no bias)
        np.testing.assert_allclose(mb[t].truth.bias[:, : d.shape[1]], np.where(moved, 12.0, 0.0), atol=0)
        hits += int(moved.sum())
        if t == 50:  # at the first epoch inside, the satellite sits on rank 7 (or the lowest in view)
            rank = np.argmax(moved, axis=1)
            n_vis = mb[t].mask.sum(axis=1)
            assert np.all(rank[moved.any(axis=1)] <= 7)
            assert np.all((rank == np.minimum(7, n_vis - 1))[moved.any(axis=1)])
    assert hits > 0.8 * B * 70  # tracked most of the segment


def test_multipath_slots_are_bounded():
    many = dataclasses.replace(BASE, multipath=tuple(Multipath(50.0, 60.0, 0, 1.0) for _ in range(9)))
    with pytest.raises(ValueError, match="at most 8"):
        _sim(many, seeds=[0])


# ---------------------------------------------------------------------------------- bursts
def test_a_manoeuvre_burst_adds_velocity_error_only_inside_it():
    """0.1 m/s^2 between 60 and 100 s: white velocity increments of 0.1 m/s, Q_true says so."""
    p, a = _sim(BASE)
    _, b = _sim(dataclasses.replace(BASE, bursts=(MotionBurst(60.0, 100.0, velocity_sigma=0.1),)))
    first = 60
    np.testing.assert_array_equal(a.ins_err[:, : first + 1], b.ins_err[:, : first + 1])
    np.testing.assert_array_equal(a.ins_err[..., 4:], b.ins_err[..., 4:])  # the biases do not move
    dv = b.ins_err[..., 2:4] - a.ins_err[..., 2:4]
    K = p.ins.K
    w = dv[:, 1:] - (1.0 - K * DT) * dv[:, :-1]  # the step's velocity increment
    steps = (TIMES[:-1] >= 60.0) & (TIMES[:-1] < 100.0)
    assert np.abs(w[:, ~steps]).max() <= 1e-12
    assert np.var(w[:, steps]) == pytest.approx(0.01, rel=0.2)  # 1280 draws
    dp = b.ins_err[..., 0:2] - a.ins_err[..., 0:2]
    np.testing.assert_allclose(np.diff(dp, axis=1), DT * dv[:, :-1], atol=1e-9)
    for t in (first - 1, first, 80, 99, 100):
        m = p.step_models(b, np.full(B, t))
        extra = np.zeros((8, 8))
        if 60.0 <= t * DT < 100.0:
            extra[2, 2] = extra[3, 3] = 0.01
        np.testing.assert_allclose(m.truth.Q - m.transition.Q, np.broadcast_to(extra, (B, 8, 8)), atol=1e-15)


# ---------------------------------------------------------------------------------- canyon
def test_urban_canyon_caps_satellites_inflates_noise_and_loses_pseudoranges():
    scen = dataclasses.replace(
        BASE,
        canyons=(
            UrbanCanyon(40.0, 60.0, max_satellites=5, noise_scale=3.0),
            UrbanCanyon(100.0, 140.0, max_satellites=12, noise_scale=1.0, loss_prob=0.5),
        ),
    )
    p, a = _sim(BASE)
    _, b = _sim(scen)
    ma, mb = _run(p, a), _run(p, b)
    for t in range(39, 59):
        assert mb[t].mask[:, 5:].sum() == 0 and (mb[t].mask[:, :5] == ma[t].mask[:, :5]).all()
        ok = mb[t].mask
        # the pseudo-range variance is 9 times as large (the troposphere-model error is not scaled)
        tv = mb[t].truth.R[:, np.arange(12), np.arange(12)]
        tv_a = ma[t].truth.R[:, np.arange(12), np.arange(12)]
        np.testing.assert_allclose((tv - tv_a)[ok], 8 * 25.0, rtol=1e-9)
        # and the error itself: the same normal times 3 (residuals about the truth, tropo noise aside)
        k = t + 1
        res_a = ma[t].z - ma[t].observation.h(_x_true(a, k)[:, None, :])[:, 0]
        res_b = mb[t].z - mb[t].observation.h(_x_true(b, k)[:, None, :])[:, 0]
        assert np.corrcoef(res_a[ok], res_b[ok])[0, 1] > 0.95
        assert np.std(res_b[ok]) > 2.5 * np.std(res_a[ok])
    kept = sum(mb[t].mask.sum() for t in range(99, 139)) / sum(ma[t].mask.sum() for t in range(99, 139))
    assert kept == pytest.approx(0.5, abs=0.05)


# ----------------------------------------------------------------------- the truth handed out
def _residuals(seed=0, n=24, compiled=True):
    dist = ScenarioDistribution(duration=float(T), start_margin=20.0, **V2_EVENTS)
    p = GpsInsPlatform(true_noise=True, scenarios=dist, compiled=compiled)
    rngs = [np.random.default_rng(seed + i) for i in range(n)]
    ep = p.simulate(rngs, p.sample_scenarios(rngs), T)
    us, big = [], []
    for t in range(T):
        m = p.step_models(ep, np.full(n, t))
        r = m.z - m.observation.h(_x_true(ep, t + 1)[:, None, :])[:, 0]
        R = np.diagonal(m.truth.R, axis1=1, axis2=2)
        bias = m.truth.bias
        u = (r - bias) / np.sqrt(R)
        us.append(u[m.mask])
        big.append(u[m.mask & (R > 4 * p.sigma_pr**2)])
    return np.concatenate(us), np.concatenate(big), ep


def test_step_models_truth_is_what_the_simulator_used():
    """``(z - h(x_true) - truth.bias) / sqrt(truth.R_ii)`` is standard normal, events included."""
    u, big, ep = _residuals()
    assert u.size > 30000 and big.size > 1000
    assert np.mean(u) == pytest.approx(0.0, abs=0.03) and np.var(u) == pytest.approx(1.0, rel=0.05)
    assert np.mean(big) == pytest.approx(0.0, abs=0.1) and np.var(big) == pytest.approx(1.0, rel=0.1)
    assert (ep.mp_sat >= 0).sum() > 20  # multipath segments were drawn and tied to satellites


def test_multipath_bias_shows_in_the_mean_residual():
    """Without subtracting the bias, the biased rows' residuals have its mean (sign included)."""
    p, ep = _sim(dataclasses.replace(BASE, multipath=(Multipath(30.0, 150.0, row=9, bias=-20.0, sigma=2.0),)))
    rows = []
    for t in range(T):
        m = p.step_models(ep, np.full(B, t))
        r = m.z - m.observation.h(_x_true(ep, t + 1)[:, None, :])[:, 0]
        on = m.mask & (m.truth.bias[:, :12] != 0)
        rows.append(r[on])
        np.testing.assert_array_equal(m.truth.bias[on], -20.0)
        R = np.diagonal(m.truth.R, axis1=1, axis2=2)
        assert np.all(R[on] >= 25.0 + 4.0)
    r = np.concatenate(rows)
    assert r.size > 1000 and np.mean(r) == pytest.approx(-20.0, abs=0.5)


def test_truth_only_with_true_noise_and_nominal_without_events():
    p, a = _sim(BASE, true_noise=False)
    assert a.true_q is None and p.step_models(copy.deepcopy(a), np.zeros(B, dtype=np.int64)).truth is None
    p2, b = _sim(BASE)
    for t in range(0, 60):
        m, m0 = p2.step_models(b, np.full(B, t)), p.step_models(a, np.full(B, t))
        np.testing.assert_array_equal(m.truth.Q, np.broadcast_to(m.transition.Q, (B, 8, 8)))
        np.testing.assert_array_equal(m.truth.bias, 0.0)
        R = np.diagonal(m.truth.R, axis1=1, axis2=2)
        # nominal pseudo-range noise plus the troposphere model's 5 % error (up to ~3.5 m near the mask)
        assert np.all(R[m.mask] >= 25.0) and np.all(R[m.mask] < 25.0 + 3.5**2) and np.all(R[~m.mask] == 25.0)
        np.testing.assert_array_equal(m.z, m0.z)  # what the filter sees does not depend on it
    assert p2.episode_bytes(T) > p.episode_bytes(T)


def test_episodes_without_events_are_simulated_as_before_in_any_batch():
    events = dataclasses.replace(
        BASE,
        bursts=(MotionBurst(50.0, 70.0, 0.2),),
        multipath=(Multipath(40.0, 90.0, 8, -8.0, 1.0),),
        canyons=(UrbanCanyon(100.0, 130.0, 6, 3.0, 0.3),),
        jamming=(Jamming(60.0, 110.0, 20.0, 0.2, 10.0),),
    )
    seeds = [3, 4, 5]
    p, mixed = _sim([BASE, events, BASE], seeds=seeds)
    q, alone = _sim(BASE, true_noise=False, seeds=[seeds[0]])
    for name in ("ins_err", "regime", "noise_n", "clock", "row_cap", "gnss_ok", "p_ins"):
        np.testing.assert_array_equal(getattr(mixed, name)[0], getattr(alone, name)[0], err_msg=name)
    mm = _run(p, mixed, 150)
    ma = _run(q, alone, 150)
    for x, y in zip(mm, ma, strict=True):
        np.testing.assert_array_equal(x.z[0], y.z[0])
        np.testing.assert_array_equal(x.mask[0], y.mask[0])
    _, single = _sim(events, seeds=[4])
    for name in ("ins_err", "regime", "mp_sat", "mp_bias", "true_q"):
        np.testing.assert_array_equal(getattr(mixed, name)[1], getattr(single, name)[0], err_msg=name)


# --------------------------------------------------------------------- compiled == reference
def test_compiled_epoch_equals_the_reference_through_the_events():
    dist = ScenarioDistribution(duration=float(T), start_margin=20.0, **V2_EVENTS)
    p = GpsInsPlatform(true_noise=True, scenarios=dist)
    rngs = [np.random.default_rng(40 + i) for i in range(B)]
    ep = p.simulate(rngs, p.sample_scenarios(rngs), T)
    ref = dataclasses.replace(p, compiled=False)
    ep_c, ep_r = copy.deepcopy(ep), copy.deepcopy(ep)
    seen = 0
    for t in range(T):
        tt = np.full(B, t)
        mc, mr = p.step_models(ep_c, tt), ref.step_models(ep_r, tt)
        np.testing.assert_array_equal(mc.mask, mr.mask)
        np.testing.assert_allclose(mc.z[mc.mask], mr.z[mr.mask], rtol=0, atol=1e-6)
        np.testing.assert_allclose(mc.truth.R, mr.truth.R, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(mc.truth.bias, mr.truth.bias, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(mc.truth.Q, mr.truth.Q)
        seen += int((mc.truth.bias != 0).sum())
    assert seen > 100


# ------------------------------------------------------------------------- bias features
def test_bias_features_are_the_filters_estimates_and_their_rates():
    from navgym.gps_ins.env_v2 import GPS_INS_V2

    core = GPS_INS_V2.core("fading", 4)
    assert core.platform.bias_features and "bias_est" in core.platform.episode_cursors
    rngs = [np.random.default_rng(i) for i in range(4)]
    obs = core.reset(np.arange(4), rngs, [None] * 4)
    cols = {n: core.obs_features.index(n) for n in ("accel_bias", "accel_bias_rate", "clock_drift_rate")}
    np.testing.assert_array_equal(obs[:, cols["accel_bias_rate"]], 0.0)
    for _ in range(5):
        prev = core.episodes.bias_est.copy()
        obs = core.step(np.full((4, 1), -1.0), rngs)[0]
        m = core.state.m
        g = 9.80665e-3
        expected = np.clip(m[:, 4:6] / g, -BIAS_BOUNDS["accel_bias"], BIAS_BOUNDS["accel_bias"])
        np.testing.assert_allclose(obs[:, cols["accel_bias"]], expected, rtol=1e-6, atol=1e-7)
        rate = np.clip((m[:, 4:6] - prev[:, 0:2]) / g, -0.1, 0.1)
        np.testing.assert_allclose(obs[:, cols["accel_bias_rate"]], rate, rtol=1e-5, atol=1e-7)
        drift_rate = np.clip(m[:, 7] - prev[:, 2], -0.5, 0.5)
        np.testing.assert_allclose(obs[:, cols["clock_drift_rate"]][:, 0], drift_rate, rtol=1e-5, atol=1e-6)
    v1 = GpsInsPlatform()
    assert not any(f.name == "accel_bias" for f in v1.features())


# ------------------------------------------------------------------------ the clairvoyant gap
def test_the_clairvoyant_filter_clearly_beats_the_plain_one_on_v2_episodes():
    """What v2 is for: the EKF told every step's true Q, R and bias (``clairvoyant=True``)."""
    from navgym.gps_ins.env_v2 import GPS_INS_V2

    n = 12
    out = []
    for clairvoyant in (False, True):
        core = GPS_INS_V2.core("fading", n, {"clairvoyant": clairvoyant})
        rngs = [np.random.default_rng(3000 + i) for i in range(n)]
        core.reset(np.arange(n), rngs, [None] * n)
        err = [core.step(np.full((n, 1), -1.0), rngs)[4]["pos_err_m"] for _ in range(core.T)]
        out.append(float(np.sqrt(np.mean(np.square(err), axis=0)).mean()))
    plain, told = out
    assert told < 0.5 * plain and plain > 4.0, out


# ---------------------------------------------------------------------------------- the v2 ids
V2_IDS = ["navgym/GpsInsFading-v2", "navgym/GpsInsNoiseScale-v2", "navgym/GpsInsMixture-v2"]


@pytest.mark.parametrize("env_id", V2_IDS)
def test_observation_carries_no_truth(env_id):
    """Perturb the truth-only arrays of the v2 episodes in a copy: the observation is unchanged."""
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the ids

    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=5)
    core = venv.unwrapped.core
    act = np.tile(core.task.neutral_action(), (3, 1))
    for _ in range(35):  # past the start margin: events may be on
        core.step(act, venv.unwrapped.rngs)
    twin, twin_rngs = copy.deepcopy((core, venv.unwrapped.rngs))
    ep = twin.episodes
    twin.episodes = ep._replace(
        ins_err=ep.ins_err + 50.0, truth_ne=ep.truth_ne - 30.0, true_q=ep.true_q + 1.0
    )
    for _ in range(4):
        o1, *_, i1 = core.step(act, venv.unwrapped.rngs)
        o2, *_, i2 = twin.step(act, twin_rngs)
        np.testing.assert_array_equal(o1, o2)
    assert not np.allclose(i1["pos_err_m"], i2["pos_err_m"])
    venv.close()


def test_the_v2_ids_sample_v2_episodes_deterministically_and_keep_the_truth():
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the ids

    env = gym.make("navgym/GpsInsFading-v2")
    core = env.unwrapped.core
    p = core.platform
    assert p.true_noise and p.bias_features and p.true_bias_limit_ug is None and core.T == 300
    doc = type(env.unwrapped).__doc__
    assert "v2 episodes" in doc and "* v2 (Fading" in doc and "accel_bias" in doc
    scenarios = []
    for _ in range(2):
        env.reset(seed=123)
        scenarios.append(core.scenarios[0])
        assert core.platform.step_models(copy.deepcopy(core.episodes), core.t).truth.R.shape == (1, 12, 12)
    assert scenarios[0] == scenarios[1] and scenarios[0].multipath
    v1 = gym.make("navgym/GpsInsFading-v1").unwrapped.core
    assert not v1.platform.true_noise and v1.platform.true_bias_limit_ug == (10.0, 3000.0)


def test_v2_vector_sub_env_i_equals_a_single_env_seeded_s_plus_i_through_the_events():
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the ids

    env_id, n, seed, steps = "navgym/GpsInsNoiseScale-v2", 2, 31, 120
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    singles = [gym.make(env_id) for _ in range(n)]
    vobs, _ = venv.reset(seed=seed)
    for i, e in enumerate(singles):
        np.testing.assert_array_equal(vobs[i], e.reset(seed=seed + i)[0])
    rng = np.random.default_rng(0)
    for _ in range(steps):
        a = rng.uniform(-1.0, 1.0, (n, 2)).astype(np.float32)
        vobs, vr, *_ = venv.step(a)
        for i, e in enumerate(singles):
            o, r, *_ = e.step(a[i])
            np.testing.assert_array_equal(vobs[i], o)
            assert vr[i] == r


def test_v2_episode_bytes_estimates_the_peak_of_a_reset():
    """As the registry-wide check for the v0/v1 declaration: between the peak and four times it."""
    import tracemalloc

    from navgym.gps_ins.env_v2 import GPS_INS_V2

    T_, B_ = 1000, 2
    rngs = [np.random.default_rng(i) for i in range(B_)]
    GPS_INS_V2.core("fading", B_, {"episode_steps": T_}).reset(np.arange(B_), rngs, [None] * B_)
    core = GPS_INS_V2.core("fading", B_, {"episode_steps": T_})
    tracemalloc.start()
    try:
        core.reset(np.arange(B_), rngs, [None] * B_)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak <= B_ * core.platform.episode_bytes(T_) <= 4 * peak, (
        peak,
        B_ * core.platform.episode_bytes(T_),
    )
