"""Quadrotor under the v2 within-episode events: IMU, fixes, ``StepModels.truth``, bias features.

Known answers on pinned scenarios (a multipath bias shifts its row by exactly its size there and
nowhere else; a vibration burst changes the preintegrated IMU only inside it, with the variances
of :func:`~navgym.quadrotor.platform.vibration_q`; the jamming ramp's profile in the true R; a
canyon's cap, noise and losses), the true noise handed to the evaluation against what the
simulator drew (residual statistics over many episodes), the bias features, and the cheap path:
without ``true_noise`` the truth is None, and an episode without events is simulated bit for bit
as before.
"""

import copy
import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.quadrotor.env import V2_EVENTS
from navgym.quadrotor.env_v2 import QUADROTOR_V2
from navgym.quadrotor.models import M_ROWS
from navgym.quadrotor.platform import QuadrotorPlatform, vibration_q
from navgym.scenarios import Jamming, MotionBurst, Multipath, Scenario, ScenarioDistribution, UrbanCanyon

T = 600
DT = 0.1
B = 16
SEEDS = list(range(700, 700 + B))
TIMES = np.arange(T + 1) * DT
ROUND = 1e-9
BASE = Scenario(duration=60.0)
V2_IDS = ["navgym/QuadrotorFading-v2", "navgym/QuadrotorNoiseScale-v2", "navgym/QuadrotorMixture-v2"]


def _sim(scenario, true_noise: bool = True, seeds=SEEDS, T_: int = T, **kw):
    p = QuadrotorPlatform(true_noise=true_noise, **kw)
    scen = scenario if isinstance(scenario, list) else [scenario] * len(seeds)
    return p, p.simulate([np.random.default_rng(s) for s in seeds], scen, T_)


def _inside(start: float, end: float, times=TIMES) -> np.ndarray:
    return (times >= start - 1e-9) & (times < end - 1e-9)


# ------------------------------------------------------------------------------ multipath
def test_multipath_shifts_its_row_by_its_bias_there_and_nowhere_else():
    pinned = dataclasses.replace(BASE, multipath=(Multipath(5.0, 15.0, row=1, bias=-12.0),))
    p, a = _sim(BASE)
    _, b = _sim(pinned)
    np.testing.assert_array_equal(a.fix, b.fix)
    np.testing.assert_array_equal(a.truth, b.truth)
    np.testing.assert_array_equal(a.d6, b.d6)
    d = b.z - a.z
    inside = _inside(5.0, 15.0)
    np.testing.assert_allclose(d[:, inside, 1], -12.0, atol=ROUND)
    assert np.abs(d[:, ~inside, 1]).max() <= ROUND
    assert np.abs(d[..., [0, 2, 3, 4, 5]]).max() == 0.0
    # the mean error of the row: -12 m inside (1600 fixes, standard error 0.05 m), 0 outside
    err = b.z[..., 1] - b.truth[..., 1]
    assert np.mean(err[:, inside]) == pytest.approx(-12.0, abs=0.25)
    assert np.mean(err[:, ~inside]) == pytest.approx(0.0, abs=0.15)
    for t in (40, 48, 49, 148, 149, 300):
        truth = p.step_models(b, np.full(B, t)).truth
        expected = -12.0 if 5.0 <= (t + 1) * DT < 15.0 - 1e-9 else 0.0
        np.testing.assert_array_equal(truth.bias, np.tile([0.0, expected, 0, 0, 0, 0], (B, 1)))


