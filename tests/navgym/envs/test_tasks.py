"""Tasks: the fading task's shared Jacobian changes nothing; ``kalman.update(H=...)``."""

import numpy as np

from filters import kalman
from navgym.envs.tasks import FadingDiagnostics, fading_traces
from navgym.gps_ins.env import GPS_INS

_core = GPS_INS.core


def _stepped_core(B=6, steps=12):
    core = _core("fading", B, {})
    rngs = [np.random.default_rng(7 + i) for i in range(B)]
    core.reset(np.arange(B), rngs, [None] * B)
    for _ in range(steps):
        core.step(np.zeros((B, 1), dtype=np.float32), rngs)
    return core


def test_the_update_with_a_given_jacobian_equals_the_update_that_evaluates_it():
    core = _stepped_core()
    models = core.platform.step_models(core.episodes, core.t)
    pred = kalman.predict(core.state, models.transition, None, models.dt)
    H = models.observation.H(pred.m)
    post, info = kalman.update(pred, models.z, models.observation, mask=models.mask, H=H)
    ref, ref_info = kalman.update(pred, models.z, models.observation, mask=models.mask)
    np.testing.assert_array_equal(post.m, ref.m)
    np.testing.assert_array_equal(post.P, ref.P)
    np.testing.assert_array_equal(info.nis, ref_info.nis)
    # the given Jacobian is the one used: another one changes the posterior
    other, _ = kalman.update(pred, models.z, models.observation, mask=models.mask, H=2.0 * H)
    assert not np.array_equal(other.m, ref.m)


def test_the_fading_step_equals_a_plain_predict_and_update():
    core = _stepped_core()
    models = core.platform.step_models(core.episodes, core.t)
    lam = np.linspace(1.0, 5.0, core.B)
    out = core.task.step(core.state, lam, models, None)
    pred = kalman.predict(core.state, models.transition, None, models.dt, fading=lam)
    post, info = kalman.update(pred, models.z, models.observation, mask=models.mask)
    np.testing.assert_array_equal(out.state.m, post.m)
    np.testing.assert_array_equal(out.state.P, post.P)
    np.testing.assert_array_equal(out.info.nis, info.nis)
    assert isinstance(out.diagnostics, FadingDiagnostics) and out.numerical_failure is None
    assert out.knob is lam and out.diagnostics.fading is lam
    for k, v in fading_traces(pred, info, models, lam).items():
        np.testing.assert_array_equal(getattr(out.diagnostics, k), v, err_msg=k)
