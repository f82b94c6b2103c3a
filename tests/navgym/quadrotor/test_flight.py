import numpy as np
import pytest

from navgym import geo
from navgym.ins import gravity_ned, rotation_vector
from navgym.motion.trajectory import replace_episodes
from navgym.quadrotor.flight import (
    N_PHASES,
    QuadrotorParams,
    quadrotor_imu,
    quadrotor_leg_lengths,
    quadrotor_trajectory,
    sample_quadrotor_plans,
)
from tests.navgym.motion.tolerances import CLOSURE_M, CONTINUITY_FACTOR, EXACT_ATOL, FD_ATOL

SEEDS = list(range(20, 26))


@pytest.fixture(scope="module")
def plans():
    return sample_quadrotor_plans(SEEDS)


def test_triangle_legs_between_100_and_500_m():
    plan = sample_quadrotor_plans(range(200))
    legs = quadrotor_leg_lengths(plan)
    assert legs.min() >= 100.0 and legs.max() <= 500.0
    assert legs.max() > 400.0 and legs.min() < 150.0  # the whole range is used
    assert plan.t_start.shape == (200, N_PHASES)


def test_returns_home_and_visits_the_vertices(plans):
    b = len(SEEDS)
    end = quadrotor_trajectory(plans, plans.t_landed[:, None] + [0.0, 50.0])
    assert np.abs(end.position_ned).max() < CLOSURE_M
    assert np.abs(end.v_ned).max() < CLOSURE_M
    # hover at A and B: the design frame passes exactly through the vertices
    a_time = plans.t_start[:, 4] + 0.5 * plans.duration[:, 4]
    b_time = plans.t_start[:, 6] + 0.5 * plans.duration[:, 6]
    tr = quadrotor_trajectory(plans, np.stack([a_time, b_time], axis=1))
    np.testing.assert_allclose(tr.position_ned, plans.vertices[:, 1:], atol=CLOSURE_M)
    # climbs: altitude reached at the vertices lies in the sampled range
    assert np.all(-plans.vertices[:, :, 2] >= 20.0) and b == plans.origin.shape[0]


def test_velocity_and_acceleration_are_continuous(plans):
    dt = 0.005
    t = np.arange(0.0, plans.t_landed.max() + 5.0, dt)
    tr = quadrotor_trajectory(plans, t)
    a_peak = np.linalg.norm(tr.a_ned, axis=-1).max()
    dv = np.linalg.norm(np.diff(tr.v_ned, axis=1), axis=-1).max()
    assert dv <= CONTINUITY_FACTOR * a_peak * dt
    jerk = np.linalg.norm(np.diff(tr.a_ned, axis=1), axis=-1) / dt
    assert jerk.max() < 5.0  # bounded jerk: no acceleration steps
    dw = np.linalg.norm(np.diff(tr.angular_rate, axis=1), axis=-1).max()
    assert dw < 0.02  # angular rate continuous at 200 Hz
    assert a_peak <= QuadrotorParams().max_accel * 1.01 * np.sqrt(3)


def test_derivatives_are_consistent(plans):
    t = np.linspace(0.0, 400.0, 97)
    d = 1e-3
    tr, tp, tm = (quadrotor_trajectory(plans, t + s) for s in (0.0, d, -d))
    ecef_p = geo.geodetic_to_ecef(tp.lat, tp.lon, tp.h)
    ecef_m = geo.geodetic_to_ecef(tm.lat, tm.lon, tm.h)
    v_fd = np.einsum("btij,btj->bti", geo.ecef_to_ned_matrix(tr.lat, tr.lon), (ecef_p - ecef_m) / (2 * d))
    np.testing.assert_allclose(v_fd, tr.v_ned, atol=FD_ATOL)
    np.testing.assert_allclose((tp.v_ned - tm.v_ned) / (2 * d), tr.a_ned, atol=FD_ATOL)
    rel = np.einsum("btji,btjk->btik", tm.C_b_n, tp.C_b_n)
    np.testing.assert_allclose(rotation_vector(rel) / (2 * d), tr.omega_nb_b, atol=FD_ATOL)


def test_hover_senses_minus_gravity(plans):
    t = plans.t_start[:, 4] + 0.5 * plans.duration[:, 4]
    tr = quadrotor_trajectory(plans, t[:, None])
    g = gravity_ned(tr.lat, tr.h)[..., 2]
    np.testing.assert_allclose(np.linalg.norm(tr.specific_force, axis=-1), g, rtol=1e-4)
    np.testing.assert_allclose(tr.specific_force[..., 2], -g, rtol=1e-3)


