"""Robot2d under the v2 within-episode events: truth, measurements and ``StepModels.truth``.

Known answers on pinned scenarios (a multipath bias shifts its row by exactly its size there and
nowhere else; a burst adds motion error only inside it; the jamming ramp's profile; a canyon's
cap, noise and losses), the true noise handed to the evaluation against what the simulator drew
(residual statistics over many episodes), and the cheap path: without ``true_noise`` the truth is
None, and an episode without events is simulated bit for bit as before.
"""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

from navgym.envs.registration import V2_ENVIRONMENTS
from navgym.ins.attitude import wrap_angle
from navgym.robot2d.env import V2_EVENTS
from navgym.robot2d.models import FixCompassModel
from navgym.robot2d.platform import GNSS_ROWS, Robot2dPlatform
from navgym.scenarios import Jamming, MotionBurst, Multipath, Scenario, ScenarioDistribution, UrbanCanyon
from tests.navgym.envs.no_truth import assert_truth_not_observed

T = 600
DT = 0.1
B = 32
SEEDS = list(range(500, 500 + B))
TIMES = np.arange(T + 1) * DT
ROUND = 1e-9  # differences that must vanish to rounding [m, rad]
#: Relative tolerance of a sample variance from ~3000 draws (its standard error is 2.6 %).
VAR_RTOL = 0.1


def _sim(scenario: Scenario | list[Scenario], true_noise: bool = True, seeds=SEEDS, **kw):
    p = Robot2dPlatform(true_noise=true_noise, **kw)
    scen = scenario if isinstance(scenario, list) else [scenario] * len(seeds)
    return p, p.simulate([np.random.default_rng(s) for s in seeds], scen, T)


def _inside(start: float, end: float) -> np.ndarray:
    return (TIMES >= start - 1e-9) & (TIMES < end - 1e-9)


BASE = Scenario(duration=60.0)


# ------------------------------------------------------------------------------ multipath
def test_multipath_shifts_its_row_by_its_bias_there_and_nowhere_else():
    """A 10 m bias on GPS N between 5 and 15 s: that row moves by 10 m there, nothing else moves."""
    pinned = dataclasses.replace(BASE, multipath=(Multipath(5.0, 15.0, row=0, bias=10.0),))
    p, a = _sim(BASE)
    _, b = _sim(pinned)
    np.testing.assert_array_equal(a.mask, b.mask)
    np.testing.assert_array_equal(a.truth_pos, b.truth_pos)
    d = np.where(b.mask, b.z - a.z, 0.0)
    inside = _inside(5.0, 15.0)
    np.testing.assert_allclose(d[:, inside, 0][b.mask[:, inside, 0]], 10.0, atol=ROUND)
    assert np.abs(d[:, ~inside, 0]).max() <= ROUND and np.abs(d[..., 1:]).max() == 0.0
    # the mean error of the row: 10 m inside (3200 fixes, standard error 0.05 m), 0 outside
    err = b.z[..., 0] - b.truth_pos[..., 0]
    ok = b.mask[..., 0]
    assert np.mean(err[:, inside][ok[:, inside]]) == pytest.approx(10.0, abs=0.25)
    assert np.mean(err[:, ~inside][ok[:, ~inside]]) == pytest.approx(0.0, abs=0.15)
    # and the truth handed to the evaluation says so at the measurement epoch t + 1
    for t in (40, 49, 50, 148, 149, 300):
        truth = p.step_models(b, np.full(B, t)).truth
        expected = 10.0 if 5.0 <= (t + 1) * DT < 15.0 - 1e-9 else 0.0
        np.testing.assert_array_equal(truth.bias, np.tile([expected, 0, 0, 0, 0], (B, 1)))


