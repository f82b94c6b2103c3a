import numpy as np
import pytest

from navgym import geo
from navgym.ins import (
    CLOCK_A,
    CLOCK_SIGMA_W,
    InsErrorParams,
    gps_ins_process_noise,
    gps_ins_transition,
    ins_error_initial_covariance,
    ins_error_process_noise,
    ins_error_transition,
    ins_indicated_position,
    position_error_to_radians,
    receiver_clock_process_noise,
    receiver_clock_transition,
    simulate_ins_errors,
)
from navgym.scenarios import standard_normal_batch

from .tolerances import EXACT_ATOL, MC_VAR_RTOL

UNLIMITED = InsErrorParams(bias_limit=np.inf, sigma_x=2e-6, sigma_y=3e-6)


def _headings(b, n, dt, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    return rng.uniform(0, 2 * np.pi, (b, 1)) + 0.01 * t[None, :]  # steady turn


def test_transition_is_carvalho_1997_eq_13():
    th, dt, K = 0.4, 2.0, 1e-3
    F = ins_error_transition(th, dt, K)
    c, s = np.cos(th), np.sin(th)
    expected = np.array(
        [
            [1, 0, dt, 0, 0, 0],
            [0, 1, 0, dt, 0, 0],
            [0, 0, 1 - K * dt, 0, -dt * c, -dt * s],
            [0, 0, 0, 1 - K * dt, -dt * s, dt * c],
            [0, 0, 0, 0, 1, 0],
            [0, 0, 0, 0, 0, 1],
        ]
    )
    np.testing.assert_array_equal(F, expected)
    Q = ins_error_process_noise(dt, 2.0, 3.0)
    np.testing.assert_array_equal(Q, np.diag([0, 0, 0, 0, 4 * dt, 9 * dt]))
    np.testing.assert_array_equal(receiver_clock_transition(dt), [[1, dt], [0, 1 - CLOCK_A * dt]])
    np.testing.assert_array_equal(receiver_clock_process_noise(dt), np.diag([0, CLOCK_SIGMA_W**2 * dt]))
    assert CLOCK_A == 1 / 500 and CLOCK_SIGMA_W == 1e-12


def test_eight_state_model_is_block_diagonal_and_batched():
    th = np.array([0.1, 1.0, 2.0])
    F = gps_ins_transition(th, 1.0)
    assert F.shape == (3, 8, 8)
    np.testing.assert_array_equal(F[:, :6, :6], ins_error_transition(th, 1.0))
    np.testing.assert_array_equal(F[:, 6:, 6:], np.broadcast_to(receiver_clock_transition(1.0), (3, 2, 2)))
    assert not F[:, :6, 6:].any() and not F[:, 6:, :6].any()
    Q = gps_ins_process_noise(1.0, 1e-6, 2e-6)
    np.testing.assert_array_equal(np.diag(Q), [0, 0, 0, 0, 1e-12, 4e-12, 0, 1e-24])
    # exact clock block (the GNSS simulator's discretization) is close to eq. 13's Euler step
    Fe = gps_ins_transition(0.3, 1.0, exact=True)
    np.testing.assert_array_equal(Fe[:6, :6], ins_error_transition(0.3, 1.0))
    np.testing.assert_allclose(Fe[6:, 6:], receiver_clock_transition(1.0), rtol=1e-3)
    Qe = gps_ins_process_noise(1.0, exact=True)
    assert Qe[7, 7] == pytest.approx(CLOCK_SIGMA_W**2, rel=1e-2) and Qe[6, 6] > 0


def test_simulation_equals_stepping_eq_13():
    b, n, dt = 3, 200, 1.0
    th = _headings(b, n, dt)
    seeds = [5, 6, 7]
    e = simulate_ins_errors(th, dt, UNLIMITED, [np.random.default_rng(s) for s in seeds])
    rngs = [np.random.default_rng(s) for s in seeds]
    z0 = standard_normal_batch(rngs, (6,))
    zw = standard_normal_batch(rngs, (n - 1, 2))
    x = z0 * np.sqrt(np.diag(ins_error_initial_covariance(UNLIMITED)))
    chol_q = np.sqrt(np.diag(ins_error_process_noise(dt, UNLIMITED.sigma_x, UNLIMITED.sigma_y)))
    for k in range(n):
        np.testing.assert_allclose(e[:, k], x, rtol=1e-9, atol=EXACT_ATOL)
        if k < n - 1:
            w = np.zeros((b, 6))
            w[:, 4:] = zw[:, k]
            x = np.einsum("bij,bj->bi", ins_error_transition(th[:, k], dt, UNLIMITED.K), x)
            x = x + chol_q * w


def test_monte_carlo_matches_covariance_propagation():
    n_mc, n, dt = 3000, 600, 1.0
    th = np.broadcast_to(_headings(1, n, dt, seed=3), (n_mc, n))
    e = simulate_ins_errors(th, dt, UNLIMITED, [np.random.default_rng(s) for s in range(n_mc)])
    P = ins_error_initial_covariance(UNLIMITED)
    Q = ins_error_process_noise(dt, UNLIMITED.sigma_x, UNLIMITED.sigma_y)
    checkpoints = {0, 100, 300, n - 1}
    for k in range(n):
        if k in checkpoints:
            sample = np.cov(e[:, k].T)
            np.testing.assert_allclose(np.diag(sample), np.diag(P), rtol=MC_VAR_RTOL)
            # correlations (e.g. position-bias) agree in absolute terms
            d = np.sqrt(np.diag(P))
            corr_err = (sample - P) / np.outer(d, d)
            assert np.abs(corr_err).max() < 0.1
        F = ins_error_transition(th[0, k], dt, UNLIMITED.K)
        P = F @ P @ F.T + Q


def test_default_biases_stay_within_10_ug():
    th = _headings(20, 3600, 1.0)
    e = simulate_ins_errors(th, 1.0, InsErrorParams(), [np.random.default_rng(s) for s in range(20)])
    assert np.abs(e[..., 4:]).max() <= 10e-6 * 9.80665 * (1 + 1e-12)
    assert np.abs(e[..., 4:]).max() > 5e-6 * 9.80665  # the walk does reach the limit region


def test_batch_equals_single_episodes():
    th = _headings(4, 50, 1.0)
    batch = simulate_ins_errors(th, 1.0, InsErrorParams(), [np.random.default_rng(s) for s in range(10, 14)])
    for i in range(4):
        one = simulate_ins_errors(th[i : i + 1], 1.0, InsErrorParams(), [np.random.default_rng(10 + i)])
        np.testing.assert_array_equal(one[0], batch[i])


def test_indicated_position_eq_14():
    lat, lon, h = np.deg2rad(45.0), np.deg2rad(1.0), 100.0
    e = np.array([30.0, -20.0, 0, 0, 0, 0])  # 30 m east, 20 m south
    lat_i, lon_i = ins_indicated_position(lat, lon, e, h)
    ned = geo.ecef_to_ned(geo.geodetic_to_ecef(lat_i, lon_i, h), lat, lon, h)
    np.testing.assert_allclose(ned[:2], [-20.0, 30.0], atol=1e-3)
    d_lon, d_lat = position_error_to_radians(e, lat, h)
    assert lon_i - lon == pytest.approx(d_lon) and lat_i - lat == pytest.approx(d_lat)


def test_bad_input_raises_naming_argument():
    with pytest.raises(ValueError, match="dt"):
        ins_error_transition(0.0, 0.0)
    with pytest.raises(ValueError, match="K"):
        ins_error_transition(0.0, 1.0, K=-1.0)
    with pytest.raises(ValueError, match="heading"):
        ins_error_transition(np.nan, 1.0)
    with pytest.raises(ValueError, match="sigma_x"):
        InsErrorParams(sigma_x=-1.0)
    with pytest.raises(ValueError, match="bias_limit"):
        InsErrorParams(bias_limit=0.0)
    with pytest.raises(ValueError, match="heading"):
        simulate_ins_errors(np.zeros(5), 1.0, InsErrorParams(), [np.random.default_rng(0)])
    with pytest.raises(ValueError, match="rngs"):
        simulate_ins_errors(np.zeros((2, 5)), 1.0, InsErrorParams(), [np.random.default_rng(0)])
    with pytest.raises(ValueError, match="sigma_w"):
        receiver_clock_process_noise(1.0, -1.0)


def test_per_episode_bias_limits_equal_one_call_per_episode():
    """bias_limit (B,) scales walk, limit and initial bias sigma per episode, value for value
    equal to separate calls with the scaled parameters; bad limits are rejected."""
    from dataclasses import replace

    from navgym.ins.error_model import InsErrorParams, simulate_ins_errors

    p = InsErrorParams()
    B, T = 5, 400
    heading = np.random.default_rng(0).uniform(-np.pi, np.pi, (B, T))
    limits = p.bias_limit * np.array([1.0, 3.0, 0.5, 20.0, 7.3])
    batched = simulate_ins_errors(
        heading, 1.0, p, [np.random.default_rng(s) for s in range(B)], bias_limit=limits
    )
    for b in range(B):
        k = limits[b] / p.bias_limit
        q = replace(
            p,
            sigma_x=p.sigma_x * k,
            sigma_y=p.sigma_y * k,
            bias_limit=limits[b],
            sigma_bias0=p.sigma_bias0 * k,
        )
        one = simulate_ins_errors(heading[b : b + 1], 1.0, q, [np.random.default_rng(b)])
        np.testing.assert_array_equal(batched[b], one[0])
        assert np.abs(batched[b, :, 4:6]).max() <= limits[b]
    with pytest.raises(ValueError, match="bias_limit"):
        simulate_ins_errors(
            heading, 1.0, p, [np.random.default_rng(s) for s in range(B)], bias_limit=[1.0, 2.0]
        )
