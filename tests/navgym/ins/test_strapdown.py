import numpy as np
import pytest

from navgym import geo
from navgym.ins import (
    CONSUMER_MEMS,
    PERFECT,
    TACTICAL,
    ImuSample,
    NavState,
    euler_to_dcm,
    imu_from_components,
    imu_from_kinematics,
    make_nav_state,
    simulate_imu,
    strapdown_integrate,
    strapdown_step,
)
from navgym.motion.trajectory import ideal_imu, midpoint_times, nav_state_at
from navgym.quadrotor.flight import QuadrotorParams, quadrotor_trajectory, sample_quadrotor_plans

from .tolerances import (
    BIAS_GROWTH_RTOL,
    EXACT_ATOL,
    GRADE_DRIFT_RATIO,
    PERFECT_IMU_DRIFT_M,
    PERFECT_IMU_VEL_MPS,
    STATIC_DRIFT_M,
)

DT = 0.005  # 200 Hz
DURATION = 300.0
GRADES = (PERFECT, TACTICAL, TACTICAL, CONSUMER_MEMS, CONSUMER_MEMS)


def _ned_error(nav, lat, lon, h):
    return geo.ecef_to_ned(geo.geodetic_to_ecef(nav.lat, nav.lon, nav.h), lat, lon, h)


@pytest.fixture(scope="module")
def flight_run():
    """One quadrotor triangle flight, 300 s at 200 Hz, flown by five IMUs at once.

    Legs of 100 to 250 m (one of Benzerrouk 2014's settings); seed 1 lands after 235 s.
    """
    n = int(round(DURATION / DT))
    plan = sample_quadrotor_plans([1] * len(GRADES), QuadrotorParams(leg_length=(100.0, 250.0)))
    truth = quadrotor_trajectory(plan, np.arange(n + 1) * DT)
    ideal = ideal_imu(quadrotor_trajectory(plan, midpoint_times(n, DT)))
    fs, ws, biases = [], [], []
    for i, spec in enumerate(GRADES):
        one = ImuSample(ideal.specific_force[i : i + 1], ideal.angular_rate[i : i + 1])
        meas, bias = simulate_imu(one, DT, spec, [np.random.default_rng(100 + i)])
        fs.append(meas.specific_force)
        ws.append(meas.angular_rate)
        biases.append(bias)
    imu = ImuSample(np.concatenate(fs), np.concatenate(ws))
    nav = strapdown_integrate(nav_state_at(truth, 0), imu, DT)
    err = _ned_error(nav, truth.lat, truth.lon, truth.h)
    return plan, truth, nav, err, biases


def test_perfect_imu_reproduces_quadrotor_flight(flight_run):
    plan, truth, nav, err, _ = flight_run
    assert plan.t_landed[0] < DURATION  # the whole triangle, landing included, is flown
    drift = np.linalg.norm(err[0], axis=-1)
    assert drift.max() < PERFECT_IMU_DRIFT_M
    assert np.abs(nav.v_ned[0] - truth.v_ned[0]).max() < PERFECT_IMU_VEL_MPS
    att = np.einsum("tji,tjk->tik", nav.C_b_n[0], truth.C_b_n[0])
    assert np.abs(att - np.eye(3)).max() < 1e-6


def test_drift_grows_with_imu_grade(flight_run):
    _, _, _, err, _ = flight_run
    horiz = np.linalg.norm(err[:, -1, :2], axis=-1)
    perfect, tactical, consumer = horiz[0], horiz[1:3], horiz[3:5]
    assert perfect < PERFECT_IMU_DRIFT_M < tactical.min()
    assert tactical.max() * 10 < consumer.min()
    # order of magnitude of the grade's own numbers: 0.5 sigma_a t^2 + g sigma_g t^3 / 6
    for i, spec in enumerate(GRADES[1:], start=1):
        bound = 0.5 * spec.accel_bias * DURATION**2 + 9.81 * spec.gyro_bias * DURATION**3 / 6.0
        assert GRADE_DRIFT_RATIO[0] < horiz[i] / bound < GRADE_DRIFT_RATIO[1]


