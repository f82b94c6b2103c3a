"""GpsIns platform: filter quality, no truth in observations, pinned scenarios, rendering."""

import copy

import gymnasium as gym
import numpy as np
import pytest

import navgym
from navgym.gps_ins.env import GPS_INS
from navgym.scenarios import Outage, Scenario, critical_scenario

_core = GPS_INS.core


def _run(core, steps, action):
    out = []
    for _ in range(steps):
        out.append(core.step(action, core._rngs))
    return out


def _make(B=4, **kw):
    core = _core("fading", B, kw)
    core._rngs = [np.random.default_rng(100 + i) for i in range(B)]
    return core


def test_plain_ekf_is_accurate_and_consistent_with_gnss():
    core = _make(
        B=8, outage_probability=0.0, jamming_probability=0.0, episode_steps=200, true_bias_limit_ug=None
    )
    core.reset(np.arange(8), core._rngs, [None] * 8)
    res = _run(core, 200, np.full((8, 1), -1.0))
    err = np.array([r[4]["pos_err_m"] for r in res[50:]])
    nees = np.array([r[4]["nees"] for r in res[50:]])
    assert np.sqrt(np.mean(err**2)) < 5.0, np.sqrt(np.mean(err**2))
    # 8 states: average NEES near 8 (chi-square mean) for a consistent filter.
    assert 4.0 < nees.mean() < 16.0, nees.mean()


def test_error_and_covariance_grow_during_an_outage():
    core = _make(B=1, imu_grade="consumer", episode_steps=220)
    scen = Scenario(duration=220.0, outages=(Outage(100.0, 200.0),))
    core.reset(np.arange(1), core._rngs, [scen])
    res = _run(core, 220, np.full((1, 1), -1.0))
    sig = np.array([np.trace(r[4]["filtered_cov"][0][:2, :2]) for r in res])
    err = np.array([r[4]["pos_err_m"][0] for r in res])
    ok = np.array([r[4]["gnss_available"][0] for r in res])
    assert not ok[101:199].any() and ok[:99].all()
    assert sig[198] > 10 * sig[98]
    assert err[195:199].mean() > err[80:99].mean()
    assert err[215:].mean() < err[195:199].mean()  # GNSS back: the error shrinks again


def test_observation_carries_no_truth():
    """Perturb truth-only arrays (true INS errors, true track) in a copy: same observation."""
    core = _make(B=3)
    core.reset(np.arange(3), core._rngs, [None] * 3)
    _run(core, 5, np.zeros((3, 1)))
    twin = copy.deepcopy(core)
    ep = twin.episodes
    twin.episodes = ep._replace(ins_err=ep.ins_err + 50.0, truth_ne=ep.truth_ne - 30.0)
    o1, r1, *_, i1 = core.step(np.zeros((3, 1)), core._rngs)
    o2, r2, *_, i2 = twin.step(np.zeros((3, 1)), twin._rngs)
    np.testing.assert_array_equal(o1, o2)
    assert not np.allclose(i1["pos_err_m"], i2["pos_err_m"])  # truth did change the evaluation


def test_pinned_critical_scenario_goes_from_three_to_two_satellites():
    env = gym.make("navgym/GpsInsFading-v0", critical=True, max_episode_steps=3600)
    obs, info = env.reset(seed=0, options={"scenario": critical_scenario()})
    assert info["scenario"].critical
    n = []
    for _ in range(3600):
        obs, r, term, trunc, info = env.step(np.array([-1.0], np.float32))
        n.append(info["n_meas"])
        if term or trunc:
            break
    n = np.array(n)
    assert n.max() == 3 and n[-1] == 2 and (np.diff(n) <= 0).all()


def test_render_rgb_array():
    env = gym.make("navgym/GpsInsFading-v0", render_mode="rgb_array", max_episode_steps=20)
    env.reset(seed=0)
    for _ in range(20):
        env.step(np.array([0.0], np.float32))
    img = env.render()
    assert img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8 and img.std() > 0


@pytest.mark.parametrize("task", ["fading", "mixture", "resample"])
def test_bad_keyword_arguments_are_rejected(task):
    with pytest.raises(TypeError, match="unexpected keyword"):
        _core(task, 1, {"no_such_option": 1})
    with pytest.raises(ValueError, match="imu_grade"):
        _core(task, 1, {"imu_grade": "military"})


def test_roughening_spreads_the_resampled_particles_only_where_resampled():
    """v1's roughening (Gordon et al. 1993): after "resample now" every particle is distinct;
    without it the resampled cloud holds duplicates; a filter that did not resample is unchanged."""
    import gymnasium as gym

    after = {}
    for K in (0.0, 0.2):
        venv = gym.make_vec("navgym/GpsInsResample-v0", num_envs=2, roughening=K, max_episode_steps=20)
        venv.reset(seed=3)
        venv.step(np.array([0, 0]))  # one update from the broad prior: ESS falls to a few
        core = venv.core
        models = core.platform.step_models(core.episodes, core.t)
        out = core.task.step(core.state, np.array([True, False]), models, venv.rngs)
        after[K] = out.state.particles.x
    N = after[0.0].shape[1]
    # resampling duplicates particles; >= 2 distinct ancestors, so the cloud's range (which
    # scales Gordon's jitter) is not zero
    assert 1 < len(np.unique(after[0.0][0, :, 0])) < N
    assert len(np.unique(after[0.2][0, :, 0])) == N  # roughening makes them distinct
    np.testing.assert_array_equal(after[0.0][1], after[0.2][1])  # the second filter did not resample


