"""Tasks: the fading task's shared Jacobian changes nothing."""

import numpy as np

from filters import kalman
from navgym.envs.tasks import JacobianAt, fading_traces
from navgym.gps_ins.env import GPS_INS

_core = GPS_INS.core


def _stepped_core(B=6, steps=12):
    core = _core("fading", B, {})
    rngs = [np.random.default_rng(7 + i) for i in range(B)]
    core.reset(np.arange(B), rngs, [None] * B)
    for _ in range(steps):
        core.step(np.zeros((B, 1), dtype=np.float32), rngs)
    return core


def test_jacobian_at_reuses_the_given_jacobian_only_for_its_point():
    core = _stepped_core()
    models = core.platform.step_models(core.episodes, core.t)
    x = core.state.m
    sentinel = np.full((x.shape[0], models.z.shape[1], x.shape[1]), 7.0)
    wrapped = JacobianAt(models.observation, x, sentinel)
    assert wrapped.H(x) is sentinel
    other = x.copy()  # the same values, another array: asks the model
    np.testing.assert_array_equal(wrapped.H(other), models.observation.H(other))
    assert wrapped.R is models.observation.R  # everything else is the model's
    np.testing.assert_array_equal(wrapped.h(x), models.observation.h(x))


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
    for k, v in fading_traces(pred, info, models, lam).items():
        np.testing.assert_array_equal(out.extras[k], v, err_msg=k)