_NO_BIAS = np.zeros(3)


def _static(lat, n, dt, accel_bias=_NO_BIAS, gyro_bias=_NO_BIAS, rotating_earth=True):
    """A level body at rest: ideal IMU plus constant biases, integrated n steps."""
    b = 1
    lat = np.full(b, lat)
    h = np.full(b, 100.0)
    C = euler_to_dcm(0.0, 0.0, np.full(b, 0.7))
    zero = np.zeros((b, 3))
    ideal = imu_from_kinematics(lat, h, zero, zero, C, zero, rotating_earth=rotating_earth)
    f = np.repeat((ideal.specific_force + accel_bias)[:, None], n, axis=1)
    w = np.repeat((ideal.angular_rate + gyro_bias)[:, None], n, axis=1)
    nav0 = make_nav_state(lat, np.full(b, 0.2), h, zero, C)
    nav = strapdown_integrate(nav0, ImuSample(f, w), dt, rotating_earth=rotating_earth)
    return nav, _ned_error(nav, lat[:, None], 0.2, h[:, None])


@pytest.mark.parametrize("rotating_earth", [True, False])
def test_body_at_rest_stays_put(rotating_earth):
    _, err = _static(np.deg2rad(45.0), 6000, 0.1, rotating_earth=rotating_earth)
    assert np.abs(err).max() < STATIC_DRIFT_M


def test_accelerometer_bias_gives_half_b_t_squared():
    b, t, dt = 1e-3, 60.0, 0.01
    _, err = _static(np.deg2rad(45.0), int(t / dt), dt, accel_bias=np.array([b, 0.0, 0.0]))
    # body x is at yaw 0.7 rad from north
    expected = 0.5 * b * t**2 * np.array([np.cos(0.7), np.sin(0.7)])
    np.testing.assert_allclose(err[0, -1, :2], expected, rtol=BIAS_GROWTH_RTOL)


def test_gyro_bias_gives_g_eps_t_cubed_over_six():
    eps, t, dt = 1e-5, 60.0, 0.01
    # a roll-axis (body x) gyro bias tilts the body; gravity leaks into the body y axis
    _, err = _static(np.deg2rad(45.0), int(t / dt), dt, gyro_bias=np.array([eps, 0.0, 0.0]))
    magnitude = 9.81 * eps * t**3 / 6.0
    assert np.linalg.norm(err[0, -1, :2]) == pytest.approx(magnitude, rel=BIAS_GROWTH_RTOL)


def test_integrate_equals_repeated_steps(flight_run):
    _, truth, nav, _, _ = flight_run
    rng = np.random.default_rng(5)
    f = rng.standard_normal((2, 20, 3)) + [0.0, 0.0, -9.8]
    w = 0.1 * rng.standard_normal((2, 20, 3))
    nav0 = NavState(
        *(np.asarray(x[:2, 0]) for x in (truth.lat, truth.lon, truth.h)),
        truth.v_ned[:2, 0],
        truth.C_b_n[:2, 0],
    )
    run = strapdown_integrate(nav0, ImuSample(f, w), DT)
    state = nav0
    for k in range(20):
        state = strapdown_step(state, ImuSample(f[:, k], w[:, k]), DT)
    for a, b in zip(state, run, strict=True):
        np.testing.assert_allclose(a, b[:, -1], atol=EXACT_ATOL, rtol=0)