def test_roughening_must_be_non_negative():
    import gymnasium as gym
    import pytest

    with pytest.raises(ValueError, match="roughening"):
        gym.make("navgym/GpsInsResample-v0", roughening=-0.1)


def test_v1_observes_log_ess_consistent_with_ess_frac():
    import gymnasium as gym

    env = gym.make("navgym/GpsInsResample-v1", max_episode_steps=10)
    f = env.unwrapped.core.obs_features
    obs, _ = env.reset(seed=1)
    assert obs[f.index("log_ess_frac")][0] == 0.0  # ESS = N at reset
    for a in (0, 0, 1, 0):
        obs, *_ = env.step(a)
        ess = obs[f.index("ess_frac")][0]
        expected = np.log10(np.clip(ess, 1e-3, 1.0))
        assert obs[f.index("log_ess_frac")][0] == pytest.approx(expected, abs=1e-5)
    assert "log_ess_frac" not in gym.make("navgym/GpsInsResample-v0").unwrapped.core.obs_features.names


def test_float32_particles_track_the_float64_filter_without_resampling():
    """particle_dtype="float32" (the default) weighs "observed minus computed" pseudo-ranges: with
    no resampling (no ancestor choice to flip) it follows the float64 filter to rounding level."""
    import gymnasium as gym

    runs = {}
    for dt in ("float64", "float32"):
        venv = gym.make_vec("navgym/GpsInsResample-v1", num_envs=4, particle_dtype=dt, max_episode_steps=40)
        venv.reset(seed=5)
        assert venv.core.state.particles.x.dtype == np.dtype(dt)
        err, ess = [], []
        for _ in range(30):
            _, _, _, _, info = venv.step(np.zeros(4, dtype=np.int64))
            err.append(info["pos_err_m"])
            ess.append(info["ess_frac"])
        runs[dt] = np.array(err), np.array(ess)
    (e64, s64), (e32, s32) = runs["float64"], runs["float32"]
    assert s64.min() < 0.01  # the weights did degenerate: a demanding case for the precision
    np.testing.assert_allclose(e32, e64, atol=2e-3)
    np.testing.assert_allclose(s32, s64, atol=1e-5)


def test_reduced_pseudorange_model_is_h_minus_rho0():
    """The float32-friendly reduced model equals h(x) - |d0| (float64 both ways)."""
    from navgym.gps_ins.models import PseudorangeModel

    rng = np.random.default_rng(0)
    B, m, N = 3, 6, 50
    sat = rng.normal(0, 1, (B, m, 3))
    sat *= 2.6e7 / np.linalg.norm(sat, axis=2, keepdims=True)
    p = rng.normal(0, 1, (B, 3)) * 1e3 + np.array([4e6, 3e6, 3.5e6])
    east, north = np.tile([1.0, 0, 0], (B, 1)), np.tile([0, 1.0, 0], (B, 1))
    model = PseudorangeModel.build(p, east, north, sat, rng.normal(2.4, 0.1, (B, m)), 25.0 * np.eye(m))
    x = rng.normal(0, 1, (B, N, 8)) * np.array([200, 200, 1, 1, 1, 1, 3e4, 10])
    z = model.h(x[:, 0]) + 1.0
    red, z_red = model.reduced(z)
    np.testing.assert_allclose(red.h(x), model.h(x) - np.sqrt(model.rho0_sq)[:, None, :], atol=1e-6)
    np.testing.assert_allclose(z_red, z - np.sqrt(model.rho0_sq))
    soa = np.ascontiguousarray(x.transpose(0, 2, 1)).transpose(0, 2, 1)
    np.testing.assert_allclose(red.h(soa), red.h(x), atol=1e-9)
    np.testing.assert_allclose(model.h(soa), model.h(x), rtol=0, atol=1e-6)  # (B, n, N) clouds
    x32 = soa.astype(np.float32)
    np.testing.assert_allclose(red.h(x32), red.h(x32.astype(np.float64)), rtol=1e-6, atol=2e-3)


def test_est_pos_is_the_corrected_position_eq_14():
    """``info["est_pos"] - info["truth_pos"]`` is the corrected position p_INS - e_hat minus truth."""
    env = gym.make("navgym/GpsInsFading-v1", outage_probability=1.0, outage_duration=(100.0, 100.0))
    env.reset(seed=3)
    core = env.unwrapped.core
    for _ in range(60):
        _, _, _, _, info = env.step(np.array([-1.0], np.float32))
    t, ep, m = int(core.t[0]), core.episodes, core.state.m[0]
    corrected = ep.p_ins[0, t] - m[0] * ep.east[0, t] - m[1] * ep.north[0, t]
    d = corrected - ep.rx_ecef[0, t]
    expected = np.array([d @ ep.north[0, t], d @ ep.east[0, t]])
    assert np.abs(expected).max() > 0.1  # a visible error, so a sign flip would show
    np.testing.assert_allclose(info["est_pos"] - info["truth_pos"], expected, atol=1e-3)
    assert info["pos_err_m"] == pytest.approx(np.hypot(*expected), abs=1e-3)