def test_batch_equals_single_and_step_equals_whole(plans):
    t = np.arange(0.0, 120.0, 0.37)
    whole = quadrotor_trajectory(plans, t)
    for i, s in enumerate(SEEDS[:2]):
        single = quadrotor_trajectory(sample_quadrotor_plans([s]), t)
        for a, b in zip(single, whole, strict=True):
            np.testing.assert_array_equal(a[0], b[i])
    for k in (0, 7, 200):
        step = quadrotor_trajectory(plans, t[k])
        np.testing.assert_allclose(step.position_ned[:, 0], whole.position_ned[:, k], atol=EXACT_ATOL)
        np.testing.assert_allclose(step.angular_rate[:, 0], whole.angular_rate[:, k], atol=EXACT_ATOL)
    # per-episode times (sub-environments at different steps after autoreset)
    per = quadrotor_trajectory(plans, t[np.arange(len(SEEDS))][:, None])
    np.testing.assert_array_equal(per.lat[:, 0], whole.lat[np.arange(len(SEEDS)), np.arange(len(SEEDS))])


def test_replace_episodes_swaps_rows(plans):
    new = sample_quadrotor_plans([99])
    swapped = replace_episodes(plans, [2], new)
    np.testing.assert_array_equal(swapped.vertices[2], new.vertices[0])
    np.testing.assert_array_equal(swapped.vertices[3], plans.vertices[3])


def test_bad_input_raises_naming_argument(plans):
    with pytest.raises(ValueError, match="leg_length"):
        QuadrotorParams(leg_length=(500.0, 100.0))
    with pytest.raises(ValueError, match="speed"):
        QuadrotorParams(speed=(-1.0, 5.0))
    with pytest.raises(ValueError, match="max_accel"):
        QuadrotorParams(max_accel=0.0)
    with pytest.raises(ValueError, match="origin_lat_deg"):
        QuadrotorParams(origin_lat_deg=(0.0, 95.0))
    with pytest.raises(ValueError, match="t must"):
        quadrotor_trajectory(plans, np.zeros((3, 4)))
    with pytest.raises(ValueError, match="seeds_or_rngs"):
        sample_quadrotor_plans([])


def test_imu_only_evaluation_equals_the_trajectory_outputs(plans):
    t = plans.t_start[:, :1] + np.linspace(0.0, 50.0, 37)
    traj = quadrotor_trajectory(plans, t)
    f_ib, w_ib = quadrotor_imu(plans, t)
    np.testing.assert_array_equal(np.stack(f_ib, axis=-1), traj.specific_force)
    np.testing.assert_array_equal(np.stack(w_ib, axis=-1), traj.angular_rate)


def test_home_frame_truth_is_the_trajectory_rotated_back_home(plans):
    """quadrotor_home_truth == quadrotor_trajectory's local-NED truth rotated into the home frame."""
    from navgym.ins import dcm_to_euler
    from navgym.quadrotor.flight import quadrotor_home_truth

    t = plans.t_start[:, :1] + np.linspace(0.0, plans.t_landed.min() - plans.t_start[:, :1].max(), 301)
    traj = quadrotor_trajectory(plans, t)
    pos, vel, (roll, pitch, yaw) = quadrotor_home_truth(plans, t)
    C_home = geo.ecef_to_ned_matrix(plans.origin[:, 0], plans.origin[:, 1])
    Mt = np.swapaxes(
        geo.ecef_to_ned_matrix(traj.lat, traj.lon) @ np.swapaxes(C_home, -1, -2)[:, None], -1, -2
    )
    np.testing.assert_allclose(np.stack(pos, axis=-1), traj.position_ned, rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        np.stack(vel, axis=-1), (Mt @ traj.v_ned[..., None])[..., 0], rtol=0, atol=1e-12
    )
    ref = dcm_to_euler(Mt @ traj.C_b_n)
    for a, b in zip((roll, pitch, yaw), ref, strict=True):
        np.testing.assert_allclose(np.angle(np.exp(1j * (a - b))), 0.0, atol=1e-12)
    assert np.ptp(yaw) > 3.0 and np.abs(pitch).max() > 0.01  # turns and tilted flight covered