# ---------------------------------------------------------------------------------- bursts
def test_a_burst_adds_motion_error_only_inside_it():
    """Slip of 2 m/s and 0.2 rad/s between 10 and 20 s: white errors of 0.2 m and 0.02 rad per step."""
    burst = MotionBurst(10.0, 20.0, velocity_sigma=2.0, yaw_rate_sigma=0.2)
    p, a = _sim(BASE)
    _, b = _sim(dataclasses.replace(BASE, bursts=(burst,)))
    first = int(round(10.0 / DT))  # the first step k -> k + 1 that starts inside
    np.testing.assert_array_equal(a.truth_pos[:, : first + 1], b.truth_pos[:, : first + 1])
    np.testing.assert_array_equal(a.encoder, b.encoder)  # the wheel does not see the slip
    np.testing.assert_array_equal(a.steering, b.steering)
    psi = b.truth_heading - a.truth_heading
    yaw = np.diff(psi, axis=1)
    dp0 = np.diff(a.truth_pos, axis=1)
    c, s = np.cos(psi[:, :-1]), np.sin(psi[:, :-1])
    turned = np.stack([c * dp0[..., 0] - s * dp0[..., 1], s * dp0[..., 0] + c * dp0[..., 1]], axis=-1)
    w = np.diff(b.truth_pos, axis=1) - turned  # the step's error beyond the (turned) commanded motion
    steps = _inside(10.0, 20.0)[:-1]
    assert np.abs(yaw[:, ~steps]).max() <= ROUND and np.abs(w[:, ~steps]).max() <= 1e-8
    assert np.var(yaw[:, steps]) == pytest.approx(0.02**2, rel=VAR_RTOL)
    assert np.var(w[:, steps]) == pytest.approx(0.2**2, rel=VAR_RTOL)
    assert abs(np.mean(w[:, steps])) < 0.02
    # the compass sees the turned heading
    ok = b.mask[..., 4]
    np.testing.assert_allclose(wrap_angle(b.z[..., 4] - a.z[..., 4])[ok], wrap_angle(psi)[ok], atol=ROUND)
    # StepModels.truth: the nominal Q plus diag(0.2^2, 0.2^2, 0.02^2) inside, the nominal Q outside
    for t in (first - 1, first, 150, 199, 200):
        m = p.step_models(b, np.full(B, t))
        extra = np.diag([0.04, 0.04, 0.0004]) if 10.0 <= t * DT < 20.0 - 1e-9 else np.zeros((3, 3))
        np.testing.assert_allclose(m.truth.Q - m.transition.Q, np.broadcast_to(extra, (B, 3, 3)), atol=1e-15)


# --------------------------------------------------------------------------------- jamming
def test_jamming_ramp_profile_in_the_fix_noise():
    """Jamming of 20 m with 5 s ramps between 10 and 30 s: the GPS noise follows the profile."""
    jam = Jamming(10.0, 30.0, jam_sigma=20.0, loss_prob=0.0, ramp=5.0)
    p, a = _sim(BASE)
    _, b = _sim(dataclasses.replace(BASE, jamming=(jam,)))
    np.testing.assert_array_equal(a.mask, b.mask)
    e_a = a.z[..., 0] - a.truth_pos[..., 0]
    e_b = b.z[..., 0] - b.truth_pos[..., 0]
    usable = a.mask[..., 0] & (np.abs(e_a) > 1e-3)
    ratio = np.where(usable, e_b / np.where(usable, e_a, 1.0), 1.0)
    profile = np.sqrt(np.maximum(ratio**2 - 1.0, 0.0)) * 3.0 / 20.0
    expected = np.array([jam.profile(t) for t in TIMES])
    np.testing.assert_allclose(profile[usable], np.broadcast_to(expected, usable.shape)[usable], atol=1e-6)
    assert (
        expected[125] == pytest.approx(0.5) and expected[200] == 1.0 and expected[275] == pytest.approx(0.5)
    )
    for t in (99, 124, 199, 274, 300):
        R = p.step_models(b, np.full(B, t)).truth.R
        k = t + 1
        np.testing.assert_allclose(R[:, 0, 0], 9.0 + (20.0 * expected[k]) ** 2, rtol=1e-12)
        np.testing.assert_allclose(R[:, 2, 2], 25.0 + (20.0 * expected[k]) ** 2, rtol=1e-12)


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
    gnss = list(GNSS_ROWS)
    assert not b.mask[:, _inside(10.0, 20.0)][..., gnss].any() and a.mask[:, _inside(10.0, 20.0), 0].all()
    noisy = _inside(30.0, 40.0)
    ok = a.mask[:, noisy][..., gnss]
    e_a = (a.z - a.truth_pos[..., [0, 1, 0, 1, 0]])[:, noisy][..., gnss]
    e_b = (b.z - b.truth_pos[..., [0, 1, 0, 1, 0]])[:, noisy][..., gnss]
    np.testing.assert_allclose(e_b[ok], 3.0 * e_a[ok], rtol=1e-9, atol=ROUND)
    lossy = _inside(45.0, 55.0)
    kept = b.mask[:, lossy, 0].sum() / a.mask[:, lossy, 0].sum()
    assert kept == pytest.approx(0.5, abs=0.05)  # 3200 scheduled fixes
    R = p.step_models(b, np.full(B, 349)).truth.R  # epoch 35 s
    np.testing.assert_allclose(
        np.diagonal(R, axis1=1, axis2=2)[:, gnss], np.tile([81.0, 81, 225, 225], (B, 1))
    )


