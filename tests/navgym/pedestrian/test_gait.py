"""The walk and the foot's kinematics (navgym.pedestrian.gait): known answers and finite differences."""

import numpy as np

from navgym.pedestrian.gait import (
    MAX_TURN_PER_STRIDE,
    PLAN_WIDTH,
    SPEED,
    foot_state,
    stride_plan,
)

B, T, DT = 6, 200, 1.0


def _plan(seed: int = 0):
    rng = np.random.default_rng(seed)
    return stride_plan(rng.random((B, T, PLAN_WIDTH)), 2.0 * np.pi * rng.random(B))


def test_strides_walk_at_a_segment_speed_or_stop_and_turn_at_most_45_deg():
    plan = _plan()
    L = plan.length
    moving = L > 0
    assert moving.mean() > 0.6 and (~moving).any()  # mostly walking, some stops
    assert np.all((L[moving] >= SPEED[0]) & (L[moving] <= SPEED[1]))
    assert np.abs(np.diff(plan.yaw, axis=1)).max() <= MAX_TURN_PER_STRIDE + 1e-12
    step = np.linalg.norm(np.diff(plan.start, axis=1), axis=-1)
    np.testing.assert_allclose(step, L, atol=1e-12)
    # piecewise constant: most strides keep the previous stride's length
    assert (np.diff(L, axis=1) == 0).mean() > 0.85


def test_the_foot_rests_at_the_epochs_and_lands_where_the_next_stride_starts():
    plan = _plan(1)
    k = np.broadcast_to(np.arange(T), (B, T))
    for frac, idx in ((0.0, 0), (0.1, 0), (0.9, 1), (1.0, 1)):  # the stance halves
        st = foot_state(plan, k, np.full((B, T), frac), DT)
        np.testing.assert_allclose(st.pos, plan.start[:, idx : T + idx], atol=1e-12)
        np.testing.assert_allclose(st.euler[..., 2], plan.yaw[:, idx : T + idx], atol=1e-12)
        for a in (st.vel, st.acc, st.rate, st.euler[..., :2]):
            np.testing.assert_allclose(a, 0.0, atol=1e-12)


def test_velocity_acceleration_and_rates_are_the_derivatives_of_the_motion():
    plan = _plan(2)
    k = np.broadcast_to(np.arange(T), (B, T))
    h = 1e-5
    for frac in (0.25, 0.4, 0.5, 0.63, 0.77):
        f = np.full((B, T), frac)
        st, lo, hi = (foot_state(plan, k, f + d, DT) for d in (0.0, -h, h))
        np.testing.assert_allclose((hi.pos - lo.pos) / (2 * h * DT), st.vel, atol=1e-5)
        np.testing.assert_allclose((hi.vel - lo.vel) / (2 * h * DT), st.acc, atol=1e-4)
        np.testing.assert_allclose((hi.euler - lo.euler) / (2 * h * DT), st.rate, atol=1e-5)
    mid = foot_state(plan, k, np.full((B, T), 0.5), DT)
    walking = plan.length > 0
    assert np.all(mid.pos[..., 2][walking] < -0.05)  # foot clearance (down is negative up)
    # the swinging foot outruns the walker
    assert np.all(np.linalg.norm(mid.vel[..., :2], axis=-1)[walking] > 1.5)
