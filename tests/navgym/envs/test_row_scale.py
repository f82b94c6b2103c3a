"""The RowScale task (v3): one R multiplier per row and a scale of the motion states' Q.

Known answers on the linear toy of :mod:`tests.navgym.envs.toy_v2` (state: position 0-1,
velocity 2-3; two fix rows): every scale 1 is the plain filter bit for bit; ``s_i`` on one row
and ``s_q`` on the motion states are the Kalman filter with that row's variance and those
states' process noise scaled (a hand recursion); a row at the top of its range is all but
excluded; the mapping and its inverse; the arguments' errors name them.
"""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from filters import GaussianState
from filters import get as get_filter
from navgym.envs.platform import build_core
from navgym.envs.protocols import StepModels
from navgym.envs.tasks import RowScaleTask, make_task
from tests.navgym.envs.toy_v2 import TOY, ToyEnv, ToyVectorEnv

B = 5
MASK = np.array([[1, 1], [1, 0], [0, 0], [1, 1], [0, 1]], dtype=bool)


def _task(**kwargs) -> RowScaleTask:
    return RowScaleTask(m_max=2, n=4, process_states=(2, 3), **kwargs)


def _models(seed: int = 0, mask: np.ndarray = MASK) -> StepModels:
    rng = np.random.default_rng(seed)
    model = TOY.platform("rowscale").model
    z = rng.normal(0.0, 3.0, (B, 2))
    return StepModels(model, model, np.where(mask, z, np.nan), mask, 1.0)


def _state(seed: int = 1) -> GaussianState:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(B, 4, 4))
    return GaussianState(rng.normal(size=(B, 4)), A @ A.transpose(0, 2, 1) + np.eye(4))


def _kalman(state: GaussianState, models: StepModels, s_rows: np.ndarray, s_q: np.ndarray):
    """Predict + update of the toy by hand: ``R_ii s_i`` per row, ``Q`` of the velocity ``s_q``."""
    model = models.transition
    F, H, Q, R = model.F(None, None, 1.0), model.H(None), model.Q, model.R
    ms, Ps = [], []
    for b in range(B):
        d = np.sqrt(np.array([1.0, 1.0, s_q[b], s_q[b]]))
        m = F @ state.m[b]
        P = F @ state.P[b] @ F.T + np.outer(d, d) * Q
        used = models.mask[b]
        if used.any():
            r = np.sqrt(s_rows[b, used])
            Hb, Rb = H[used], np.outer(r, r) * R[np.ix_(used, used)]
            S = Hb @ P @ Hb.T + Rb
            K = P @ Hb.T @ np.linalg.inv(S)
            m, P = m + K @ (models.z[b, used] - Hb @ m), P - K @ S @ K.T
        ms.append(m)
        Ps.append(P)
    return np.array(ms), np.array(Ps)


def test_the_action_maps_log_linearly_per_entry_and_its_neutral_action_is_every_scale_one():
    task = _task()
    assert task.action_space.shape == (3,)
    s, clipped = task.knob(np.array([[-1.0, 1.0, -1.0], [1.0, -1.0, 1.0]], dtype=np.float32), 2)
    np.testing.assert_allclose(s, [[0.3, 1e4, 0.1], [1e4, 0.3, 1e4]], rtol=1e-6)
    assert not clipped.any()
    neutral = task.neutral_action()
    assert neutral.dtype == np.float32
    knob, _ = task.knob(np.tile(neutral, (4, 1)), 4)
    assert (knob == 1.0).all()  # exactly: the float32 neutral action snaps to s = 1
    scales = np.array([[2.0, 500.0, 30.0], [0.5, 1.0, 0.2]])
    np.testing.assert_allclose(task.knob_of(task.actions_of(scales).astype(np.float64)), scales, rtol=1e-5)
    assert [(f.name, f.size) for f in task.features()] == [("log_row_scale", 2), ("log_process_scale", 1)]


