import numpy as np
import pytest
from scipy.integrate import quad

from navgym import geo
from navgym.gps_ins import vehicle
from navgym.gps_ins.vehicle import (
    LAND_VEHICLE,
    SHIP,
    VehicleParams,
    sample_vehicle_plans,
    vehicle_track,
    vehicle_trajectory,
)
from navgym.motion.profiles import gauss_legendre_partial, segment_index, smootherstep
from navgym.motion.trajectory import trajectory_heading
from tests.navgym.motion.tolerances import EXACT_ATOL, FD_ATOL

SEEDS = [3, 4, 5]


@pytest.mark.parametrize("params", [LAND_VEHICLE, SHIP], ids=["land", "ship"])
def test_velocity_is_the_derivative_of_position(params):
    plan = sample_vehicle_plans(SEEDS, params)
    t = np.linspace(0.0, params.duration, 301)
    d = 1e-3
    tr, tp, tm = (vehicle_trajectory(plan, t + s) for s in (0.0, d, -d))
    ecef_p = geo.geodetic_to_ecef(tp.lat, tp.lon, tp.h)
    ecef_m = geo.geodetic_to_ecef(tm.lat, tm.lon, tm.h)
    v_fd = np.einsum("btij,btj->bti", geo.ecef_to_ned_matrix(tr.lat, tr.lon), (ecef_p - ecef_m) / (2 * d))
    np.testing.assert_allclose(v_fd, tr.v_ned, atol=FD_ATOL)
    np.testing.assert_allclose((tp.v_ned - tm.v_ned) / (2 * d), tr.a_ned, atol=FD_ATOL)
    speed = np.linalg.norm(tr.v_ned, axis=-1)
    assert speed.min() >= params.speed[0] * 0.99 and speed.max() <= params.speed[1] * 1.01
    assert np.abs(tr.a_ned).max() <= 1.05 * np.hypot(params.max_lateral_accel, params.max_longitudinal_accel)
    assert np.all(tr.h == tr.h[:, :1])  # constant height: ship at sea level, car on flat ground
    course = np.arctan2(tr.v_ned[..., 1], tr.v_ned[..., 0])
    sideslip = np.angle(np.exp(1j * (course - trajectory_heading(tr))))
    assert np.abs(sideslip).max() < 1e-2  # heading Theta is the direction of travel


def test_heading_and_speed_change_during_an_hour():
    plan = sample_vehicle_plans(SEEDS)
    tr = vehicle_trajectory(plan, np.arange(0.0, 3600.0, 1.0))
    heading = np.unwrap(trajectory_heading(tr), axis=1)
    assert np.all(np.ptp(heading, axis=1) > np.deg2rad(30))
    assert np.all(np.ptp(np.linalg.norm(tr.v_ned, axis=-1), axis=1) > 2.0)


def test_gauss_legendre_partial_is_exact_for_maneuver_integrands():
    # the worst maneuver: a 120 deg heading change with a speed change over one segment
    d, dth = 10.0, np.deg2rad(120.0)

    def north_speed(x):
        tau = x / d
        return (5.0 + 20.0 * smootherstep(tau)) * np.cos(0.3 + dth * smootherstep(tau))

    upper = np.array([0.5, 3.0, 7.0, 10.0])
    got = gauss_legendre_partial(north_speed, upper)
    ref = [quad(north_speed, 0.0, u, epsabs=1e-13, epsrel=1e-13)[0] for u in upper]
    np.testing.assert_allclose(got, ref, atol=1e-9)


@pytest.mark.parametrize("params", [LAND_VEHICLE, SHIP], ids=["land", "ship"])
def test_closed_form_arc_of_straight_segments_equals_quadrature(params):
    # constant-heading segments (cruise, speed-only maneuvers) use the smootherstep integral;
    # it must agree with the quadrature that turning segments use, segment by segment
    plan = sample_vehicle_plans(SEEDS, params)
    t = np.broadcast_to(np.arange(0.0, params.duration, 0.7), (len(SEEDS), int(params.duration / 0.7) + 1))
    i = segment_index(plan.t_start, t)
    fields = (plan.duration, plan.speed_start, plan.speed_end, plan.heading_start, plan.heading_end)
    rows = tuple(np.take_along_axis(x, i, axis=1) for x in fields)
    elapsed = t - np.take_along_axis(plan.t_start, i, axis=1)
    straight = rows[3] == rows[4]
    speed_change = straight & (rows[1] != rows[2])
    assert straight.mean() > 0.5 and speed_change.any() and (~straight).any()  # all three kinds
    got = vehicle._arc(rows, elapsed)
    ref = vehicle._arc_quadrature(tuple(r.ravel() for r in rows), elapsed.ravel()).reshape(got.shape)
    np.testing.assert_allclose(got, ref, atol=EXACT_ATOL, rtol=0)


def test_batch_equals_single_and_step_equals_whole():
    plan = sample_vehicle_plans(SEEDS)
    t = np.arange(0.0, 600.0, 1.0)
    whole = vehicle_trajectory(plan, t)
    for i, s in enumerate(SEEDS):
        single = vehicle_trajectory(sample_vehicle_plans([s]), t)
        for a, b in zip(single, whole, strict=True):
            np.testing.assert_array_equal(a[0], b[i])
    step = vehicle_trajectory(plan, t[123])
    np.testing.assert_allclose(step.lat[:, 0], whole.lat[:, 123], atol=EXACT_ATOL, rtol=0)
    np.testing.assert_allclose(step.specific_force[:, 0], whole.specific_force[:, 123], atol=EXACT_ATOL)


def test_bad_input_raises_naming_argument():
    with pytest.raises(ValueError, match="duration"):
        VehicleParams(duration=-1.0)
    with pytest.raises(ValueError, match="turn_probability"):
        VehicleParams(turn_probability=1.5)
    with pytest.raises(ValueError, match="max_turn_deg"):
        VehicleParams(max_turn_deg=270.0)
    with pytest.raises(ValueError, match="cruise"):
        VehicleParams(cruise=(0.0, 10.0))


@pytest.mark.parametrize("params", [LAND_VEHICLE, SHIP])
def test_vehicle_track_equals_vehicle_trajectory(params):
    """The GpsIns episodes' track is vehicle_trajectory's position and heading, bit for bit."""
    plans = sample_vehicle_plans([np.random.default_rng(s) for s in range(7)], params)
    times = np.arange(301) * 1.0
    track = vehicle_track(plans, times)
    traj = vehicle_trajectory(plans, times, imu=False)
    for name in ("lat", "lon", "h", "position_ned"):
        np.testing.assert_array_equal(getattr(track, name), getattr(traj, name), err_msg=name)
    np.testing.assert_array_equal(track.heading, trajectory_heading(traj))
    np.testing.assert_array_equal(track.ecef, geo.geodetic_to_ecef(traj.lat, traj.lon, traj.h))