# ----------------------------------------------------------------------- the truth handed out
def _true_noise_residuals(seed: int = 0, n: int = 64):
    """Standardized residuals of every delivered row over ``n`` v2 episodes (random events)."""
    dist = ScenarioDistribution(duration=60.0, start_margin=6.0, **V2_EVENTS)
    p = Robot2dPlatform(true_noise=True, scenarios=dist)
    rngs = [np.random.default_rng(seed + i) for i in range(n)]
    ep = p.simulate(rngs, p.sample_scenarios(rngs), T)
    rows = {r: [] for r in range(5)}
    inflated = []
    for t in range(T):
        m = p.step_models(ep, np.full(n, t))
        k = t + 1
        err = m.z - ep.truth_pos[:, k][:, [0, 1, 0, 1, 0]]
        err[:, 4] = wrap_angle(m.z[:, 4] - ep.truth_heading[:, k])
        R = np.diagonal(m.truth.R, axis1=1, axis2=2)
        u = (err - m.truth.bias) / np.sqrt(R)
        for r in range(5):
            rows[r].append(u[m.mask[:, r], r])
        big = m.mask & (R > 4 * np.diag(p.R()))
        inflated.append(u[big])
    return {r: np.concatenate(v) for r, v in rows.items()}, np.concatenate(inflated)


def test_step_models_truth_is_what_the_simulator_used():
    """``(z - h(truth) - truth.bias) / sqrt(truth.R_ii)`` is standard normal, row by row."""
    rows, inflated = _true_noise_residuals()
    for r, u in rows.items():
        assert u.size > 5000, r
        assert np.mean(u) == pytest.approx(0.0, abs=0.05), r
        assert np.var(u) == pytest.approx(1.0, rel=0.06), r
    assert inflated.size > 2000  # the jammed, canyon and multipath epochs on their own
    assert np.mean(inflated) == pytest.approx(0.0, abs=0.08) and np.var(inflated) == pytest.approx(
        1.0, rel=0.08
    )


def test_truth_only_with_true_noise_and_nominal_without_events():
    p, a = _sim(BASE, true_noise=False)
    assert a.true_q is None and a.true_r is None and a.true_bias is None
    assert p.step_models(a, np.zeros(B, dtype=np.int64)).truth is None
    p2, b = _sim(BASE)
    for t in (0, 77, 599):
        m = p2.step_models(b, np.full(B, t))
        np.testing.assert_array_equal(m.truth.Q, m.transition.Q)
        np.testing.assert_array_equal(m.truth.R, np.broadcast_to(p2.R(), (B, 5, 5)))
        np.testing.assert_array_equal(m.truth.bias, 0.0)
        # everything the filter sees is the same with and without the truth kept
        m0 = p.step_models(a, np.full(B, t))
        np.testing.assert_array_equal(m.z, m0.z)
        np.testing.assert_array_equal(m.transition.Q, m0.transition.Q)
    assert p2.episode_bytes(T) > p.episode_bytes(T)