def test_imu_components_with_precomputed_terms_equal_the_array_form(flight_run):
    # imu_from_kinematics on (..., 3) arrays and imu_from_components with the caller's sin/cos
    # and transport rate (as the quadrotor truth passes them) are the same computation
    tr = flight_run[1]
    ref = imu_from_kinematics(tr.lat, tr.h, tr.v_ned, tr.a_ned, tr.C_b_n, tr.omega_nb_b)

    def comps(x):
        return tuple(x[..., i] for i in range(3))

    C = tuple(comps(tr.C_b_n[..., i, :]) for i in range(3))
    v = comps(tr.v_ned)
    rn = geo.normal_radius(tr.lat) + tr.h
    w_en = (v[1] / rn, -v[0] / (geo.meridian_radius(tr.lat) + tr.h), -v[1] * np.tan(tr.lat) / rn)
    sl, cl = np.sin(tr.lat), np.cos(tr.lat)
    f_b, w_ib = imu_from_components(
        tr.lat, tr.h, v, comps(tr.a_ned), C, comps(tr.omega_nb_b), sin_lat=sl, cos_lat=cl, w_en=w_en
    )
    np.testing.assert_allclose(np.stack(f_b, -1), ref.specific_force, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.stack(w_ib, -1), ref.angular_rate, rtol=0, atol=1e-15)
    np.testing.assert_allclose(tr.specific_force, ref.specific_force, rtol=0, atol=1e-12)


def test_bad_input_raises_naming_argument():
    nav = make_nav_state([0.5], [0.1], [0.0], np.zeros((1, 3)), np.eye(3)[None])
    imu = ImuSample(np.zeros((1, 3)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="dt"):
        strapdown_step(nav, imu, 0.0)
    with pytest.raises(ValueError, match="imu"):
        strapdown_step(nav, ImuSample(np.zeros((2, 3)), np.zeros((2, 3))), 0.01)
    with pytest.raises(ValueError, match="v_ned"):
        make_nav_state([0.5], [0.1], [0.0], np.zeros((1, 2)), np.eye(3)[None])
    with pytest.raises(ValueError, match="lat"):
        make_nav_state([np.nan], [0.1], [0.0], np.zeros((1, 3)), np.eye(3)[None])
    with pytest.raises(ValueError, match="imu"):
        strapdown_integrate(nav, ImuSample(np.zeros((1, 3)), np.zeros((1, 3))), 0.01)


def test_non_finite_imu_and_impossible_attitudes_raise():
    """A NaN sample would turn the state into NaN silently; a non-rotation C_b_n is not an attitude."""
    nav = make_nav_state([0.5], [0.1], [0.0], np.zeros((1, 3)), np.eye(3)[None])
    f = np.zeros((1, 3))
    f[0, 2] = np.nan
    with pytest.raises(ValueError, match=r"imu.specific_force must be finite.*\(0, 2\)"):
        strapdown_step(nav, ImuSample(f, np.zeros((1, 3))), 0.01)
    w = np.zeros((1, 4, 3))
    w[0, 3, 1] = np.inf
    with pytest.raises(ValueError, match=r"imu.angular_rate must be finite.*\(0, 3, 1\)"):
        strapdown_integrate(nav, ImuSample(np.zeros((1, 4, 3)), w), 0.01)
    scaled = np.stack([np.eye(3), 1.01 * np.eye(3)])
    with pytest.raises(ValueError, match="C_b_n must be rotation matrices.*member 1"):
        make_nav_state([0.5, 0.5], [0.1, 0.1], [0.0, 0.0], np.zeros((2, 3)), scaled)
    with pytest.raises(ValueError, match="C_b_n must be rotation matrices.*det -1"):
        make_nav_state([0.5], [0.1], [0.0], np.zeros((1, 3)), np.diag([1.0, 1.0, -1.0])[None])
    with pytest.raises(ValueError, match="lat must lie in"):
        make_nav_state([2.0], [0.1], [0.0], np.zeros((1, 3)), np.eye(3)[None])
    # a rotation with rounding-level deviations is accepted
    c, s = np.cos(0.3), np.sin(0.3)
    make_nav_state([0.5], [0.1], [0.0], np.zeros((1, 3)), np.array([[[c, -s, 0], [s, c, 0], [0, 0, 1.0]]]))
