"""Carvalho et al. 1997, §III-B regularization (Examples 1-2) and position jitter."""

import numpy as np
import pytest

from filters import ParticleState
from filters.particle import bootstrap, estimates
from filters.particle import regularization as reg

from .problems import simulate_linear, two_sensor_model
from .tolerances import EXACT_ATOL, EXACT_RTOL, N_SIGMA


def _quadratic_forms(xs, zs, model):
    """-1/2 ||Y_i - h(X_i)||^2_R for each step and particle (the exponent of Carvalho et al. 1997, eq. 3)."""
    H, Rinv = model.observation_matrix, np.linalg.inv(model.R)
    v = zs[:, :, None, :] - xs @ H.T  # (T, B, N, m)
    return -0.5 * np.einsum("tbni,ij,tbnj->tbn", v, Rinv, v)


def _run_without_resampling(model, B, N, T, seed):
    rng = np.random.default_rng(seed)
    _, zs = simulate_linear(model, B, T, rng)
    st = ParticleState(rng.standard_normal((B, N, 2)), np.full((B, N), -np.log(N)))
    xs = []
    for _k in range(T):
        st = bootstrap.predict(st, model, None, 1.0, rng)
        xs.append(st.x)
    return np.array(xs), zs


def _normalize(a):
    return a - estimates.logsumexp(a)[..., None]