# ------------------------------------------------------------------------------ vibration
def test_vibration_changes_the_imu_only_inside_the_burst_with_the_variances_of_vibration_q():
    """0.3 m/s/sqrt(s) between 10 and 30 s: dv, dp of the steps inside change by white noise of
    covariance ``0.09 vibration_q`` per axis; nothing else changes (no gyro vibration here)."""
    s = 0.3
    burst = MotionBurst(10.0, 30.0, velocity_sigma=s, yaw_rate_sigma=0.0)
    p, a = _sim(BASE)
    _, b = _sim(dataclasses.replace(BASE, bursts=(burst,)))
    for name in ("truth", "z", "fix", "dR", "phi", "m0"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    steps = _inside(10.0, 30.0, TIMES[:-1])  # step k -> k + 1 starts at k dt
    d = b.d6 - a.d6
    assert np.abs(d[:, ~steps]).max() == 0.0
    dv, dp = d[:, steps, :3].reshape(-1), d[:, steps, 3:].reshape(-1)  # 9600 draws each
    Qv = s**2 * vibration_q(DT, p.n_sub)
    assert np.mean(dv**2) == pytest.approx(Qv[3, 3], rel=0.06)
    assert np.mean(dp**2) == pytest.approx(Qv[0, 0], rel=0.06)
    assert np.mean(dp * dv) == pytest.approx(Qv[0, 3], rel=0.06)
    assert abs(np.mean(dv)) < 0.1 * np.sqrt(Qv[3, 3])
    # the exact discrete covariance, not the continuous T^3/3 (a 0.02 % difference here)
    assert Qv[0, 0] == pytest.approx(s**2 * (DT**3 / 3 - DT * (DT / 20) ** 2 / 12), rel=1e-12)
    # StepModels.truth: the nominal Q plus 0.09 vibration_q inside, the nominal Q outside
    for t in (99, 100, 250, 299, 300):
        m = p.step_models(b, np.full(B, t))
        extra = Qv if 10.0 <= t * DT < 30.0 - 1e-9 else np.zeros((15, 15))
        np.testing.assert_allclose(
            m.truth.Q - m.transition.Q, np.broadcast_to(extra, (B, 15, 15)), atol=1e-18
        )


def test_gyro_vibration_is_an_angle_random_walk_of_its_density():
    """0.01 rad/sqrt(s) of gyro vibration: the step's rotation changes by ``0.01^2 dt`` per axis."""
    y = 0.01
    burst = MotionBurst(10.0, 30.0, velocity_sigma=0.0, yaw_rate_sigma=y)
    p, a = _sim(BASE)
    _, b = _sim(dataclasses.replace(BASE, bursts=(burst,)))
    steps = _inside(10.0, 30.0, TIMES[:-1])
    assert np.abs(b.dR[:, ~steps] - a.dR[:, ~steps]).max() == 0.0
    E = np.swapaxes(a.dR[:, steps], -1, -2) @ b.dR[:, steps]  # small rotations
    angle = (
        np.stack([E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0], E[..., 1, 0] - E[..., 0, 1]], -1)
        / 2
    )
    assert np.mean(angle**2) == pytest.approx(y**2 * DT, rel=0.06)
    m = p.step_models(b, np.full(B, 150))
    dQ = m.truth.Q - m.transition.Q
    np.testing.assert_allclose(np.diagonal(dQ, axis1=1, axis2=2)[:, 6:9], y**2 * DT, rtol=1e-12)
    np.testing.assert_allclose(dQ[:, :6], 0.0, atol=0)