@pytest.mark.parametrize(
    "kwargs", [{"error_scale_m": -1.0}, {"error_scale_m": float("nan")}, {"divergence_m": -1.0}]
)
def test_reward_and_divergence_scales_are_validated(kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        gym.make("navgym/GpsInsFading-v1", **kwargs)


def test_card_documents_the_true_imu_mismatch():
    """``true_bias_limit_ug``: documented in the card with the per-task defaults the code uses."""
    from navgym.gps_ins.env import TASK_MISMATCH, GpsInsEnv

    flat = " ".join(GpsInsEnv.__doc__.split())
    assert TASK_MISMATCH == {"fading": (10.0, 3000.0), "mixture": None, "resample": None}
    assert "``true_bias_limit_ug=(10.0, 3000.0)`` (Fading) or ``None`` (Mixture, Resample)" in flat
    for task, limit in TASK_MISMATCH.items():
        assert _core(task, 1, {}).platform.true_bias_limit_ug == limit
    assert _core("fading", 1, {"true_bias_limit_ug": None}).platform.true_bias_limit_ug is None


@pytest.mark.parametrize("kwargs", [{"mask_deg": 20.0}, {"outage_probability": 0.5}])
def test_critical_scenario_refuses_scenario_kwargs_it_would_ignore(kwargs):
    with pytest.raises(ValueError, match="critical=True"):
        gym.make("navgym/GpsInsFading-v1", critical=True, **kwargs)


@pytest.mark.parametrize("kwargs", [{"episode_steps": 300}, {"dt": 0.5}])
def test_critical_scenario_keeps_its_published_horizon_and_rate(kwargs):
    with pytest.raises(ValueError, match="3600 s at dt = 1 s"):
        gym.make("navgym/GpsInsFading-v1", critical=True, **kwargs)


def test_fading_trace_of_HQH_is_zero_as_the_card_says():
    # Carvalho et al. 1997's Q drives only states no pseudo-range sees within a step (card: Observation Space)
    core = _make(B=4, episode_steps=20)
    core.reset(np.arange(4), core._rngs, [None] * 4)
    res = _run(core, 10, np.zeros((4, 1)))
    assert all((r[4]["tr_HQH"] == 0.0).all() for r in res)
    used = np.array([r[4]["gnss_available"] for r in res])
    tr_R = np.array([r[4]["tr_R"] for r in res])
    assert used.any() and (tr_R[used] > 0).all()  # zero with pseudo-ranges in use, not for want of rows
    assert "log_tr_HQH`` stays at its floor -8" in navgym.gps_ins.env.GpsInsEnv.__doc__


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        # 3600.0 == 3600 passed the published-horizon check and became 3600
        ({"critical": True, "episode_steps": 3600.0}, TypeError, r"episode_steps must be an integer >= 1"),
        ({"critical": True, "dt": "1"}, TypeError, r"dt must be a real number"),
        ({"critical": "no"}, TypeError, r"critical must be True or False; got 'no'"),
        # the vehicle plan of a 3e11 s episode hung the first reset
        ({"dt": 1e9}, ValueError, r"dt must be a finite number in \(0, 60\]"),
        ({"sigma_pr": 1e300}, ValueError, r"sigma_pr must be a finite number in \[0.001, 1000\]"),
        ({"sigma_pr": "5"}, TypeError, r"sigma_pr must be a real number in \[0.001, 1000\]; got '5'"),
        ({"true_bias_limit_ug": (10.0, 1e300)}, ValueError, r"true_bias_limit_ug .* in \(0, 100000\]"),
        ({"true_bias_limit_ug": 100.0}, TypeError, r"true_bias_limit_ug must be a pair"),
        ({"m_max": 8.0}, TypeError, r"m_max must be an integer in \[4, 16\]; got 8.0"),
        ({"mask_deg": "10"}, TypeError, r"mask_deg must be a real number in \[0, 90\)"),
        # the scenario's probabilities were compared as strings at the first reset
        ({"outage_probability": "0.5"}, TypeError, r"outage_probability must be a real number in \[0, 1\]"),
        ({"jamming_sigma": (10.0, float("inf"))}, ValueError, r"jamming_sigma must be a pair"),
    ],
)
def test_bad_values_are_refused_at_make_naming_the_argument(kwargs, error, message):
    with pytest.raises(error, match=message):
        gym.make("navgym/GpsInsFading-v1", **kwargs)


def test_the_largest_step_still_makes_an_env():
    env = gym.make("navgym/GpsInsFading-v1", dt=60.0, episode_steps=20, sigma_pr=1000.0)
    assert env.unwrapped.core.platform.dt == 60.0
