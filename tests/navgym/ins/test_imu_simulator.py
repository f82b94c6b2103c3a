import numpy as np
import pytest

from navgym.ins import (
    CONSUMER_MEMS,
    IMU_NOISE_WIDTH,
    PERFECT,
    TACTICAL,
    ImuErrorSpec,
    ImuSample,
    earth_rate_ned,
    euler_to_dcm,
    gravity_ned,
    imu_error_step,
    imu_error_steps,
    imu_from_kinematics,
    imu_grade,
    sample_imu_bias,
    simulate_imu,
    skew,
    transport_rate_ned,
)
from navgym.scenarios import NormalStream

from .tolerances import EXACT_ATOL


def _ideal(b=3, n=400):
    rng = np.random.default_rng(0)
    return ImuSample(rng.standard_normal((b, n, 3)), 0.1 * rng.standard_normal((b, n, 3)))


def test_inverse_mechanization_satisfies_the_mechanization_equations():
    rng = np.random.default_rng(1)
    n = 50
    lat = rng.uniform(-1.3, 1.3, n)
    h = rng.uniform(0, 5000, n)
    v = rng.normal(0, 30, (n, 3))
    a = rng.normal(0, 3, (n, 3))
    C = euler_to_dcm(*rng.uniform(-1, 1, (3, n)))
    w_nb = rng.normal(0, 0.5, (n, 3))
    f, w_ib = imu_from_kinematics(lat, h, v, a, C, w_nb)
    w_ie, w_en = earth_rate_ned(lat), transport_rate_ned(lat, h, v)
    # Groves eq. 5.54: dv/dt = C f + g - (w_en + 2 w_ie) x v
    vdot = np.einsum("nij,nj->ni", C, f) + gravity_ned(lat, h) - np.cross(w_en + 2 * w_ie, v)
    np.testing.assert_allclose(vdot, a, atol=1e-10)
    # Groves eq. 5.46: dC/dt = C [w_ib x] - [w_in x] C  equals  C [w_nb x]
    lhs = C @ skew(w_ib) - skew(w_ie + w_en) @ C
    np.testing.assert_allclose(lhs, C @ skew(w_nb), atol=1e-12)


def test_grade_presets_document_their_sources():
    deg = np.pi / 180
    assert TACTICAL.gyro_bias == pytest.approx(1.0 * deg / 3600)  # HG1700: 1 deg/h
    assert TACTICAL.gyro_noise == pytest.approx(0.125 * deg / 60)  # 0.125 deg/sqrt(h)
    assert TACTICAL.accel_bias == pytest.approx(9.80665e-3)  # 1 mg
    assert TACTICAL.accel_noise == pytest.approx(3.302e-4, rel=1e-3)  # 0.065 ft/s/sqrt(h)
    assert CONSUMER_MEMS.gyro_bias == pytest.approx(0.1 * deg)  # 0.1 deg/s
    assert CONSUMER_MEMS.gyro_noise == pytest.approx(0.0038 * deg)  # walk_0827 IMU
    assert CONSUMER_MEMS.accel_noise == pytest.approx(70e-6 * 9.80665)
    assert imu_grade("tactical") is TACTICAL
    for spec in (TACTICAL, CONSUMER_MEMS):
        assert spec.gyro_bias_walk * 60.0 == pytest.approx(spec.gyro_bias)


def test_perfect_imu_adds_nothing():
    ideal = _ideal()
    meas, bias = simulate_imu(ideal, 0.01, PERFECT, [np.random.default_rng(s) for s in range(3)])
    np.testing.assert_array_equal(meas.specific_force, ideal.specific_force)
    np.testing.assert_array_equal(meas.angular_rate, ideal.angular_rate)
    assert not np.any(bias.accel) and not np.any(bias.gyro)


def test_error_statistics_match_the_spec():
    b, n, dt = 400, 200, 0.01
    spec = ImuErrorSpec("test", 0.1, 0.02, 0.05, 0.01, 0.003, 0.002)
    zero = ImuSample(np.zeros((b, n, 3)), np.zeros((b, n, 3)))
    meas, bias = simulate_imu(zero, dt, spec, [np.random.default_rng(s) for s in range(b)])
    # turn-on bias, white noise and random-walk growth (1200 numbers each -> ~3 % sd)
    assert bias.accel[:, 0].std() == pytest.approx(spec.accel_bias, rel=0.1)
    assert bias.gyro[:, 0].std() == pytest.approx(spec.gyro_bias, rel=0.1)
    white = meas.specific_force - bias.accel
    assert white.std() == pytest.approx(spec.accel_noise / np.sqrt(dt), rel=0.05)
    walk = bias.accel[:, -1] - bias.accel[:, 0]
    assert walk.std() == pytest.approx(spec.accel_bias_walk * np.sqrt((n - 1) * dt), rel=0.1)
    walk_g = bias.gyro[:, -1] - bias.gyro[:, 0]
    assert walk_g.std() == pytest.approx(spec.gyro_bias_walk * np.sqrt((n - 1) * dt), rel=0.1)


