import numpy as np
import pytest

from navgym.robot2d.robot import encoder_speed, robot_trajectory, sample_robot_plans
from navgym.robot2d.sensors import (
    COMPASS_RATE_HZ,
    GLONASS_RATE_HZ,
    GPS_RATE_HZ,
    ROBOT_NOISE_WIDTH,
    RobotSensorNoise,
    is_measurement_step,
    measurement_schedule,
    position_fixes,
    robot_measurements,
    simulate_robot_measurements,
)
from navgym.scenarios import NormalStream

DT = 0.02  # 50 Hz robot simulation


@pytest.fixture(scope="module")
def run():
    plan = sample_robot_plans([1, 2, 3, 4])
    n = int(300 / DT)
    traj = robot_trajectory(plan, np.arange(n) * DT)
    meas = simulate_robot_measurements(traj, DT, [np.random.default_rng(s) for s in range(4)])
    return traj, meas


def test_rates_are_10_5_5_hz(run):
    _, meas = run
    seconds = meas.gps_mask.shape[1] * DT
    assert (GPS_RATE_HZ, GLONASS_RATE_HZ, COMPASS_RATE_HZ) == (10.0, 5.0, 5.0)
    assert meas.gps_mask.sum(axis=1).tolist() == [int(10 * seconds)] * 4
    assert meas.glonass_mask.sum(axis=1).tolist() == [int(5 * seconds)] * 4
    assert meas.compass_mask.sum(axis=1).tolist() == [int(5 * seconds)] * 4
    gaps = np.diff(np.flatnonzero(meas.gps_mask[0])) * DT
    np.testing.assert_allclose(gaps, 0.1)
    assert measurement_schedule(10, 0.1, 10.0).all()


def test_noise_levels_match_the_sensor_spec(run):
    traj, meas = run
    s = RobotSensorNoise()
    assert np.std(meas.gps - traj.position) == pytest.approx(s.gps, rel=0.03)
    assert np.std(meas.glonass - traj.position) == pytest.approx(s.glonass, rel=0.03)
    dphi = np.angle(np.exp(1j * (meas.compass - traj.heading)))
    assert np.std(dphi) == pytest.approx(np.deg2rad(s.compass_deg), rel=0.03)
    enc = meas.encoder - encoder_speed(traj.v_c, traj.alpha)
    assert np.std(enc) == pytest.approx(s.encoder, rel=0.03)


def test_stepping_equals_whole_episode(run):
    traj, meas = run
    rngs = [np.random.default_rng(s) for s in range(4)]
    stream = NormalStream(rngs, ROBOT_NOISE_WIDTH, chunk=100)
    for k in range(250):
        step = traj._replace(
            **{f: getattr(traj, f)[:, k : k + 1] for f in ("t", "position", "heading", "v_c", "alpha")}
        )
        z = stream.next()[:, None, :]
        out = robot_measurements(step, np.full((4, 1), k), z, DT)
        for a, b in zip(out, meas, strict=True):
            np.testing.assert_array_equal(a[:, 0], b[:, k])


def test_schedule_and_fix_validation():
    with pytest.raises(ValueError, match="rate_hz"):
        measurement_schedule(10, 0.02, 3.0)  # 1/(3 * 0.02) is not an integer
    with pytest.raises(ValueError, match="dt"):
        is_measurement_step(0, -0.1, 5.0)
    with pytest.raises(ValueError, match="noise"):
        position_fixes(np.zeros((1, 2, 2)), 1.0, np.zeros((1, 2, 3)))
    with pytest.raises(ValueError, match="sigma"):
        position_fixes(np.zeros((1, 2, 2)), -1.0, np.zeros((1, 2, 2)))
    with pytest.raises(ValueError, match="encoder"):
        RobotSensorNoise(encoder=-0.1)