@pytest.mark.parametrize("gamma", [1.0, 0.9, 0.5])
def test_forgetting_reproduces_example_1(gamma):
    """log w_k = normalize(sum_i gamma^(k-i) * (-1/2 ||Y_i - h(X_i)||^2_R)), no resampling."""
    model = two_sensor_model()
    B, N, T = 3, 50, 8
    xs, zs = _run_without_resampling(model, B, N, T, 0)
    q = _quadratic_forms(xs, zs, model)
    lw = np.full((B, N), -np.log(N))
    lw_age = lw.copy()
    for k in range(T):
        st, _ = bootstrap.update(ParticleState(xs[k], lw), zs[k], model, forgetting=gamma)
        lw = st.log_w
        ll = bootstrap.particle_log_likelihood(xs[k], zs[k], model)
        lw_age = reg.age_weight(lw_age, ll, gamma)
        expected = _normalize(sum(gamma ** (k - i) * q[i] for i in range(k + 1)))
        np.testing.assert_allclose(lw, expected, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        np.testing.assert_allclose(lw_age, expected, rtol=EXACT_RTOL, atol=EXACT_ATOL)


@pytest.mark.parametrize("T_window", [1, 3, 20])
def test_window_reproduces_example_2(T_window):
    """log w_k = normalize(sum of the last T terms), no resampling; T >= k is the plain filter."""
    model = two_sensor_model()
    B, N, T = 3, 40, 9
    xs, zs = _run_without_resampling(model, B, N, T, 1)
    q = _quadratic_forms(xs, zs, model)
    win = reg.window_init(B, N, T_window)
    for k in range(T):
        st, win, info = reg.window_update(ParticleState(xs[k], np.zeros((B, N))), win, zs[k], model)
        expected = _normalize(sum(q[i] for i in range(max(0, k - T_window + 1), k + 1)))
        np.testing.assert_allclose(st.log_w, expected, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        np.testing.assert_allclose(info.ess, estimates.ess(st.log_w), rtol=1e-12)
    if T_window >= T:
        lw = np.full((B, N), -np.log(N))
        for k in range(T):
            lw = bootstrap.update(ParticleState(xs[k], lw), zs[k], model)[0].log_w
        np.testing.assert_allclose(st.log_w, lw, rtol=EXACT_RTOL, atol=EXACT_ATOL)


def test_window_is_cleared_by_resampling_only_where_decided():
    model = two_sensor_model()
    B, N, T = 4, 30, 6
    xs, zs = _run_without_resampling(model, B, N, T, 2)
    q = _quadratic_forms(xs, zs, model)
    rng = np.random.default_rng(3)
    win = reg.window_init(B, N, 4)
    st = ParticleState(xs[0], np.zeros((B, N)))
    for k in range(3):
        st, win, _ = reg.window_update(st._replace(x=xs[k]), win, zs[k], model)
    d = np.array([True, False, True, False])
    st2, win2 = reg.window_resample(st, win, d, rng)
    assert (win2.log_lik[d] == 0).all()
    np.testing.assert_array_equal(win2.log_lik[~d], win.log_lik[~d])
    np.testing.assert_allclose(st2.log_w[d], -np.log(N))
    # after the reset, a decided filter's weights are the likelihood of the new step only
    st3, _, _ = reg.window_update(st2._replace(x=xs[3]), win2, zs[3], model)
    np.testing.assert_allclose(st3.log_w[~d], _normalize(q[0] + q[1] + q[2] + q[3])[~d], atol=EXACT_ATOL)
    np.testing.assert_allclose(st3.log_w[d], _normalize(q[3])[d], atol=EXACT_ATOL)


def test_roughen_scale_and_decision():
    rng = np.random.default_rng(0)
    B, N, n = 4, 20_000, 3
    x = rng.uniform(-1, 1, (B, N, n)) * np.array([1.0, 5.0, 0.1])
    st = ParticleState(x, np.full((B, N), -np.log(N)))
    K = np.array([0.2, 0.0, 0.5, 0.2])
    d = np.array([True, True, True, False])
    out = reg.roughen(st, rng, K, d)
    np.testing.assert_array_equal(out.x[~d], x[~d])
    np.testing.assert_array_equal(out.x[1], x[1])  # K = 0
    E = x.max(axis=1) - x.min(axis=1)
    for b in (0, 2):
        sigma = K[b] * E[b] * N ** (-1.0 / n)
        sd = (out.x[b] - x[b]).std(axis=0)
        assert (np.abs(sd / sigma - 1) < N_SIGMA / np.sqrt(2 * N)).all()


def test_kernel_jitter_covariance_and_bandwidth():
    assert reg.optimal_bandwidth(100, 1) == pytest.approx((4 / 300) ** 0.2)
    rng = np.random.default_rng(1)
    B, N, n = 2, 50_000, 2
    C = np.array([[1.0, 0.6], [0.6, 2.0]])
    st = bootstrap.from_gaussian(np.zeros((B, n)), C, N, rng)
    out = reg.kernel_jitter(st, rng, bandwidth_scale=np.array([1.0, 2.0]))
    noise = out.x - st.x
    for b, c in enumerate((1.0, 2.0)):
        want = (c * reg.optimal_bandwidth(N, n)) ** 2 * estimates.covariance(st)[b]
        got = np.cov(noise[b].T)
        np.testing.assert_allclose(got, want, atol=N_SIGMA * np.sqrt(2 / N) * want.max())
    same = reg.kernel_jitter(st, rng, decision=False)
    assert same.x is st.x


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("frac", [0.5, 1.0], ids=["some-rows", "every-row"])
def test_roughen_kernel_equals_numpy_twin(dtype, frac):
    """The compiled roughening of a component-major cloud equals the NumPy path bit for bit.

    Same normals; NaN and inf in some components (the range is NaN there, as np.max/np.min give).
    """
    B, N, n = 24, 300, 5
    r = np.random.default_rng(1)
    xT = r.standard_normal((B, n, N)) * r.uniform(0.1, 100.0, (B, n, 1)) + r.uniform(-1e4, 1e4, (B, n, 1))
    xT = xT.astype(dtype)
    xT[3, 2, 5] = np.nan
    xT[4, 1, 0] = np.nan
    xT[5, 0, 7] = np.inf
    state = ParticleState(xT.transpose(0, 2, 1), np.full((B, N), -np.log(N)))
    rows = np.flatnonzero(r.random(B) < frac)
    rows = rows if rows.size else np.arange(B)
    K = r.uniform(0.0, 0.5, B)
    scale = K[rows] * float(N) ** (-1.0 / n)  # as roughen forms it
    e = bootstrap.component_major_normals(
        [np.random.default_rng(9 + b) for b in range(B)], B, N, n, rows, dtype
    )
    with np.errstate(invalid="ignore"):
        want = reg._roughen_numpy(state, e.copy(), scale, rows)
        got = reg._roughen_compiled(state, e.copy(), scale, rows)
    np.testing.assert_array_equal(got.x, want.x)
    assert got.x.dtype == want.x.dtype and got.x.transpose(0, 2, 1).flags.c_contiguous
    # roughen itself takes the compiled path for this cloud and draws the same normals
    decision = np.zeros(B, dtype=bool)
    decision[rows] = True
    with np.errstate(invalid="ignore"):
        out = reg.roughen(state, [np.random.default_rng(9 + b) for b in range(B)], K, decision)
    np.testing.assert_array_equal(out.x, want.x)
