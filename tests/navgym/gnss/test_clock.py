import numpy as np
import pytest
import scipy.linalg

from navgym.gnss import CLOCK_A, CLOCK_SIGMA_W, ClockParams, clock_init, clock_step, clock_transition

from .tolerances import MC_STD_REL


def test_seed_constants():
    assert CLOCK_A == 1 / 500 and CLOCK_SIGMA_W == 1e-12


@pytest.mark.parametrize("dt", [1e-3, 0.1, 1.0, 30.0, 2000.0])
def test_transition_matches_van_loan(dt):
    a, q = CLOCK_A, CLOCK_SIGMA_W**2
    f = np.array([[0.0, 1.0], [0.0, -a]])
    g = np.array([[0.0, 0.0], [0.0, q]])
    m = scipy.linalg.expm(np.block([[-f, g], [np.zeros((2, 2)), f.T]]) * dt)
    phi_ref = m[2:, 2:].T
    q_ref = phi_ref @ m[:2, 2:]
    phi, big_q = clock_transition(dt)
    np.testing.assert_allclose(phi, phi_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(big_q, q_ref, rtol=1e-7, atol=0)


def test_q11_series_and_closed_form_agree_at_switch():
    lo = clock_transition(0.4999999 / CLOCK_A * 1e-3 * 2)[1][0, 0]
    hi = clock_transition(0.5000001 / CLOCK_A * 1e-3 * 2)[1][0, 0]
    assert lo == pytest.approx(hi, rel=1e-5)


def _allan_from_structure(d_tau, d_2tau, tau):
    return (4 * d_tau - d_2tau) / (2 * tau**2)


def test_monte_carlo_statistics_follow_eq_11():
    """Stationary drift variance, correlation exp(-a tau), bias increments and Allan var."""
    b = 20000
    a, sw = CLOCK_A, CLOCK_SIGMA_W
    var_d = sw**2 / (2 * a)
    params = ClockParams(bias0_std=0.0, drift0_std=np.sqrt(var_d))
    rng = np.random.default_rng(7)
    state = clock_init(rng.standard_normal((b, 2)), params)
    d0 = state.drift.copy()
    tau = 250
    bias = [state.bias.copy()]
    for k in range(1, 2 * tau + 1):
        state = clock_step(state, 1.0, rng.standard_normal((b, 2)), params)
        if k % tau == 0:
            bias.append(state.bias.copy())
            if k == tau:
                d_tau = state.drift.copy()
    assert np.std(state.drift) == pytest.approx(np.sqrt(var_d), rel=MC_STD_REL)
    corr = np.corrcoef(d0, d_tau)[0, 1]
    assert corr == pytest.approx(np.exp(-a * tau), abs=0.02)

    def structure(t):  # Var(b(t) - b(0)) for a stationary Gauss-Markov drift
        return 2 * var_d * (a * t - 1 + np.exp(-a * t)) / a**2

    inc = bias[1] - bias[0]
    assert np.std(inc) == pytest.approx(np.sqrt(structure(tau)), rel=MC_STD_REL)
    second = bias[2] - 2 * bias[1] + bias[0]
    avar = 0.5 * np.mean(second**2) / tau**2
    avar_ref = _allan_from_structure(structure(tau), structure(2 * tau), tau)
    assert avar == pytest.approx(avar_ref, rel=3 * MC_STD_REL)


def test_per_episode_parameters_and_bad_input():
    z = np.zeros((3, 2))
    st = clock_init(np.ones((3, 2)), ClockParams(drift0_std=1e-9, bias0_std=1e-7))
    assert st.bias_m == pytest.approx(299792458.0 * 1e-7)
    nxt = clock_step(st, np.array([1.0, 10.0, 100.0]), z, ClockParams(a=np.array([0.1, 0.2, 0.3])))
    np.testing.assert_allclose(nxt.drift, 1e-9 * np.exp(-np.array([0.1, 2.0, 30.0])))
    with pytest.raises(ValueError, match="z"):
        clock_step(st, 1.0, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="a must"):
        clock_transition(1.0, a=0.0)