def test_per_step_noise_sigmas_in_the_compiled_kernel_equal_the_numpy_reference():
    """The kernel's per-step ``na, ng`` (the bursts) against the NumPy IMU and preintegration."""
    from tests.navgym.quadrotor import test_imu_kernel as k

    plans, t0, bias, noise, na, ng, omega, gamma = k._inputs(1e-3)
    rng = np.random.default_rng(1)
    na2 = np.where(rng.random((k.B, k.T)) < 0.5, na[:, None], 3.0)  # (B, T): a burst on half the steps
    ng2 = np.where(rng.random((k.B, k.T)) < 0.5, ng[:, None], 0.05)
    times = t0[:, None, None] + (np.arange(k.T) * k.DT)[None, :, None] + (np.arange(k.N_SUB) + 0.5) * k.DELTA
    f_ib, w_ib = k.quadrotor_imu(plans, times.reshape(k.B, -1))
    f = np.stack(f_ib, -1).reshape(k.B, k.T, k.N_SUB, 3)
    w = np.stack(w_ib, -1).reshape(k.B, k.T, k.N_SUB, 3)
    accel = f + bias[:, : k.T, None, :3] + na2[:, :, None, None] * noise[..., :3]
    gyro = w + bias[:, : k.T, None, 3:] + ng2[:, :, None, None] * noise[..., 3:]
    ref = k.preintegrate(gyro, accel, k.DELTA)
    dR, phi, d6, J6 = k._kernel(plans, t0, bias, noise, na2, ng2, omega, gamma, chunk=7)
    np.testing.assert_allclose(dR, ref.dR, rtol=0, atol=1e-14)
    np.testing.assert_allclose(phi, ref.phi, rtol=0, atol=1e-14)
    np.testing.assert_allclose(d6, np.concatenate([ref.dv, ref.dp], -1), rtol=0, atol=1e-12)
    np.testing.assert_allclose(J6, np.block([[-ref.jva, ref.jvg], [-ref.jpa, ref.jpg]]), rtol=0, atol=1e-12)
    # one value per episode is the same as that value at every step, bit for bit
    one = k._kernel(plans, t0, bias, noise, na, ng, omega, gamma)
    same = k._kernel(
        plans, t0, bias, noise, np.repeat(na[:, None], k.T, 1), np.repeat(ng[:, None], k.T, 1), omega, gamma
    )
    for x, y in zip(one, same, strict=True):
        np.testing.assert_array_equal(x, y)
    from navgym.quadrotor.imu_kernel import preintegrated_imu

    with pytest.raises(ValueError, match="na must be"):
        preintegrated_imu(plans, t0, 0, k.DT, k.N_SUB, omega, gamma, bias, noise, na2[:, :5], ng, one)


# --------------------------------------------------------------------------------- jamming
def test_jamming_ramp_profile_in_the_true_r():
    jam = Jamming(10.0, 30.0, jam_sigma=20.0, loss_prob=0.0, ramp=5.0)
    p, b = _sim(dataclasses.replace(BASE, jamming=(jam,)))
    expected = np.array([jam.profile(t) for t in TIMES])
    for t in (99, 124, 199, 274, 300):
        R = np.diagonal(p.step_models(b, np.full(B, t)).truth.R, axis1=1, axis2=2)
        j = 20.0 * expected[t + 1]
        np.testing.assert_allclose(R[:, 0], 4.0 + j**2, rtol=1e-12)
        np.testing.assert_allclose(R[:, 2], 9.0 + j**2, rtol=1e-12)
        np.testing.assert_allclose(R[:, 3], 0.01 + (0.05 * j) ** 2, rtol=1e-12)


# ---------------------------------------------------------------------------------- canyon
def test_urban_canyon_caps_satellites_inflates_noise_and_loses_fixes():
    scen = dataclasses.replace(
        BASE,
        canyons=(
            UrbanCanyon(10.0, 20.0, max_satellites=3),  # below 4: no fix
            UrbanCanyon(30.0, 40.0, max_satellites=6, noise_scale=3.0),
            UrbanCanyon(45.0, 55.0, max_satellites=6, noise_scale=1.0, loss_prob=0.5),
        ),
    )
    p, a = _sim(BASE)
    _, b = _sim(scen)
    assert not b.fix[:, _inside(10.0, 20.0)].any() and a.fix[:, _inside(10.0, 20.0)].all()
    noisy = _inside(30.0, 40.0)
    e_a = (a.z - a.truth[..., :M_ROWS])[:, noisy]
    e_b = (b.z - b.truth[..., :M_ROWS])[:, noisy]
    np.testing.assert_allclose(e_b, 3.0 * e_a, rtol=1e-9, atol=ROUND)
    kept = b.fix[:, _inside(45.0, 55.0)].mean()
    assert kept == pytest.approx(0.5, abs=0.06)  # 1600 fixes
    R = np.diagonal(p.step_models(b, np.full(B, 349)).truth.R, axis1=1, axis2=2)  # epoch 35 s
    np.testing.assert_allclose(R, np.tile(9.0 * p.row_sigma**2, (B, 1)), rtol=1e-12)
    outside = ~(_inside(10.0, 20.0) | _inside(45.0, 55.0))
    np.testing.assert_array_equal(a.fix[:, outside], b.fix[:, outside])