def test_episodes_without_events_are_simulated_as_before_in_any_batch():
    """The general path (events in the batch, truth kept) equals the cheap one bit for bit."""
    events = dataclasses.replace(
        BASE,
        bursts=(MotionBurst(10.0, 20.0, 2.0, 0.2),),
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
        if getattr(single, name) is None:  # the v3 context (context=False here)
            assert getattr(mixed, name) is None
            continue
        np.testing.assert_array_equal(getattr(mixed, name)[1], getattr(single, name)[0], err_msg=name)


def test_a_multipath_row_beyond_the_gnss_rows_is_refused():
    with pytest.raises(ValueError, match="GNSS rows"):
        _sim(dataclasses.replace(BASE, multipath=(Multipath(5.0, 15.0, 4, 1.0),)), seeds=[0])
    with pytest.raises(ValueError, match="row 7"):
        _sim(dataclasses.replace(BASE, multipath=(Multipath(5.0, 15.0, 7, 1.0),)), seeds=[0])


# ------------------------------------------------------------------------ the clairvoyant gap
class Clairvoyant:
    """A platform whose step models are the true ones: Q, R and z minus the bias of ``truth``."""

    def __init__(self, platform):
        self.platform = platform

    def __getattr__(self, name):
        return getattr(self.platform, name)

    def step_models(self, ep, t):
        m = self.platform.step_models(ep, t)
        tr = m.truth
        return m._replace(
            transition=m.transition._replace(Q=tr.Q), observation=FixCompassModel(tr.R), z=m.z - tr.bias
        )


def _clairvoyant_rmse(B_: int = 32) -> tuple[float, float]:
    """Mean position RMSE of the plain EKF and of one told the true Q, R and bias (same episodes)."""
    from navgym.robot2d.env_v2 import ROBOT2D_V2

    out = []
    for clairvoyant in (False, True):
        core = ROBOT2D_V2.core("fading", B_)
        if clairvoyant:
            core.platform = Clairvoyant(core.platform)
        rngs = [np.random.default_rng(1000 + i) for i in range(B_)]
        core.reset(np.arange(B_), rngs, [None] * B_)
        err = [core.step(np.full((B_, 1), -1.0), rngs)[4]["pos_err_m"] for _ in range(core.T)]
        out.append(float(np.sqrt(np.mean(np.square(err), axis=0)).mean()))
    return out[0], out[1]


def test_the_clairvoyant_filter_clearly_beats_the_plain_one_on_v2_episodes():
    """What v2 is for: knowing the true noise pays (measured 5.3 -> 1.0 m on 32 episodes)."""
    plain, told = _clairvoyant_rmse()
    assert told < 0.5 * plain and plain > 2.0


# ---------------------------------------------------------------------------------- the v2 id
V2_ID = "navgym/Robot2dFading-v2"


def test_the_v2_id_samples_v2_episodes_deterministically_and_keeps_the_truth():
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the ids

    env = gym.make(V2_ID)
    core = env.unwrapped.core
    assert core.platform.true_noise and core.penalize_remaining_steps and core.T == 600
    assert (
        "v2 episodes" in type(env.unwrapped).__doc__
        and "* v2 (Fading, NoiseScale, Mixture, Resample)" in type(env.unwrapped).__doc__
    )
    scenarios = []
    for _ in range(2):
        env.reset(seed=123)
        scenarios.append(core.scenarios[0])
        models = core.platform.step_models(core.episodes, core.t)
        assert models.truth is not None and models.truth.R.shape == (1, 5, 5)
    assert scenarios[0] == scenarios[1] and scenarios[0].multipath and scenarios[0].bursts
    v1 = gym.make("navgym/Robot2dFading-v1").unwrapped.core
    v1.reset(np.zeros(1, dtype=np.int64), [np.random.default_rng(0)], [None])
    assert not v1.platform.true_noise and v1.platform.step_models(v1.episodes, v1.t).truth is None


def test_v2_vector_sub_env_i_equals_a_single_env_seeded_s_plus_i_through_the_events():
    """Over 30 s (the registry test covers the first 6 s, before any event can start)."""
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the ids

    n, seed, steps = 3, 31, 300
    venv = gym.make_vec(V2_ID, num_envs=n, vectorization_mode="vector_entry_point")
    singles = [gym.make(V2_ID) for _ in range(n)]
    vobs, _ = venv.reset(seed=seed)
    for i, e in enumerate(singles):
        np.testing.assert_array_equal(vobs[i], e.reset(seed=seed + i)[0])
    assert all(s.multipath or s.bursts or s.canyons for s in venv.unwrapped.core.scenarios)
    rng = np.random.default_rng(0)
    for _ in range(steps):
        a = rng.uniform(-1.0, 1.0, (n, 1)).astype(np.float32)
        vobs, vr, vterm, vtrunc, vinfo = venv.step(a)
        for i, e in enumerate(singles):
            o, r, term, trunc, info = e.step(a[i])
            np.testing.assert_array_equal(vobs[i], o)
            assert vr[i] == r and vterm[i] == term and vinfo["pos_err_m"][i] == info["pos_err_m"]


def test_v2_episode_bytes_estimates_the_peak_of_a_reset():
    """As the registry-wide check for the v0/v1 declaration: between the peak and four times it."""
    import tracemalloc

    from navgym.robot2d.env_v2 import ROBOT2D_V2

    T_, B_ = 1000, 2
    rngs = [np.random.default_rng(i) for i in range(B_)]
    ROBOT2D_V2.core("fading", B_, {"episode_steps": T_}).reset(np.arange(B_), rngs, [None] * B_)
    core = ROBOT2D_V2.core("fading", B_, {"episode_steps": T_})
    tracemalloc.start()
    try:
        core.reset(np.arange(B_), rngs, [None] * B_)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak <= B_ * core.platform.episode_bytes(T_) <= 4 * peak


# ------------------------------------------------------------------------ no truth in the observation
V2_IDS = [e[0] for e in V2_ENVIRONMENTS if e[2] == "Robot2d"]


@pytest.mark.parametrize("env_id", V2_IDS)
def test_observation_carries_no_truth(env_id):
    """Perturb every truth-only array of the v2 episodes in a copy: the observation is unchanged."""
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=5)
    core = venv.unwrapped.core
    act = core.task.neutral_action()
    act = np.full(3, act) if np.ndim(act) == 0 else np.tile(act, (3, 1))
    for _ in range(5):
        core.step(act, venv.unwrapped.rngs)

    def perturb(ep):
        assert ep.true_r is not None  # the v2 ids keep the truth
        return ep._replace(
            truth_pos=ep.truth_pos + 40.0,
            truth_heading=ep.truth_heading + 0.5,
            truth_scale=ep.truth_scale + 0.1,
            true_q=ep.true_q + 1.0,
            true_r=ep.true_r * 9.0,
            true_bias=ep.true_bias + 30.0,
        )

    assert_truth_not_observed(core, venv.unwrapped.rngs, act, perturb)