def test_batch_equals_single_episodes_and_stepping():
    ideal = _ideal(b=4, n=300)
    seeds = [11, 12, 13, 14]
    batch, bias = simulate_imu(ideal, 0.005, CONSUMER_MEMS, [np.random.default_rng(s) for s in seeds])
    for i, s in enumerate(seeds):
        one = ImuSample(ideal.specific_force[i : i + 1], ideal.angular_rate[i : i + 1])
        single, _ = simulate_imu(one, 0.005, CONSUMER_MEMS, [np.random.default_rng(s)])
        np.testing.assert_array_equal(single.specific_force[0], batch.specific_force[i])
        np.testing.assert_array_equal(single.angular_rate[0], batch.angular_rate[i])
    rngs = [np.random.default_rng(s) for s in seeds]
    b_k = sample_imu_bias(CONSUMER_MEMS, rngs)
    stream = NormalStream(rngs, IMU_NOISE_WIDTH, chunk=64)
    for k in range(300):
        step = ImuSample(ideal.specific_force[:, k], ideal.angular_rate[:, k])
        meas, b_k = imu_error_step(step, b_k, CONSUMER_MEMS, 0.005, stream.next())
        np.testing.assert_allclose(meas.specific_force, batch.specific_force[:, k], atol=EXACT_ATOL)
        np.testing.assert_allclose(meas.angular_rate, batch.angular_rate[:, k], atol=EXACT_ATOL)


def test_a_block_of_steps_equals_one_step_at_a_time():
    ideal = _ideal(b=3, n=20)
    rng = np.random.default_rng(7)
    b0 = sample_imu_bias(CONSUMER_MEMS, [np.random.default_rng(s) for s in range(3)])
    z = rng.standard_normal((3, 20, IMU_NOISE_WIDTH))
    block, in_effect, after = imu_error_steps(ideal, b0, CONSUMER_MEMS, 0.005, z)
    b_k = b0
    for k in range(20):
        np.testing.assert_allclose(in_effect.accel[:, k], b_k.accel, rtol=0, atol=EXACT_ATOL)
        step = ImuSample(ideal.specific_force[:, k], ideal.angular_rate[:, k])
        meas, b_k = imu_error_step(step, b_k, CONSUMER_MEMS, 0.005, z[:, k])
        np.testing.assert_allclose(block.specific_force[:, k], meas.specific_force, rtol=0, atol=EXACT_ATOL)
        np.testing.assert_allclose(block.angular_rate[:, k], meas.angular_rate, rtol=0, atol=EXACT_ATOL)
    np.testing.assert_allclose(after.accel, b_k.accel, rtol=0, atol=EXACT_ATOL)
    np.testing.assert_allclose(after.gyro, b_k.gyro, rtol=0, atol=EXACT_ATOL)
    with pytest.raises(ValueError, match="noise"):
        imu_error_steps(ideal, b0, CONSUMER_MEMS, 0.005, z[:, :5])


def test_bad_input_raises_naming_argument():
    with pytest.raises(ValueError, match="gyro_noise"):
        ImuErrorSpec("x", 0.0, 0.0, 0.0, 0.0, -1.0, 0.0)
    with pytest.raises(ValueError, match="name"):
        imu_grade("navigation")
    ideal = _ideal(b=2, n=5)
    rngs = [np.random.default_rng(0)]
    with pytest.raises(ValueError, match="rngs"):
        simulate_imu(ideal, 0.01, TACTICAL, rngs)
    with pytest.raises(ValueError, match="dt"):
        simulate_imu(ideal, -0.01, TACTICAL, rngs * 2)
    with pytest.raises(ValueError, match="ideal"):
        simulate_imu(ImuSample(np.zeros((2, 5)), np.zeros((2, 5))), 0.01, TACTICAL, rngs * 2)
    b0 = sample_imu_bias(TACTICAL, rngs * 2)
    one = ImuSample(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="noise"):
        imu_error_step(one, b0, TACTICAL, 0.01, np.zeros((2, 6)))


def test_imu_bias_walks_batch_equals_singles_and_scale_multiplies():
    from navgym.ins import CONSUMER_MEMS, imu_bias_walks

    batch = imu_bias_walks(CONSUMER_MEMS, [np.random.default_rng(s) for s in (3, 4, 5)], 0.5, 20)
    assert batch.shape == (3, 21, 6)
    for i, s in enumerate((3, 4, 5)):
        np.testing.assert_array_equal(
            batch[i], imu_bias_walks(CONSUMER_MEMS, [np.random.default_rng(s)], 0.5, 20)[0]
        )
    g = np.random.default_rng(3)
    b0 = np.repeat([CONSUMER_MEMS.accel_bias, CONSUMER_MEMS.gyro_bias], 3) * g.standard_normal(6)
    np.testing.assert_array_equal(batch[0, 0], b0)  # the turn-on bias first, then the walk
    steps = np.diff(batch[0], axis=0) / np.repeat(
        [CONSUMER_MEMS.accel_bias_walk, CONSUMER_MEMS.gyro_bias_walk], 3
    )
    np.testing.assert_allclose(steps, np.sqrt(0.5) * g.standard_normal((20, 6)), rtol=1e-9, atol=1e-12)
    scaled = imu_bias_walks(CONSUMER_MEMS, [np.random.default_rng(3)], 0.5, 20, np.array([2.0]))
    np.testing.assert_allclose(scaled[0], 2.0 * batch[0], rtol=1e-12)