# ----------------------------------------------------------------------- the truth handed out
def test_step_models_truth_is_what_the_simulator_used():
    """``(z - h(truth) - truth.bias) / sqrt(truth.R_ii)`` is standard normal, row by row."""
    n = 48
    dist = ScenarioDistribution(duration=60.0, start_margin=6.0, **V2_EVENTS)
    p = QuadrotorPlatform(true_noise=True, scenarios=dist)
    rngs = [np.random.default_rng(i) for i in range(n)]
    ep = p.simulate(rngs, p.sample_scenarios(rngs), T)
    rows, inflated = [[] for _ in range(M_ROWS)], []
    for t in range(T):
        m = p.step_models(ep, np.full(n, t))
        R = np.diagonal(m.truth.R, axis1=1, axis2=2)
        u = (m.z - ep.truth[:, t + 1, :M_ROWS] - m.truth.bias) / np.sqrt(R)
        for r in range(M_ROWS):
            rows[r].append(u[m.mask[:, r], r])
        inflated.append(u[m.mask & (R > 4 * np.diag(p.R))])
    for r, u in enumerate(rows):
        u = np.concatenate(u)
        assert u.size > 10000, r
        assert np.mean(u) == pytest.approx(0.0, abs=0.04), r
        assert np.var(u) == pytest.approx(1.0, rel=0.05), r
    big = np.concatenate(inflated)
    assert big.size > 5000  # the jammed, canyon and multipath epochs on their own
    assert np.mean(big) == pytest.approx(0.0, abs=0.06) and np.var(big) == pytest.approx(1.0, rel=0.06)
    # a multipath segment's bias is the mean error of its row
    biased = ep.true_bias != 0
    assert biased.any(axis=(0, 1))[:3].all() and not biased[..., 3:].any()
    resid = (ep.z - ep.truth[..., :M_ROWS])[biased & ep.fix[..., None]]
    np.testing.assert_allclose(np.mean(resid - ep.true_bias[biased & ep.fix[..., None]]), 0.0, atol=0.1)
    assert np.mean(np.abs(resid)) > 5.0


def test_truth_scales_the_nominal_q_with_the_imu_mismatch():
    p, ep = _sim(BASE, imu_mismatch=(0.5, 4.0), seeds=SEEDS[:4], T_=20)
    m = p.step_models(ep, np.full(4, 3))
    np.testing.assert_allclose(m.truth.Q, (ep.imu_scale**2)[:, None, None] * p.Q, rtol=1e-15)
    assert not np.allclose(ep.imu_scale, 1.0)


def test_truth_only_with_true_noise_and_nominal_without_events():
    p, a = _sim(BASE, true_noise=False)
    assert a.true_q is None and a.true_r is None and a.true_bias is None and a.bias_prev is None
    assert p.step_models(a, np.zeros(B, dtype=np.int64)).truth is None
    p2, b = _sim(BASE)
    for t in (0, 77, 599):
        m = p2.step_models(b, np.full(B, t))
        np.testing.assert_array_equal(m.truth.Q, np.broadcast_to(m.transition.Q, (B, 15, 15)))
        np.testing.assert_array_equal(m.truth.R, np.broadcast_to(p2.R, (B, 6, 6)))
        np.testing.assert_array_equal(m.truth.bias, 0.0)
        m0 = p.step_models(a, np.full(B, t))
        np.testing.assert_array_equal(m.z, m0.z)
    assert p2.episode_bytes(T) > p.episode_bytes(T)


