import numpy as np
import pytest

from navgym.robot2d.robot import (
    RobotGeometry,
    RobotParams,
    encoder_speed,
    robot_derivative,
    robot_trajectory,
    robot_transition,
    sample_robot_plans,
)
from tests.navgym.motion.tolerances import EXACT_ATOL

SEEDS = [1, 2, 3]


def _state(tr):
    return np.concatenate([tr.position, tr.heading[..., None]], axis=-1)


@pytest.mark.parametrize("as_printed", [False, True])
def test_trajectory_follows_eq_77_exactly(as_printed):
    plan = sample_robot_plans(SEEDS)
    # times strictly inside command segments (inputs are piecewise constant)
    t = (plan.t_start[:, :-1] + 0.5 * np.diff(plan.t_start, axis=1))[:, :40]
    d = 1e-5
    tr, tp, tm = (robot_trajectory(plan, t + s, as_printed=as_printed) for s in (0.0, d, -d))
    fd = (_state(tp) - _state(tm)) / (2 * d)
    rhs = robot_derivative(_state(tr), tr.v_c, tr.alpha, as_printed=as_printed)
    np.testing.assert_allclose(fd, rhs, atol=1e-6)


def test_eq_77_rhs_in_closed_form():
    g = RobotGeometry()
    phi, v, alpha = 0.3, 2.0, 0.2
    w = v / g.wheelbase * np.tan(alpha)
    rhs = robot_derivative([0.0, 0.0, phi], v, alpha)
    expected = [
        v * np.cos(phi) - w * (g.a * np.sin(phi) + g.b * np.cos(phi)),
        v * np.sin(phi) + w * (g.a * np.cos(phi) - g.b * np.sin(phi)),
        w,
    ]
    np.testing.assert_allclose(rhs, expected, rtol=1e-15)
    printed = robot_derivative([0.0, 0.0, phi], v, alpha, as_printed=True)
    assert printed[1] == pytest.approx(v * np.sin(phi) - w * (g.a * np.cos(phi) + g.b * np.sin(phi)))


@pytest.mark.parametrize("as_printed", [False, True])
def test_transition_is_exact_for_constant_inputs(as_printed):
    plan = sample_robot_plans(SEEDS)
    t0 = plan.t_start[:, :30] + 0.1
    dt = 0.2  # shorter than any command segment (>= 2 s) after the 0.1 s offset
    a = robot_trajectory(plan, t0, as_printed=as_printed)
    b = robot_trajectory(plan, t0 + dt, as_printed=as_printed)
    u = np.stack([a.v_c, a.alpha], axis=-1)
    np.testing.assert_allclose(
        robot_transition(_state(a), u, dt, as_printed=as_printed), _state(b), atol=EXACT_ATOL
    )
    # broadcasting over particles (B, N, 3)
    parts = np.repeat(_state(a)[:, :1], 5, axis=1)
    out = robot_transition(parts, u[:, :1], dt)
    assert out.shape == parts.shape


def test_encoder_speed_is_guivant_nebot():
    g = RobotGeometry()
    assert encoder_speed(2.0, 0.0) == 2.0
    assert encoder_speed(2.0, 0.3) == pytest.approx(2.0 * (1 - g.encoder_offset * np.tan(0.3) / g.wheelbase))


def test_starts_at_origin_and_batch_equals_single():
    plan = sample_robot_plans(SEEDS)
    t = np.arange(0.0, 300.0, 0.02)
    whole = robot_trajectory(plan, t)
    np.testing.assert_allclose(whole.position[:, 0], 0.0, atol=1e-12)
    for i, s in enumerate(SEEDS):
        one = robot_trajectory(sample_robot_plans([s]), t)
        np.testing.assert_array_equal(one.position[0], whole.position[i])


def test_bad_input_raises_naming_argument():
    with pytest.raises(ValueError, match="wheelbase"):
        RobotGeometry(wheelbase=0.0)
    with pytest.raises(ValueError, match="steering_deg"):
        RobotParams(steering_deg=(-100.0, 10.0))
    with pytest.raises(ValueError, match="straight_probability"):
        RobotParams(straight_probability=-0.1)
    with pytest.raises(ValueError, match="dt"):
        robot_transition(np.zeros(3), np.zeros(2), 0.0)
    with pytest.raises(ValueError, match="state"):
        robot_transition(np.zeros(2), np.zeros(2), 0.1)