@pytest.mark.parametrize("filter_name", ["ekf", "kf", "ukf", "ckf"])
def test_every_scale_one_is_the_plain_filter_bit_for_bit(filter_name):
    task = _task(filter=filter_name)
    state, models = _state(), _models()
    knob, _ = task.knob(np.tile(task.neutral_action(), (B, 1)), B)
    out = task.step(state, knob, models, [])
    filt = get_filter(filter_name)
    pred = filt.predict(state, models.transition, None, models.dt)
    post, info = filt.update(pred, models.z, models.observation, mask=models.mask)
    np.testing.assert_array_equal(out.state.m, post.m)
    np.testing.assert_array_equal(out.state.P, post.P)
    np.testing.assert_array_equal(out.info.nis, info.nis)


def test_row_scales_and_the_process_scale_are_the_kalman_filter_with_those_variances():
    task = _task()
    rng = np.random.default_rng(4)
    scales = np.column_stack([10 ** rng.uniform(-0.5, 4.0, (B, 2)), 10 ** rng.uniform(-1.0, 4.0, B)])
    knob, _ = task.knob(task.actions_of(scales), B)
    state, models = _state(), _models()
    out = task.step(state, knob, models, [])
    m, P = _kalman(state, models, knob[:, :2], knob[:, 2])
    np.testing.assert_allclose(out.state.m, m, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(out.state.P, P, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(out.diagnostics.r_scale, knob[:, :2])
    np.testing.assert_array_equal(out.diagnostics.q_scale, knob[:, 2])
    # the position block's process noise is untouched by s_q: the position-only Q entries
    pred_plain = get_filter("ekf").predict(state, models.transition, None, 1.0)
    q_only = _task()
    k2 = q_only.knob(q_only.actions_of(np.array([[1.0, 1.0, 1e3]] * B)), B)[0]
    pred = q_only.predict(state, k2, models, None)
    np.testing.assert_allclose(pred.P[:, :2, :2], pred_plain.P[:, :2, :2], rtol=1e-12)
    assert (
        np.diagonal(pred.P, axis1=1, axis2=2)[:, 2:] > np.diagonal(pred_plain.P, axis1=1, axis2=2)[:, 2:]
    ).all()


def test_a_row_at_the_top_of_its_range_is_all_but_excluded():
    task = _task()
    state, models = _state(), _models(mask=np.ones((B, 2), dtype=bool))
    knob, _ = task.knob(task.actions_of(np.array([[1e4, 1.0, 1.0]] * B)), B)
    out = task.step(state, knob, models, [])
    only_row_1 = _models(mask=np.tile([False, True], (B, 1)))
    filt = get_filter("ekf")
    post, _ = filt.update(
        filt.predict(state, models.transition, None, 1.0),
        only_row_1.z,
        models.observation,
        mask=only_row_1.mask,
    )
    # s = 1e4 (a 100-fold sigma) leaves row 0 a weight of about 1e-4 of its plain one
    np.testing.assert_allclose(out.state.m, post.m, atol=0.05)
    plain, _ = filt.update(
        filt.predict(state, models.transition, None, 1.0), models.z, models.observation, mask=models.mask
    )
    assert np.abs(out.state.m - post.m).max() < 0.01 * np.abs(plain.m - post.m).max()


def test_the_env_passes_the_checker_and_the_vector_env_equals_single_envs():
    env = ToyEnv(task="rowscale")
    assert env.action_space.shape == (3,)
    check_env(env, skip_render_check=True)
    venv = ToyVectorEnv(num_envs=3, task="rowscale")
    obs, _ = venv.reset(seed=5)
    singles = [ToyEnv(task="rowscale") for _ in range(3)]
    for i, e in enumerate(singles):
        np.testing.assert_array_equal(obs[i], e.reset(seed=5 + i)[0])
    rng = np.random.default_rng(0)
    for _ in range(6):
        a = rng.uniform(-1, 1, (3, 3)).astype(np.float32)
        obs, r, *_ = venv.step(a)
        for i, e in enumerate(singles):
            o, ri, *_ = e.step(a[i])
            np.testing.assert_array_equal(obs[i], o)
            assert r[i] == ri


def test_the_clairvoyant_ignores_the_knob_and_uses_the_true_noise():
    core = build_core(TOY, "rowscale", 2, {"clairvoyant": True, "truth_r_scale": 4.0})
    task = core.task
    knob, _ = task.knob(np.ones((2, 3), dtype=np.float32), 2)
    assert (knob == 1.0).all()


@pytest.mark.parametrize(
    ("name", "value", "match"),
    [
        ("r_scale_range", (2.0, 10.0), "r_scale_range"),
        ("q_scale_range", (1e-7, 1e7), "q_scale_range"),
        ("r_scale_range", "wide", "r_scale_range"),
    ],
)
def test_a_bad_range_is_refused_naming_it(name, value, match):
    with pytest.raises((ValueError, TypeError), match=match):
        ToyEnv(task="rowscale", **{name: value})


def test_the_task_needs_the_platform_rows_and_states():
    with pytest.raises(ValueError, match="m_max, n and process_noise_states"):
        make_task("rowscale")
    with pytest.raises(ValueError, match="process_states"):
        RowScaleTask(m_max=2, n=4, process_states=(4,))
    core = build_core(TOY, "rowscale", 1, {})
    assert core.task.process_states == (0, 1, 2, 3)  # the platform's default: every state


def test_the_regime_oracle_sets_each_rows_scale_from_its_true_regime():
    table = (1.0, 30.0, 1e4, 1.0, 100.0)
    task = _task(regime_oracle=table)
    model = TOY.platform("rowscale").model
    Q, R = np.asarray(model.Q), np.asarray(model.R)
    truth_R = np.tile(R, (B, 1, 1))
    truth_R[1, 0, 0] *= 5.0  # episode 1, row 0: noisy
    bias = np.zeros((B, 2))
    bias[2, 1] = 3.0  # episode 2, row 1: biased
    truth_Q = np.tile(Q, (B, 1, 1))
    truth_Q[3, 2, 2] *= 10.0  # episode 3: a motion event
    from navgym.envs.protocols import TrueNoise

    models = _models(mask=np.ones((B, 2), dtype=bool))._replace(truth=TrueNoise(truth_Q, truth_R, bias))
    knob = task.regime_knob(models)
    expected = np.ones((B, 3))
    expected[1, 0], expected[2, 1], expected[3, 2] = 30.0, 1e4, 100.0
    np.testing.assert_array_equal(knob, expected)
    out = task.step(_state(), np.ones((B, 3)), models, [])  # the agent's knob is ignored
    np.testing.assert_array_equal(out.knob, expected)
    assert task.filter_name == "ekf/regime_oracle"


def test_the_regime_oracle_needs_truth_and_excludes_the_clairvoyant():
    from navgym.envs.tasks import NoTruthError

    with pytest.raises(ValueError, match="two references"):
        _task(regime_oracle=(1, 1, 1, 1, 1), clairvoyant=True)
    with pytest.raises(ValueError, match="regime_oracle"):
        _task(regime_oracle=(1, 1, 1, 1))
    env = ToyEnv(task="rowscale", regime_oracle=(1, 1, 1, 1, 1), gives_truth=False)
    env.reset(seed=0)
    with pytest.raises(NoTruthError):
        env.step(env.action_space.sample())


def test_the_regime_oracle_excluding_a_biased_row_beats_the_plain_filter():
    kwargs = {"bias": (0.0, 15.0)}  # row 1 always carries a 5-sigma bias
    errs = {}
    for name, extra in {"plain": {}, "oracle": {"regime_oracle": (1.0, 1.0, 1e4, 1.0, 1.0)}}.items():
        venv = ToyVectorEnv(num_envs=8, task="rowscale", **kwargs, **extra)
        venv.reset(seed=0)
        a = np.tile(venv.core.task.neutral_action(), (8, 1))
        e = [venv.step(a)[4]["pos_err_m"] for _ in range(30)]
        errs[name] = float(np.sqrt(np.nanmean(np.square(e))))
    assert errs["oracle"] < 0.7 * errs["plain"], errs