def test_episodes_without_events_are_simulated_as_before_in_any_batch():
    """The general path (events in the batch, truth kept) equals the cheap one bit for bit."""
    events = dataclasses.replace(
        BASE,
        bursts=(MotionBurst(10.0, 20.0, 0.2, 0.004),),
        multipath=(Multipath(5.0, 15.0, 1, -8.0, 1.0),),
        canyons=(UrbanCanyon(30.0, 40.0, 6, 3.0, 0.3),),
        jamming=(Jamming(20.0, 40.0, 10.0, 0.2, 4.0),),
    )
    seeds = [3, 4, 5]
    _, mixed = _sim([BASE, events, BASE], seeds=seeds)
    for i in (0, 2):
        _, alone = _sim(BASE, true_noise=False, seeds=[seeds[i]])
        for name in alone._fields:
            if getattr(alone, name) is not None:
                np.testing.assert_array_equal(getattr(mixed, name)[i], getattr(alone, name)[0], err_msg=name)
    _, single = _sim(events, seeds=[4])
    for name in single._fields:
        if getattr(single, name) is not None:
            np.testing.assert_array_equal(getattr(mixed, name)[1], getattr(single, name)[0], err_msg=name)


# ------------------------------------------------------------------------ the clairvoyant gap
def _rmse(clairvoyant: bool, B_: int = 16, scenario=None) -> np.ndarray:
    core = QUADROTOR_V2.core("fading", B_, {"clairvoyant": clairvoyant})
    rngs = [np.random.default_rng(1000 + i) for i in range(B_)]
    core.reset(np.arange(B_), rngs, [scenario] * B_)
    err = [core.step(np.full((B_, 1), -1.0), rngs)[4]["pos_err_m"] for _ in range(core.T)]
    return np.sqrt(np.mean(np.square(err), axis=0))


def test_the_clairvoyant_filter_clearly_beats_the_plain_one_on_v2_episodes():
    """What v2 is for: knowing the true noise pays (measured 7.8 -> 1.3 m on 16 episodes)."""
    plain, told = _rmse(False).mean(), _rmse(True).mean()
    assert told < 0.5 * plain and plain > 3.0


def test_the_clairvoyant_equals_the_plain_filter_without_events():
    np.testing.assert_array_equal(_rmse(False, 4, BASE), _rmse(True, 4, BASE))


# --------------------------------------------------------------------------- bias features
def test_bias_features_are_the_filters_estimates_and_their_rates_and_only_on_v2():
    core = QUADROTOR_V2.core("fading", 3, {})
    rngs = [np.random.default_rng(i) for i in range(3)]
    obs = core.reset(np.arange(3), rngs, [None] * 3)
    fs = core.obs_features
    sig = core.platform.P0_sigma[9:15]
    np.testing.assert_array_equal(obs[:, fs.index("accel_bias_rate")], 0.0)
    prev = core.state.m[:, 9:15].copy()
    for _ in range(30):
        obs = core.step(np.full((3, 1), -1.0), rngs)[0]
        m = core.state.m[:, 9:15]
        want = np.concatenate([m / sig, (m - prev) / (sig * DT)], axis=1).astype(np.float32)
        got = np.concatenate(
            [obs[:, fs.index(k)] for k in ("accel_bias", "gyro_bias", "accel_bias_rate", "gyro_bias_rate")], 1
        )
        ok = np.abs(want) < [20] * 6 + [50] * 6
        np.testing.assert_allclose(got[ok], want[ok], rtol=1e-6, atol=1e-6)
        prev = m.copy()
    assert core.platform.episode_cursors == ("bias_prev",)
    v1 = gym.make("navgym/QuadrotorFading-v1").unwrapped.core
    assert "accel_bias" not in v1.obs_features.names and v1.platform.episode_cursors == ()


@pytest.mark.parametrize("env_id", V2_IDS)
def test_observation_carries_no_truth(env_id):
    """Perturb every truth-only array of the v2 episodes in a copy: the observation is unchanged."""
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=5)
    core = venv.unwrapped.core
    act = np.tile(core.task.neutral_action(), (3, 1))
    for _ in range(5):
        core.step(act, venv.unwrapped.rngs)
    twin, twin_rngs = copy.deepcopy((core, venv.unwrapped.rngs))
    ep, g = twin.episodes, np.random.default_rng(0)
    twin.episodes = ep._replace(
        truth=ep.truth + g.normal(0, 20.0, ep.truth.shape),
        t_start=ep.t_start + 3.0,
        imu_scale=ep.imu_scale * 2.0,
        origin=ep.origin + 0.1,
        true_q=ep.true_q + 1.0,
        true_r=ep.true_r * 9.0,
        true_bias=ep.true_bias + 30.0,
    )
    for _ in range(4):
        o1, *_, i1 = core.step(act, venv.unwrapped.rngs)
        o2, *_, i2 = twin.step(act, twin_rngs)
        np.testing.assert_array_equal(o1, o2)
    assert not np.allclose(i1["pos_err_m"], i2["pos_err_m"])


