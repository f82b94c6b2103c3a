"""The compiled strapdown transition (navgym.quadrotor.strapdown_kernel) equals the NumPy form.

``f`` and ``F`` of real Quadrotor and Pedestrian steps (the platforms' own ``StepModels``) at
random states around the episodes' means, yaw and roll near the wrap, on both paths; the memo
still gives ``F(m)`` then ``f(m)`` from one propagation.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)
from filters.core.compiled import numpy_only
from navgym.quadrotor import models as models_module
from tests.filters.compiled_paths import count_calls


def _transition(env_id: str, B: int = 12):
    env = gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point")
    env.reset(seed=3)
    core = env.unwrapped.core
    models = core.platform.step_models(core.episodes, core.t + 5)
    return models.transition, core.state.m.copy() if hasattr(core.state, "m") else None


@pytest.mark.parametrize("env_id", ["navgym/QuadrotorNoiseScale-v2", "navgym/PedestrianNoiseScale-v3"])
def test_the_compiled_f_and_F_equal_the_numpy_forms(monkeypatch, env_id):
    trans, m = _transition(env_id)
    rng = np.random.default_rng(0)
    x = m + rng.normal(0, 1, m.shape) * np.array([5, 5, 5, 1, 1, 1, 0.05, 0.05, 0.05] + [1e-3] * 6)
    x[0, 6], x[0, 8] = np.pi - 1e-9, -np.pi + 1e-9  # roll and yaw at the wrap
    x[1, 8] = 3 * np.pi  # an unwrapped yaw
    calls = count_calls(monkeypatch, models_module, ("strapdown_pass",))
    fresh = trans._replace(memo=[None])
    F, f = fresh.F(x), fresh.f(x)
    assert calls == {"strapdown_pass": 1}  # F then f of the same array: one pass
    with numpy_only():
        ref = trans._replace(memo=[None])
        F_ref, f_ref = ref.F(x), ref.f(x)
    np.testing.assert_allclose(f, f_ref, rtol=1e-13, atol=1e-10)
    np.testing.assert_allclose(F, F_ref, rtol=1e-12, atol=1e-13)
    pts = np.stack([x, x + 1e-3], axis=1)  # sigma points keep the NumPy form
    np.testing.assert_array_equal(trans._replace(memo=[None]).f(pts)[:, 0], f_ref)


def test_the_compiled_preintegration_equals_the_numpy_form(monkeypatch):
    rng = np.random.default_rng(7)
    n_sub, N = 40, 23
    w = rng.normal(0, 1.5, (n_sub, 3, N))  # walking rates, up to several rad/s
    w[:, :, 0] = 0.0  # no rotation: Rodrigues' limits
    w[:, :, 1] = 1e-9
    f = rng.normal(0, 5, (n_sub, 3, N)) + np.array([0.0, 0.0, -9.81])[None, :, None]
    calls = count_calls(monkeypatch, models_module, ("preintegrate_rows",))
    gyro, accel = np.moveaxis(w, -1, 0).reshape(N, 1, n_sub, 3), np.moveaxis(f, -1, 0)
    rows = models_module.preintegrate(gyro, accel, 0.01)
    assert calls == {"preintegrate_rows": 1}
    ref = models_module.preintegrate_components(w, f, 0.01)  # the NumPy passes
    with numpy_only():
        ref_rows = models_module.preintegrate(gyro, accel, 0.01)
    assert calls == {"preintegrate_rows": 1}
    for name, a, b, c in zip(ref._fields, rows, ref, ref_rows, strict=True):  # NumPy's sin/cos: same bits
        np.testing.assert_array_equal(a.reshape((N,) + b.shape[:-1]), np.moveaxis(b, -1, 0), err_msg=name)
        np.testing.assert_array_equal(a, c, err_msg=name)
    R = rows.dR.reshape(N, 3, 3)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
