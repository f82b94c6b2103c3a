"""The Quadrotor env's compiled reset kernel against the NumPy reference chain.

Reference: :func:`navgym.quadrotor.flight.quadrotor_imu` (ideal IMU through geodetic
coordinates and the local NED frame at every sample) plus bias and noise, then
:func:`navgym.quadrotor.models.preintegrate`. The kernel works in the home frame and interpolates
the gravity vector through three nodes per step (module docstring of
:mod:`navgym.quadrotor.imu_kernel`). Measured (3 episodes x 60 steps): ``d6`` within 1.1e-14,
``J6`` 1.1e-14, ``dR`` 3e-16, ``Phi`` 7e-17 of the reference, with small-angle (series) and
large-angle (trigonometric) Rodrigues coefficients alike.
"""

import numpy as np
import pytest

from navgym.geo import gravity
from navgym.ins import earth_rate_ned
from navgym.quadrotor.flight import (
    QuadrotorParams,
    home_gravity,
    quadrotor_imu,
    quadrotor_positions,
    sample_quadrotor_plans,
)
from navgym.quadrotor.imu_kernel import LANES, preintegrated_imu
from navgym.quadrotor.models import preintegrate

B, T, N_SUB, DT = 3, 60, 20, 0.1
DELTA = DT / N_SUB


def _inputs(gyro_noise: float, seed: int = 3, n: int = B):
    rng = np.random.default_rng(seed)
    plans = sample_quadrotor_plans([np.random.default_rng(seed + i) for i in range(n)], QuadrotorParams())
    # start inside the flight: take-off, legs and turns fall in the 6 s windows of some episodes
    t0 = rng.uniform(0.0, 0.5, n) * plans.t_landed
    bias = rng.normal(0.0, [0.05] * 3 + [1e-3] * 3, (n, T + 1, 6))
    noise = rng.standard_normal((n, T, N_SUB, 6))
    na, ng = np.full(n, 0.02), np.full(n, gyro_noise)
    omega = earth_rate_ned(plans.origin[:, 0])
    nodes = t0[:, None] + np.arange(2 * T + 1) * (0.5 * DT)
    gamma = home_gravity(plans.origin, quadrotor_positions(plans, nodes))
    return plans, t0, bias, noise, na, ng, omega, gamma


def _reference(plans, t0, bias, noise, na, ng):
    times = t0[:, None, None] + (np.arange(T) * DT)[None, :, None] + (np.arange(N_SUB) + 0.5) * DELTA
    f_ib, w_ib = quadrotor_imu(plans, times.reshape(B, -1))
    f = np.stack(f_ib, -1).reshape(B, T, N_SUB, 3)
    w = np.stack(w_ib, -1).reshape(B, T, N_SUB, 3)
    b = bias[:, :T, None, :]
    accel = f + b[..., :3] + na[:, None, None, None] * noise[..., :3]
    gyro = w + b[..., 3:] + ng[:, None, None, None] * noise[..., 3:]
    return preintegrate(gyro, accel, DELTA)


def _kernel(plans, t0, bias, noise, na, ng, omega, gamma, chunk=T):
    out = (np.empty((B, T, 3, 3)), np.empty((B, T, 3, 3)), np.empty((B, T, 6)), np.empty((B, T, 6, 6)))
    for k0 in range(0, T, chunk):
        block = noise[:, k0 : k0 + chunk]
        preintegrated_imu(plans, t0, k0, DT, N_SUB, omega, gamma, bias, block, na, ng, out)
    return out


# gyro noise 1e-3 rad/s per sample: every Rodrigues angle below 0.01 rad (series); 10 rad/s: above
@pytest.mark.parametrize("gyro_noise", [1e-3, 10.0])
def test_kernel_equals_the_numpy_imu_and_preintegration(gyro_noise):
    plans, t0, bias, noise, na, ng, omega, gamma = _inputs(gyro_noise)
    ref = _reference(plans, t0, bias, noise, na, ng)
    dR, phi, d6, J6 = _kernel(plans, t0, bias, noise, na, ng, omega, gamma, chunk=7)
    np.testing.assert_allclose(dR, ref.dR, rtol=0, atol=1e-14)
    np.testing.assert_allclose(phi, ref.phi, rtol=0, atol=1e-14)
    np.testing.assert_allclose(d6, np.concatenate([ref.dv, ref.dp], -1), rtol=0, atol=1e-12)
    J_ref = np.block([[-ref.jva, ref.jvg], [-ref.jpa, ref.jpg]])
    np.testing.assert_allclose(J6, J_ref, rtol=0, atol=1e-12)