# ---------------------------------------------------------------------------------- the v2 ids
def test_the_v2_ids_sample_v2_episodes_deterministically_and_keep_the_truth():
    env = gym.make("navgym/QuadrotorFading-v2")
    core = env.unwrapped.core
    p = core.platform
    assert p.true_noise and p.bias_features and p.imu_mismatch is None and core.penalize_remaining_steps
    doc = type(env.unwrapped).__doc__
    assert "v2 episodes" in doc and "* v2 (Fading, NoiseScale, Mixture)" in doc and "accel_bias_rate" in doc
    scenarios = []
    for _ in range(2):
        env.reset(seed=123)
        scenarios.append(core.scenarios[0])
        models = p.step_models(core.episodes, core.t)
        assert (
            models.truth is not None
            and models.truth.R.shape == (1, 6, 6)
            and models.truth.Q.shape == (1, 15, 15)
        )
    assert scenarios[0] == scenarios[1] and (scenarios[0].multipath or scenarios[0].bursts)
    v1 = gym.make("navgym/QuadrotorFading-v1").unwrapped.core
    v1.reset(np.zeros(1, dtype=np.int64), [np.random.default_rng(0)], [None])
    assert not v1.platform.true_noise and v1.platform.step_models(v1.episodes, v1.t).truth is None
    # an explicit mismatch is still taken on a v2 id
    assert gym.make(
        "navgym/QuadrotorNoiseScale-v2", imu_mismatch=(1.0, 2.0)
    ).unwrapped.core.platform.imu_mismatch == (1.0, 2.0)


def test_v2_vector_sub_env_i_equals_a_single_env_seeded_s_plus_i_through_the_events():
    """Over 30 s and an autoreset (the bias-rate cursor is restored with the episode)."""
    env_id, n, seed = "navgym/QuadrotorNoiseScale-v2", 3, 31
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=150)
    singles = [gym.make(env_id, max_episode_steps=150) for _ in range(n)]
    vobs, _ = venv.reset(seed=seed)
    for i, e in enumerate(singles):
        np.testing.assert_array_equal(vobs[i], e.reset(seed=seed + i)[0])
    rng = np.random.default_rng(0)
    done = np.zeros(n, dtype=bool)
    for _ in range(300):
        a = rng.uniform(-1.0, 1.0, (n, 2)).astype(np.float32)
        vobs, vr, vterm, vtrunc, _ = venv.step(a)
        for i, e in enumerate(singles):
            if done[i]:  # the vector env resets on the step after the end
                o, _ = e.reset()
                done[i] = False
            else:
                o, r, term, trunc, _ = e.step(a[i])
                assert vr[i] == r and vterm[i] == term and vtrunc[i] == trunc
                done[i] = term or trunc
            np.testing.assert_array_equal(vobs[i], o)
    assert venv.unwrapped.core.t.max() < 150  # an autoreset happened


def test_v2_episode_bytes_estimates_the_peak_of_a_reset():
    import tracemalloc

    T_, B_ = 1000, 2
    rngs = [np.random.default_rng(i) for i in range(B_)]
    QUADROTOR_V2.core("fading", B_, {"episode_steps": T_}).reset(np.arange(B_), rngs, [None] * B_)
    core = QUADROTOR_V2.core("fading", B_, {"episode_steps": T_})
    tracemalloc.start()
    try:
        core.reset(np.arange(B_), rngs, [None] * B_)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak <= B_ * core.platform.episode_bytes(T_) <= 4 * peak
