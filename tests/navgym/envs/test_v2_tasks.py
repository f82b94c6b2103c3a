"""The v2 tasks (#21): NoiseScale, the per-row Mixture and the clairvoyant reference.

Known answers on the linear toy of :mod:`tests.navgym.envs.toy_v2`: the neutral NoiseScale is the
plain filter bit for bit, ``s_r = k`` is the Kalman filter with ``k R`` (hand recursion), the
per-row Mixture with every weight 0 is the plain filter, and the clairvoyant told the nominal
noise is the plain filter while a known bias is subtracted from the measurements.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from filters import GaussianState
from filters import get as get_filter
from navgym.envs.platform import build_core
from navgym.envs.protocols import StepModels, TrueNoise
from navgym.envs.tasks import MixtureTask, NoiseScaleTask, NoTruthError, make_task
from navgym.envs.tasks.noise_scale import scale_motion_q
from navgym.scenarios import Outage, Scenario
from tests.navgym.envs.toy_v2 import TOY, ToyEnv, ToyVectorEnv

B = 5
#: The toy's state size.
N = 4


def _models(seed: int = 0, mask: np.ndarray | None = None, truth: TrueNoise | None = None) -> StepModels:
    rng = np.random.default_rng(seed)
    platform = TOY.platform("fading")
    z = rng.normal(0.0, 3.0, (B, 2))
    mask = np.ones((B, 2), dtype=bool) if mask is None else mask
    return StepModels(platform.model, platform.model, np.where(mask, z, np.nan), mask, 1.0, truth=truth)


def _state(seed: int = 1) -> GaussianState:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(B, 4, 4))
    return GaussianState(rng.normal(size=(B, 4)), A @ A.transpose(0, 2, 1) + np.eye(4))


def _kalman(state: GaussianState, models: StepModels, q: np.ndarray, r: np.ndarray, z=None):
    """One predict + update of the linear toy by hand, ``Q' = q Q`` and ``R' = r R`` per filter.

    Only the received rows (``models.mask``) enter the update.
    """
    model = models.transition
    F, H, Q, R = model.F(None, None, 1.0), model.H(None), model.Q, model.R
    z = models.z if z is None else z
    ms, Ps = [], []
    for b in range(B):
        m = F @ state.m[b]
        P = F @ state.P[b] @ F.T + q[b] * Q
        used = models.mask[b]
        if used.any():
            Hb, Rb = H[used], R[np.ix_(used, used)]
            S = Hb @ P @ Hb.T + r[b] * Rb
            K = P @ Hb.T @ np.linalg.inv(S)
            m, P = m + K @ (z[b, used] - Hb @ m), P - K @ S @ K.T
        ms.append(m)
        Ps.append(P)
    return np.array(ms), np.array(Ps)


# ------------------------------------------------------------------------------- NoiseScale
def test_noise_scale_maps_the_action_log_linearly_and_its_neutral_action_is_scale_one():
    task = NoiseScaleTask()
    a = np.array([[-1.0, 1.0], [1.0, -1.0], [1 / 3, 1 / 3]], dtype=np.float32)
    s, clipped = task.knob(a, 3)
    np.testing.assert_allclose(s, [[0.1, 100.0], [100.0, 0.1], [10.0, 10.0]], rtol=1e-6)
    assert not clipped.any()
    neutral = task.neutral_action()
    assert neutral.dtype == np.float32 and neutral == pytest.approx([-1 / 3, -1 / 3], abs=1e-7)
    s, _ = task.knob(np.tile(neutral, (4, 1)), 4)
    assert (s == 1.0).all()  # exactly: the float32 -1/3 snaps to s = 1
    other = NoiseScaleTask(q_scale_range=(1.0, 10.0), r_scale_range=(0.01, 1.0))
    np.testing.assert_array_equal(other.neutral_action(), [-1.0, 1.0])
    assert (other.knob(other.neutral_action()[None], 1)[0] == 1.0).all()
    assert [(f.name, f.low, f.high) for f in task.features()] == [
        ("log_q_scale", -1.0, 2.0),
        ("log_r_scale", -1.0, 2.0),
    ]


@pytest.mark.parametrize("filter_name", ["ekf", "kf", "iekf", "ukf", "ckf", "ghkf", "dd1", "dd2"])
def test_noise_scale_one_is_the_plain_filter_bit_for_bit(filter_name):
    task = NoiseScaleTask(filter=filter_name)
    state, models = _state(), _models(mask=np.array([[1, 1], [1, 0], [0, 0], [1, 1], [0, 1]], dtype=bool))
    knob, _ = task.knob(np.tile(task.neutral_action(), (B, 1)), B)
    out = task.step(state, knob, models, [])
    filt = get_filter(filter_name)
    pred = filt.predict(state, models.transition, None, models.dt)
    post, info = filt.update(pred, models.z, models.observation, mask=models.mask)
    np.testing.assert_array_equal(out.state.m, post.m)
    np.testing.assert_array_equal(out.state.P, post.P)
    np.testing.assert_array_equal(out.P_pred, pred.P)
    np.testing.assert_array_equal(out.info.nis, info.nis)


def test_noise_scale_env_with_the_neutral_action_is_the_plain_fading_env():
    scenario = Scenario(outages=(Outage(10.0, 18.0),), duration=40.0)
    plain, scaled = ToyEnv(task="fading"), ToyEnv(task="noisescale")
    plain.reset(seed=3, options={"scenario": scenario})
    scaled.reset(seed=3, options={"scenario": scenario})
    a = scaled.unwrapped.task.neutral_action()
    for _ in range(40):
        _, r1, _, _, i1 = plain.step(np.array([-1.0], dtype=np.float32))
        _, r2, _, _, i2 = scaled.step(a)
        assert r1 == r2
        for key in ("filtered_cov", "est_pos", "nis", "innovation"):
            np.testing.assert_array_equal(i1[key], i2[key])


@pytest.mark.parametrize("k", [10.0, 0.1, 100.0])
def test_noise_scale_r_k_and_q_k_are_the_kalman_filter_with_k_R_and_k_Q(k):
    task = NoiseScaleTask()
    exponent = np.log10(k)
    a_of = float((exponent + 1.0) / 3.0 * 2.0 - 1.0)  # the action of s = k for the range 0.1-100
    state, models = _state(), _models(mask=np.array([[1, 1], [1, 0], [0, 0], [1, 1], [0, 1]], dtype=bool))
    for column in (0, 1):
        a = np.tile(task.neutral_action().astype(np.float64), (B, 1))
        a[:, column] = a_of
        knob, _ = task.knob(a, B)
        np.testing.assert_allclose(knob[:, column], k, rtol=1e-12)
        assert (knob[:, 1 - column] == 1.0).all()
        out = task.step(state, knob, models, [])
        m, P = _kalman(state, models, knob[:, 0], knob[:, 1])
        np.testing.assert_allclose(out.state.m, m, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(out.state.P, P, rtol=1e-10, atol=1e-10)
        np.testing.assert_array_equal(out.diagnostics.q_scale, knob[:, 0])
        np.testing.assert_array_equal(out.diagnostics.r_scale, knob[:, 1])


def test_noise_scale_overflowing_prediction_fails_only_its_row():
    task = NoiseScaleTask(q_scale_range=(1e-6, 1e6))
    state = _state()
    big = GaussianState(state.m, state.P.copy())
    big.P[2] *= 1e307  # F P F^T overflows
    knob, _ = task.knob(np.array([[1.0, 0.0]] * B), B)
    out = task.step(big, knob, _models(), [])
    assert out.numerical_failure.tolist() == [False, False, True, False, False]
    assert not out.info.healthy[2] and np.isfinite(out.state.P[[0, 1, 3, 4]]).all()


def test_noise_scale_motion_q_scales_only_the_motion_states_process_noise():
    k = 100.0
    whole = NoiseScaleTask(q_scale_range=(0.1, 1e4))
    motion = NoiseScaleTask(q_scale_range=(0.1, 1e4), motion_q=True, process_states=(1,), n=N)
    state, models = _state(), _models()
    knob = np.tile([k, 1.0], (B, 1))
    Q = np.asarray(models.transition.Q)
    d = np.ones(N)
    d[1] = np.sqrt(k)
    want = d[:, None] * Q * d[None, :]
    for task, q in ((whole, k * Q), (motion, np.broadcast_to(want, Q.shape))):
        pred = task.predict(state, knob, models, None)
        ref = task.filter.predict(state, models.transition, None, models.dt, Q=q)
        np.testing.assert_allclose(pred.P, ref.P, rtol=1e-12)
    assert not np.allclose(want, k * Q)  # the two differ on this model
    with pytest.raises(ValueError, match="motion_q=True needs the platform's n"):
        NoiseScaleTask(motion_q=True)
    with pytest.raises(ValueError, match="process_states must be distinct states"):
        NoiseScaleTask(motion_q=True, process_states=(N,), n=N)


def test_scale_motion_q_of_a_shared_q_equals_the_dense_product_bit_for_bit():
    """A shared Q is scaled on its nonzero entries only: the same products, zeros elsewhere."""
    rng = np.random.default_rng(3)
    Q = np.diag(rng.uniform(0.1, 2.0, 6))
    Q[0, 3] = Q[3, 0] = 0.3  # a cross term, as an INS Q's position-velocity ones
    on = np.array([0.0, 1.0, 1.0, 1.0, 0.0, 0.0])
    s_q = 10.0 ** rng.uniform(-3.0, 3.0, (5, 1))
    d = 1.0 + on * (np.sqrt(s_q) - 1.0)
    dense = d[:, :, None] * Q * d[:, None, :]
    got = scale_motion_q(Q, on, s_q)
    np.testing.assert_array_equal(got, dense)
    assert not np.signbit(got).any()
    np.testing.assert_array_equal(scale_motion_q(np.broadcast_to(Q, (5, 6, 6)), on, s_q), dense)


def test_noise_scale_motion_q_on_a_v3_id_reads_the_platform_motion_states():
    env = gym.make("navgym/GpsInsRowScale-v3", task="noisescale", motion_q=True, q_scale_range=(0.1, 1e4))
    task = env.unwrapped.task
    np.testing.assert_array_equal(np.flatnonzero(task._on), [2, 3])  # GpsIns' velocity errors
    assert env.action_space.shape == (2,)
    env.close()


# ------------------------------------------------------------------------ per-row Mixture
def test_per_row_mixture_action_and_weights_on_the_outlier_rows_only():
    task = MixtureTask(per_row=True, m_max=3, outlier_rows=(0, 2), eps_max=0.4)
    assert task.action_space.shape == (3,)
    eps, _ = task.knob(np.array([[1.0, 1.0, 0.0], [-1.0, 0.5, 1.0]]), 2)
    np.testing.assert_allclose(eps, [[0.4, 0.0, 0.2], [0.0, 0.0, 0.4]])
    np.testing.assert_array_equal(task.neutral_action(), [-1.0, -1.0, -1.0])
    (feature,) = task.features()
    assert feature.name == "outlier_posterior" and feature.size == 3
    assert make_task("mixture", outlier_rows=(1,), m_max=4, per_row=True).action_space.shape == (4,)
    assert make_task("mixture", outlier_rows=(1,), m_max=4).action_space.shape == (1,)  # v0/v1


@pytest.mark.parametrize("base", ["ckf", "ekf", "ukf"])
def test_per_row_mixture_with_zero_weights_is_the_plain_filter(base):
    task = MixtureTask(filter=base, per_row=True, m_max=2)
    state, models = _state(), _models(mask=np.array([[1, 1], [1, 0], [0, 0], [1, 1], [0, 1]], dtype=bool))
    knob, _ = task.knob(np.tile(task.neutral_action(), (B, 1)), B)
    assert (knob == 0.0).all()
    out = task.step(state, knob, models, [])
    filt = get_filter(base)
    pred = filt.predict(state, models.transition, None, models.dt)
    post, info = filt.update(pred, models.z, models.observation, mask=models.mask)
    np.testing.assert_allclose(out.state.m, post.m, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(out.state.P, post.P, rtol=1e-10, atol=1e-10)
    np.testing.assert_array_equal(out.diagnostics.outlier_posterior, 0.0)
    np.testing.assert_array_equal(out.state.m[2], pred.m[2])  # no row received: the prediction


def test_per_row_mixture_calls_the_row_with_the_gross_error_an_outlier():
    task = MixtureTask(filter="ekf", per_row=True, m_max=2)
    models = _models()
    state = _state()
    z = models.transition.H(None) @ (models.transition.F(None, None, 1.0) @ state.m[:, :, None])
    z = z[:, :, 0].copy()
    z[:, 1] += 200.0  # row 1 of every filter: a gross error
    models = models._replace(z=z, mask=np.array([[1, 1]] * 4 + [[0, 1]], dtype=bool))
    knob, _ = task.knob(np.zeros((B, 2)), B)  # eps = 0.25 on both rows
    out = task.step(state, knob, models, [])
    post = out.diagnostics.outlier_posterior
    assert (post[:, 1] > 0.99).all() and (post[:4, 0] < 0.5).all()
    assert post[4, 0] == 0.0  # not received
    env = ToyEnv(task="mixture", per_row=True)
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert obs[env.unwrapped.observation_features.index("outlier_posterior")].shape == (2,)


# -------------------------------------------------------------------------- clairvoyant
@pytest.mark.parametrize(
    ("task", "kwargs", "plain"),
    [
        ("fading", {}, ("fading", {}, [-1.0])),
        ("noisescale", {}, ("fading", {}, [-1.0])),
        ("mixture", {"filter": "ekf"}, ("fading", {}, [-1.0])),
        ("mixture", {"filter": "ckf", "per_row": True}, ("noisescale", {"filter": "ckf"}, None)),
    ],
)
def test_clairvoyant_told_the_nominal_noise_is_the_plain_filter(task, kwargs, plain):
    scenario = Scenario(outages=(Outage(10.0, 18.0),), duration=40.0)
    reference = ToyEnv(task=plain[0], **plain[1])
    clairvoyant = ToyEnv(task=task, clairvoyant=True, **kwargs)
    reference.reset(seed=4, options={"scenario": scenario})
    clairvoyant.reset(seed=4, options={"scenario": scenario})
    a_ref = (
        np.array(plain[2], np.float32) if plain[2] is not None else reference.unwrapped.task.neutral_action()
    )
    rng = np.random.default_rng(0)
    for _ in range(40):
        _, r1, _, _, i1 = reference.step(a_ref)
        _, r2, _, _, i2 = clairvoyant.step(clairvoyant.action_space.sample() * 0 + rng.uniform(-1, 1))
        assert r1 == r2
        np.testing.assert_array_equal(i1["filtered_cov"], i2["filtered_cov"])
        np.testing.assert_array_equal(i1["est_pos"], i2["est_pos"])
    assert clairvoyant.unwrapped.task.filter_name.endswith("/clairvoyant")


@pytest.mark.parametrize("task", ["fading", "mixture", "noisescale"])
def test_clairvoyant_uses_the_true_noise_and_subtracts_the_known_bias(task):
    state = _state()
    truth = TrueNoise(
        np.broadcast_to(3.0 * 0.01 * np.eye(4), (B, 4, 4)).copy(),
        np.broadcast_to(np.diag([4.0, 25.0]), (B, 2, 2)).copy(),
        np.tile([5.0, -7.0], (B, 1)),
    )
    models = _models(truth=truth)
    rows = {"outlier_rows": (0, 1), "m_max": 2} if task == "mixture" else {}  # the platform's rows
    obj = make_task(task, clairvoyant=True, filter="ekf", **rows)
    knob, _ = obj.knob(np.tile(obj.action_space.sample(), (B, 1)), B)
    out = obj.step(state, knob, models, [])
    ekf = get_filter("ekf")
    pred = ekf.predict(state, models.transition, None, 1.0, Q=truth.Q)
    post, _ = ekf.update(pred, models.z - truth.bias, models.observation, R=truth.R)
    np.testing.assert_array_equal(out.state.m, post.m)
    np.testing.assert_array_equal(out.state.P, post.P)
    # the same by hand: R' = diag(4, 25) = r R with sigma = 3 is not a scalar multiple; check Q, bias
    m, P = _kalman(state, models._replace(truth=None), np.full(B, 3.0), np.ones(B), z=models.z - truth.bias)
    ekf_nominal_r, _ = ekf.update(pred, models.z - truth.bias, models.observation)
    np.testing.assert_allclose(ekf_nominal_r.m, m, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(ekf_nominal_r.P, P, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("task", ["fading", "mixture", "noisescale"])
def test_clairvoyant_without_truth_raises_a_clear_error(task):
    env = ToyEnv(task=task, clairvoyant=True, gives_truth=False)
    env.reset(seed=0)
    with pytest.raises(NoTruthError, match=r"clairvoyant=True\) .*StepModels\.truth is None"):
        env.step(env.action_space.sample())
    venv = ToyVectorEnv(num_envs=2, task=task, clairvoyant=True, gives_truth=False)
    venv.reset(seed=0)
    with pytest.raises(NoTruthError, match="v2"):
        venv.step(venv.action_space.sample())


def test_clairvoyant_with_a_bias_beats_the_plain_filter_on_biased_fixes():
    """With a 20 m bias in the fixes the plain filter is off by about the bias; the clairvoyant is not."""
    kwargs = {"bias": (20.0, -20.0), "outage_probability": 0.0}
    plain, clairvoyant = ToyEnv(task="fading", **kwargs), ToyEnv(task="fading", clairvoyant=True, **kwargs)
    plain.reset(seed=1)
    clairvoyant.reset(seed=1)
    e_plain, e_clair = [], []
    for _ in range(40):
        e_plain.append(plain.step(np.array([-1.0], np.float32))[4]["pos_err_m"])
        e_clair.append(clairvoyant.step(np.array([1.0], np.float32))[4]["pos_err_m"])
    assert np.mean(e_plain[10:]) > 20.0 > 5.0 > np.mean(e_clair[10:])


# ------------------------------------------------------------------ checker and arguments
@pytest.mark.parametrize(
    ("task", "kwargs"),
    [
        ("noisescale", {}),
        ("noisescale", {"filter": "ckf", "memory_features": True}),
        ("noisescale", {"clairvoyant": True}),
        ("mixture", {"per_row": True, "memory_features": True}),
        ("fading", {"memory_features": True, "clairvoyant": True}),
        ("resample", {"memory_features": True, "n_particles": 50}),
    ],
)
def test_new_tasks_pass_the_checker_and_vector_equals_single(task, kwargs):
    env = ToyEnv(task=task, **kwargs)
    check_env(env, skip_render_check=True)
    venv = ToyVectorEnv(num_envs=3, task=task, **kwargs)
    obs, _ = venv.reset(seed=11)
    singles = [ToyEnv(task=task, **kwargs) for _ in range(3)]
    for i, e in enumerate(singles):
        np.testing.assert_array_equal(obs[i], e.reset(seed=11 + i)[0])
    venv.action_space.seed(0)
    for _ in range(6):
        a = venv.action_space.sample()
        obs, reward, *_ = venv.step(a)
        for i, e in enumerate(singles):
            o, r, *_ = e.step(a[i])
            np.testing.assert_array_equal(obs[i], o)
            assert reward[i] == r


BAD = [
    ("noisescale", "q_scale_range", (1.0, 1.0)),
    ("noisescale", "q_scale_range", (2.0, 10.0)),
    ("noisescale", "q_scale_range", (0.1, 0.5)),
    ("noisescale", "q_scale_range", (0.0, 10.0)),
    ("noisescale", "q_scale_range", (-1.0, 10.0)),
    ("noisescale", "q_scale_range", (0.1, np.inf)),
    ("noisescale", "q_scale_range", (0.1, np.nan)),
    ("noisescale", "q_scale_range", (1e-10, 1e10)),
    ("noisescale", "q_scale_range", (10.0, 0.1)),
    ("noisescale", "q_scale_range", 10.0),
    ("noisescale", "q_scale_range", (0.1,)),
    ("noisescale", "q_scale_range", ("0.1", 10)),
    ("noisescale", "q_scale_range", (True, 10)),
    ("noisescale", "r_scale_range", (1.0, 1.0)),
    ("noisescale", "r_scale_range", (0.5, 0.9)),
    ("noisescale", "r_scale_range", None),
    ("noisescale", "filter", "pf"),
    ("noisescale", "clairvoyant", "yes"),
    ("noisescale", "clairvoyant", 1),
    ("fading", "clairvoyant", None),
    ("mixture", "clairvoyant", np.nan),
    ("mixture", "per_row", "True"),
    ("mixture", "per_row", 1),
    ("fading", "memory_features", "no"),
    ("resample", "memory_features", 0),
]


@pytest.mark.parametrize(("task", "name", "value"), BAD, ids=[f"{t}-{n}={v!r}" for t, n, v in BAD])
@pytest.mark.parametrize("vector", [False, True], ids=["single", "vector"])
def test_a_bad_v2_argument_fails_at_construction_naming_it(task, name, value, vector):
    with pytest.raises((TypeError, ValueError), match=name) as caught:
        if vector:
            ToyVectorEnv(num_envs=2, task=task, **{name: value})
        else:
            ToyEnv(task=task, **{name: value})
    assert "got" in str(caught.value)


def test_arguments_a_task_does_not_take_are_refused_and_per_row_needs_m_max():
    with pytest.raises(TypeError, match="unexpected keyword arguments: \\['per_row'\\]"):
        ToyEnv(task="fading", per_row=True)
    with pytest.raises(TypeError, match="clairvoyant"):
        ToyEnv(task="resample", clairvoyant=True)
    with pytest.raises(ValueError, match="m_max"):
        MixtureTask(per_row=True)
    with pytest.raises(ValueError, match="outlier_rows"):
        MixtureTask(per_row=True, m_max=2, outlier_rows=(2,))
    core = build_core(
        TOY, "noisescale", 2, {"q_scale_range": [0.5, 2], "r_scale_range": np.array([1.0, 4.0])}
    )
    assert core.task.q_scale_range == (0.5, 2.0) and core.task.r_scale_range == (1.0, 4.0)
    np.testing.assert_allclose(core.task.neutral_action(), [0.0, -1.0], atol=1e-7)


def test_cards_document_the_new_task_and_arguments():
    flat = " ".join(ToyEnv.__doc__.split())
    assert "``NoiseScale``: ``Box(-1, 1, (2,), float32)``" in flat and "Gao et al. 2020" in flat
    assert "``ToyV2NoiseScale`` (11 columns)" in flat
    for text in ("``q_scale_range=(0.1, 100)``", "``per_row=False``", "``clairvoyant=False``"):
        assert text in flat
    assert "never a baseline" in flat and "``memory_features=False``" in flat
