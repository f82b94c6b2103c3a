"""The compiled Robot2d process noise (navgym.robot2d.noise_kernel) equals the NumPy form."""

from __future__ import annotations

import numpy as np
import pytest

from filters.core.compiled import numpy_only
from navgym.robot2d import platform as platform_module
from navgym.robot2d.platform import Robot2dPlatform
from tests.filters.compiled_paths import count_calls


@pytest.mark.parametrize("turn", ["straight", "tight", "tiny"])
def test_the_compiled_process_noise_equals_the_numpy_form(monkeypatch, turn):
    rng = np.random.default_rng(3)
    B = 257
    phi = rng.uniform(-np.pi, np.pi, B)
    v_e = rng.uniform(0.0, 8.0, B)
    alpha = {
        "straight": np.zeros(B),
        "tight": rng.uniform(-0.5, 0.5, B),
        "tiny": rng.uniform(-1e-5, 1e-5, B),  # the series branch of d sinc
    }[turn]
    calls = count_calls(monkeypatch, platform_module, ("process_noise_pass",))
    p = Robot2dPlatform()
    Q = p.process_noise(phi, v_e, alpha)
    with numpy_only():
        ref = p.process_noise(phi, v_e, alpha)
    assert calls == {"process_noise_pass": 1}
    scale = np.sqrt(np.diagonal(ref, axis1=1, axis2=2))
    np.testing.assert_allclose(
        Q / (scale[:, :, None] * scale[:, None, :]),
        ref / (scale[:, :, None] * scale[:, None, :]),
        rtol=1e-12,
        atol=1e-12,
    )
    np.testing.assert_array_equal(Q, np.swapaxes(Q, 1, 2))
    assert (np.linalg.eigvalsh(Q) > 0).all()


@pytest.mark.parametrize("turn", ["straight", "tight", "tiny"])
def test_the_compiled_odometry_f_and_F_equal_the_numpy_forms(turn):
    from navgym.robot2d.models import OdometryTransition
    from navgym.robot2d.robot import RobotGeometry

    rng = np.random.default_rng(4)
    B = 33
    g = RobotGeometry()
    alpha = {
        "straight": np.zeros(B),
        "tight": rng.uniform(-0.5, 0.5, B),
        "tiny": rng.uniform(-1e-7, 1e-7, B),
    }[turn]
    trans = OdometryTransition(rng.uniform(0.0, 8.0, B), np.tan(alpha), np.zeros((B, 3, 3)), g)
    x = np.column_stack([rng.normal(0, 100, B), rng.normal(0, 100, B), rng.uniform(-7, 7, B)])
    f, F = trans.f(x, None, 0.1), trans.F(x, None, 0.1)
    with numpy_only():
        f_ref, F_ref = trans.f(x, None, 0.1), trans.F(x, None, 0.1)
    np.testing.assert_allclose(f, f_ref, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(F, F_ref, rtol=1e-12, atol=1e-13)
    # sigma points (B, S, 3) keep the NumPy form: the same numbers for the same states
    pts = np.stack([x, x + 0.1], axis=1)
    np.testing.assert_array_equal(trans.f(pts, None, 0.1)[:, 0], trans.f(x[:, None, :], None, 0.1)[:, 0])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_compiled_odometry_f_of_a_particle_cloud_equals_the_numpy_form(monkeypatch, dtype):
    """A component-major cloud (B, 3, N) seen as (B, N, 3): the same numbers, bit for bit."""
    from navgym.robot2d import models as models_module
    from navgym.robot2d.models import OdometryTransition
    from navgym.robot2d.robot import RobotGeometry

    rng = np.random.default_rng(6)
    B, N = 9, 301
    alpha = rng.uniform(-0.5, 0.5, B)
    alpha[0] = 0.0
    trans = OdometryTransition(rng.uniform(0.0, 8.0, B), np.tan(alpha), np.zeros((B, 3, 3)), RobotGeometry())
    xT = np.stack([rng.normal(0, 100, (B, N)), rng.normal(0, 100, (B, N)), rng.uniform(-7, 7, (B, N))], 1)
    x = xT.astype(dtype).transpose(0, 2, 1)
    calls = count_calls(monkeypatch, models_module, ("cloud_transition_pass",))
    f = trans.f(x, None, 0.1)
    with numpy_only():
        f_ref = trans.f(x, None, 0.1)
    assert calls == {"cloud_transition_pass": 1}
    assert f.dtype == f_ref.dtype == dtype and f.strides == f_ref.strides  # the cloud's layout kept
    np.testing.assert_array_equal(f, f_ref)


def test_the_fix_compass_h_of_a_particle_cloud_keeps_its_layout():
    """The same values; component-major on the compiled path (what the weighing kernel reads)."""
    from filters.core.layout import is_component_major
    from navgym.robot2d.models import FixCompassModel

    model = FixCompassModel(np.eye(5))
    xT = np.random.default_rng(7).normal(size=(4, 3, 50)).astype(np.float32)
    x = xT.transpose(0, 2, 1)
    z = model.h(x)
    with numpy_only():
        z_ref = model.h(x)
    np.testing.assert_array_equal(z, z_ref)
    np.testing.assert_array_equal(z, x[..., [0, 1, 0, 1, 2]])
    assert is_component_major(z) and not is_component_major(z_ref)
    sigma = np.ascontiguousarray(x)  # sigma points (B, S, 3): the NumPy form on both paths
    assert model.h(sigma).strides == sigma[..., [0, 1, 0, 1, 2]].strides