def test_the_flights_turn_and_move_inside_the_tested_windows():
    """Guard for the test above: its episodes include yaw turns and accelerations (not hover only)."""
    plans, t0, *_ = _inputs(1e-3)
    times = t0[:, None] + np.arange(T * N_SUB) * DELTA
    seg = (plans.t_start[:, None, :] <= times[..., None]).sum(-1) - 1
    turning = np.take_along_axis(plans.yaw_end - plans.yaw_start, seg, axis=1) != 0
    assert turning.any()
    f_ib, w_ib = quadrotor_imu(plans, times)
    # thrust (the specific force lies along the body z axis) and body rates vary
    assert np.ptp(np.sqrt(sum(c * c for c in f_ib))) > 0.1  # m/s^2 (hover alone: 1e-5)
    assert np.abs(np.stack(w_ib)).max() > 0.05  # rad/s


def test_chunking_does_not_change_the_result():
    args = _inputs(1e-3)
    whole = _kernel(*args, chunk=T)
    pieces = _kernel(*args, chunk=11)
    for a, b in zip(whole, pieces, strict=True):
        np.testing.assert_array_equal(a, b)


def test_each_episode_is_computed_as_if_alone():
    """The kernel runs blocks of LANES episodes side by side (SIMD lanes): no lane sees another's data.

    Two blocks, the second part-filled; each of its episodes preintegrated alone gives the same bits.
    """
    n = LANES + 3
    plans, t0, bias, noise, na, ng, omega, gamma = _inputs(1e-3, seed=5, n=n)
    out = tuple(np.empty((n, T) + s) for s in [(3, 3), (3, 3), (6,), (6, 6)])
    preintegrated_imu(plans, t0, 0, DT, N_SUB, omega, gamma, bias, noise[:, :9], na, ng, out)
    for b in (0, LANES - 1, LANES, n - 1):
        one = slice(b, b + 1)
        alone = tuple(np.empty((1, T) + s) for s in [(3, 3), (3, 3), (6,), (6, 6)])
        plan = type(plans)(*(field[one] for field in plans))
        args = (t0[one], 0, DT, N_SUB, omega[one], gamma[one], bias[one], noise[one, :9], na[one], ng[one])
        preintegrated_imu(plan, *args, alone)
        for a, ref in zip(out, alone, strict=True):
            np.testing.assert_array_equal(a[b, :9], ref[0, :9])


def test_home_gravity_at_home_is_normal_gravity_down():
    origin = np.array([[0.7, -1.2, 150.0], [-0.3, 2.0, 5.0]])
    zero = np.zeros((2, 1))
    g = home_gravity(origin, (zero, zero, zero))[:, 0]
    np.testing.assert_allclose(g[:, :2], 0.0, atol=1e-12)
    np.testing.assert_allclose(g[:, 2], gravity(origin[:, 0], origin[:, 2]), rtol=1e-14)
    # 1 km north the vertical has turned by ~ 1 km / R_M about the east axis: gamma_N ~ -g 1.6e-4
    north = home_gravity(origin, (np.full((2, 1), 1000.0), zero, zero))[:, 0]
    assert np.all((north[:, 0] < -1.4e-3) & (north[:, 0] > -1.7e-3))


def test_bad_shapes_raise():
    plans, t0, bias, noise, na, ng, omega, gamma = _inputs(1e-3)
    out = (np.empty((B, T, 3, 3)), np.empty((B, T, 3, 3)), np.empty((B, T, 6)), np.empty((B, T, 6, 6)))
    with pytest.raises(ValueError, match="noise"):
        preintegrated_imu(plans, t0, 0, DT, N_SUB, omega, gamma, bias, noise[..., :3], na, ng, out)
    with pytest.raises(ValueError, match="gamma_nodes"):
        preintegrated_imu(plans, t0, 0, DT, N_SUB, omega, gamma[:, :10], bias, noise, na, ng, out)
