"""Bootstrap PF: reference loop, batching/determinism, masks, diagnostics, health, model hooks."""

import numpy as np
import pytest

from filters import GaussianState, LinearGaussianModel, ParticleState, kalman
from filters.core.normal import standard_normal_block
from filters.particle import bootstrap, estimates

from .problems import cv_model, simulate_linear, two_sensor_model
from .tolerances import EXACT_ATOL, EXACT_RTOL, MASK_ATOL, N_SIGMA

LOG_2PI = np.log(2 * np.pi)


# ---------------------------------------------------------------------------------------------
# reference: one filter, one particle at a time
# ---------------------------------------------------------------------------------------------
def _ref_step(x, lw, z, mask, model, g, do_resample):
    """SIR step for one filter with plain loops (Touil & Ghadi 2012, eq. 15-17, systematic points)."""
    F, H, Q, R = model.transition_matrix, model.observation_matrix, model.Q, model.R
    N, n = x.shape
    e = standard_normal_block(g, (n, N))[0].T  # the filters' sampler (tested on its own), component-major
    x = np.array([F @ x[i] + np.linalg.cholesky(Q) @ e[i] for i in range(N)])
    used = np.flatnonzero(mask)
    Hu, Ru, zu = H[used], R[np.ix_(used, used)], z[used]
    ll = np.empty(N)
    for i in range(N):
        v = zu - Hu @ x[i]
        ll[i] = -0.5 * (v @ np.linalg.solve(Ru, v) + np.log(np.linalg.det(Ru)) + used.size * LOG_2PI)
    lw = lw + ll
    lw = lw - (lw.max() + np.log(np.exp(lw - lw.max()).sum()))
    if do_resample:
        U = 1.0 - g.random((1, 1))[0, 0]
        c = np.cumsum(np.exp(lw))
        c /= c[-1]
        anc = [next(i for i in range(N) if (j + U) / N <= c[i] or i == N - 1) for j in range(N)]
        x, lw = x[anc], np.full(N, -np.log(N))
    return x, lw


def _scenario(B, T, seed, m):
    rng = np.random.default_rng(seed)
    masks = rng.random((T, B, m)) < 0.8
    decisions = rng.random((T, B)) < 0.5
    return masks, decisions


@pytest.mark.parametrize("policy", ["never", "always", "mixed"])
def test_sir_matches_reference_loop(policy):
    """Batched predict/update/resample (per-filter generators) == per-filter Python loop, for
    never resampling, always resampling and per-filter per-step decisions."""
    model = two_sensor_model()
    B, N, T = 4, 25, 6
    _, zs = simulate_linear(model, B, T, np.random.default_rng(0))
    masks, decisions = _scenario(B, T, 1, 3)
    if policy != "mixed":
        decisions[:] = policy == "always"
    x0 = np.random.default_rng(2).standard_normal((B, N, 2))
    gens = [np.random.default_rng(10 + b) for b in range(B)]
    state = ParticleState(x0.copy(), np.full((B, N), -np.log(N)))
    for k in range(T):
        state = bootstrap.predict(state, model, None, 1.0, gens)
        state, info = bootstrap.update(state, zs[k], model, masks[k], decision=decisions[k], rng=gens)
        np.testing.assert_array_equal(info.resampled, decisions[k])
    for b in range(B):
        g = np.random.default_rng(10 + b)
        x, lw = x0[b].copy(), np.full(N, -np.log(N))
        for k in range(T):
            x, lw = _ref_step(x, lw, zs[k, b], masks[k, b], model, g, decisions[k, b])
        np.testing.assert_allclose(state.x[b], x, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        np.testing.assert_allclose(state.log_w[b], lw, rtol=EXACT_RTOL, atol=EXACT_ATOL)


@pytest.mark.parametrize("method", ["systematic", "stratified", "multinomial", "residual"])
def test_batch_equals_separate_runs_with_corresponding_generators(method):
    model = two_sensor_model()
    B, N, T = 5, 40, 8
    _, zs = simulate_linear(model, B, T, np.random.default_rng(3))
    masks, decisions = _scenario(B, T, 4, 3)
    gamma = np.array([1.0, 0.9, 0.5, 1.0, 0.75])
    x0 = np.random.default_rng(5).standard_normal((B, N, 2))

    def run(idx, gens):
        st = ParticleState(x0[idx].copy(), np.full((len(idx), N), -np.log(N)))
        infos = []
        for k in range(T):
            st = bootstrap.predict(st, model, None, 1.0, gens)
            st, info = bootstrap.update(
                st,
                zs[k][idx],
                model,
                masks[k][idx],
                forgetting=gamma[idx],
                decision=decisions[k][idx],
                rng=gens,
                method=method,
            )
            infos.append(info)
        return st, infos

    together, infos = run(np.arange(B), [np.random.default_rng(50 + b) for b in range(B)])
    for b in range(B):
        alone, infos_b = run(np.array([b]), np.random.default_rng(50 + b))  # plain Generator
        np.testing.assert_allclose(together.x[b], alone.x[0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(together.log_w[b], alone.log_w[0], rtol=1e-12, atol=1e-12)
        for i, ib in zip(infos, infos_b, strict=True):
            np.testing.assert_allclose(i.log_likelihood[b], ib.log_likelihood[0], rtol=1e-12)
            np.testing.assert_allclose(i.nis[b], ib.nis[0], rtol=1e-10, atol=1e-12)
            assert i.resampled[b] == ib.resampled[0]


def test_resample_decision_false_is_no_resampling_and_true_is_resampling():
    rng = np.random.default_rng(0)
    B, N = 6, 50
    state = ParticleState(rng.standard_normal((B, N, 3)), np.log(rng.dirichlet(np.ones(N), B)))
    same = bootstrap.resample(state, np.zeros(B, bool), rng)
    assert same.x is state.x and same.log_w is state.log_w
    d = np.array([True, False, True, False, True, True])
    new = bootstrap.resample(state, d, rng)
    np.testing.assert_array_equal(new.x[~d], state.x[~d])
    np.testing.assert_array_equal(new.log_w[~d], state.log_w[~d])
    np.testing.assert_allclose(new.log_w[d], -np.log(N))
    for b in np.flatnonzero(d):
        # every new particle is a copy of an old one, and the cloud changed
        rows = {tuple(r) for r in state.x[b]}
        assert all(tuple(r) in rows for r in new.x[b])
        assert not np.array_equal(new.x[b], state.x[b])
    # update(decision=...) reports what it did
    model = LinearGaussianModel(np.eye(3), np.eye(3)[:2], np.eye(3), np.eye(2))
    z = rng.standard_normal((B, 2))
    plain, info0 = bootstrap.update(state, z, model)
    assert not info0.resampled.any()
    post, info = bootstrap.update(state, z, model, decision=d, rng=rng)
    np.testing.assert_array_equal(info.resampled, d)
    np.testing.assert_array_equal(post.log_w[~d], plain.log_w[~d])
    np.testing.assert_allclose(info.ess, info0.ess)


@pytest.mark.parametrize("full_R", [True, False])
def test_masked_row_contributes_exactly_nothing(full_R):
    model = two_sensor_model()
    if not full_R:
        model = model._replace(R=np.diag(np.diag(model.R)))
    rng = np.random.default_rng(1)
    B, N = 4, 30
    state = ParticleState(rng.standard_normal((B, N, 2)), np.log(rng.dirichlet(np.ones(N), B)))
    z = rng.standard_normal((B, 3))
    mask = np.ones((B, 3), bool)
    mask[:, 1] = False
    z[:, 1] = np.nan
    post, info = bootstrap.update(state, z, model, mask)
    keep = [0, 2]
    sub = model._replace(observation_matrix=model.observation_matrix[keep], R=model.R[np.ix_(keep, keep)])
    post2, info2 = bootstrap.update(state, z[:, keep], sub)
    np.testing.assert_allclose(post.log_w, post2.log_w, atol=MASK_ATOL, rtol=0)
    np.testing.assert_allclose(info.log_likelihood, info2.log_likelihood, atol=MASK_ATOL, rtol=0)
    np.testing.assert_allclose(info.nis, info2.nis, atol=MASK_ATOL, rtol=1e-12)
    np.testing.assert_allclose(info.innovation[:, keep], info2.innovation, atol=MASK_ATOL, rtol=0)
    assert (info.innovation[:, 1] == 0).all() and (info.S[:, 1, 1] == 1).all()
    assert (info.n_meas == 2).all() and info.healthy.all()


def test_diagnostics_match_the_kalman_filter_for_a_large_cloud():
    """One update from an exact Gaussian cloud: innovation, S, log p(z|past) ~ the KF's."""
    model = cv_model()
    B, N = 20, 200_000
    rng = np.random.default_rng(8)
    m0 = rng.standard_normal((B, 2))
    P0 = np.array([[2.0, 0.5], [0.5, 1.0]])
    state = bootstrap.from_gaussian(m0, P0, N, rng)
    z = rng.standard_normal((B, 1)) * 2
    post, info = bootstrap.update(state, z, model)
    kf, kinfo = kalman.update(GaussianState(m0, np.broadcast_to(P0, (B, 2, 2))), z, model)
    S = P0[0, 0] + model.R[0, 0]
    se_mean = np.sqrt(P0[0, 0] / N)
    assert np.abs(info.innovation - kinfo.innovation).max() < N_SIGMA * se_mean
    np.testing.assert_allclose(info.S, kinfo.S, rtol=N_SIGMA * np.sqrt(2 / N) * P0[0, 0] / S)
    # log p(z|past) estimate: delta-method standard error sqrt((E[l^2] / p^2 - 1) / N) of the
    # mean of l_i = N(z; H x_i, R) under x_i ~ N(m0, P0) (scalar z: N(z; H x, R)^2 =
    # N(z; H x, R / 2) / (2 sqrt(pi R)), so E[l^2] = N(z; H m0, R / 2 + H P0 H^T) / (2 sqrt(pi R)))
    mu, R = (m0 @ model.observation_matrix.T)[:, 0], model.R[0, 0]

    def pdf(x, var):
        return np.exp(-0.5 * (x - mu) ** 2 / var) / np.sqrt(2 * np.pi * var)

    p, El2 = pdf(z[:, 0], S), pdf(z[:, 0], R / 2 + P0[0, 0]) / (2 * np.sqrt(np.pi * R))
    se_loglik = np.sqrt((El2 / p**2 - 1.0) / N)
    assert (np.abs(info.log_likelihood - kinfo.log_likelihood) < N_SIGMA * se_loglik).all()
    pm = estimates.mean_and_covariance(post)
    # importance-sampling standard errors with the effective sample size (Kong 1992):
    # mean sqrt(P_ii / ESS), covariance sqrt((P_ii P_jj + P_ij^2) / ESS)
    ess = info.ess[:, None]
    dP = np.einsum("bii->bi", kf.P)
    assert (np.abs(pm.m - kf.m) < N_SIGMA * np.sqrt(dP / ess)).all()
    se_P = np.sqrt((dP[:, :, None] * dP[:, None, :] + kf.P**2) / ess[:, :, None])
    assert (np.abs(pm.P - kf.P) < N_SIGMA * se_P).all()
    assert ((info.ess > 1) & (info.ess <= N)).all() and info.healthy.all()


def test_health_flag_instead_of_nan():
    model = cv_model()
    rng = np.random.default_rng(0)
    B, N = 3, 10
    x = rng.standard_normal((B, N, 2))
    x[1, 4, 0] = np.nan
    state = ParticleState(x, np.full((B, N), -np.log(N)))
    post, info = bootstrap.update(state, rng.standard_normal((B, 1)), model)
    np.testing.assert_array_equal(info.healthy, [True, False, True])
    assert not np.isnan(post.log_w).any()
    assert post.log_w[1, 4] == -np.inf
    assert estimates.healthy(post).tolist() == [True, False, True]

    class Impossible:
        R = np.eye(1)

        def h(self, x):
            return x[..., :1]

        def log_likelihood(self, z, x, mask):
            return np.where(np.arange(x.shape[0])[:, None] == 0, -np.inf, 0.0) + np.zeros(x.shape[:2])

    state = ParticleState(rng.standard_normal((B, N, 2)), np.log(rng.dirichlet(np.ones(N), B)))
    post, info = bootstrap.update(state, np.zeros((B, 1)), Impossible())
    assert info.healthy.tolist() == [False, True, True]
    assert info.log_likelihood[0] == -np.inf
    np.testing.assert_allclose(post.log_w[0], state.log_w[0])  # prior weights kept, no NaN


def test_model_hooks_sample_noise_and_log_likelihood():
    class Heavy:
        """Random walk with Laplace process noise and Student-t (nu = 3) measurement noise."""

        Q = np.eye(1)
        R = np.eye(1)

        def f(self, x, u, dt):
            return x

        def sample_noise(self, g, shape):
            return g.laplace(0.0, 1.0, (*shape, 1))

        def h(self, x):
            return x

        def log_likelihood(self, z, x, mask):
            r = z[:, None, :] - x
            return (-2.0 * np.log1p(r**2 / 3.0) * mask[:, None, :]).sum(axis=2)

    model = Heavy()
    B, N = 4, 20_000
    rng = np.random.default_rng(3)
    state = ParticleState(np.zeros((B, N, 1)), np.full((B, N), -np.log(N)))
    pred = bootstrap.predict(state, model, None, 1.0, rng)
    var = pred.x.var(axis=1)[:, 0]  # Laplace(0, 1): variance 2
    assert np.abs(var - 2.0).max() < N_SIGMA * np.sqrt((24 - 4) / N)  # fourth moment 24
    z = np.array([[0.5], [1.0], [-3.0], [2.0]])
    post, _ = bootstrap.update(pred, z, model)
    lw = -2.0 * np.log1p((z[:, None, 0] - pred.x[..., 0]) ** 2 / 3.0)
    lw -= estimates.logsumexp(lw)[:, None]
    np.testing.assert_allclose(post.log_w, lw, rtol=1e-12, atol=1e-12)
    # an R override forces the Gaussian likelihood
    post_g, _ = bootstrap.update(pred, z, model, R=np.eye(1))
    lg = -0.5 * (z[:, None, 0] - pred.x[..., 0]) ** 2
    np.testing.assert_allclose(post_g.log_w, lg - estimates.logsumexp(lg)[:, None], atol=1e-10)


def test_predict_q_override_and_batched_q():
    model = cv_model()
    rng = np.random.default_rng(0)
    B, N = 3, 40_000
    state = ParticleState(np.zeros((B, N, 2)), np.full((B, N), -np.log(N)))
    det = bootstrap.predict(state, model, None, 1.0, rng, Q=np.zeros((2, 2)))
    np.testing.assert_array_equal(det.x, 0.0)
    Qb = np.stack([model.Q * s for s in (0.5, 1.0, 4.0)])
    pred = bootstrap.predict(state, model, None, 1.0, rng, Q=Qb)
    cov = estimates.covariance(pred)
    for b in range(B):
        np.testing.assert_allclose(cov[b], Qb[b], atol=N_SIGMA * np.sqrt(2 / N) * Qb[b].max())


def test_from_gaussian_moments_and_weights():
    rng = np.random.default_rng(1)
    B, N = 3, 100_000
    m = rng.standard_normal((B, 2))
    P = np.array([[1.0, 0.3], [0.3, 0.5]])
    st = bootstrap.from_gaussian(m, P, N, rng)
    g = estimates.mean_and_covariance(st)
    np.testing.assert_allclose(g.m, m, atol=N_SIGMA * np.sqrt(1.0 / N))
    np.testing.assert_allclose(g.P, np.broadcast_to(P, (B, 2, 2)), atol=N_SIGMA * np.sqrt(2.0 / N))
    np.testing.assert_allclose(st.log_w, -np.log(N))
    np.testing.assert_allclose(estimates.ess(st.log_w), N)


def test_structure_of_arrays_layout_gives_the_same_results_and_is_kept():
    """Particles stored as a (B, n, N) buffer seen as (B, N, n): same numbers, layout preserved."""
    model = two_sensor_model()
    rng = np.random.default_rng(2)
    B, N = 4, 50
    aos = ParticleState(rng.standard_normal((B, N, 2)), np.log(rng.dirichlet(np.ones(N), B)))
    soa = aos._replace(x=np.ascontiguousarray(aos.x.transpose(0, 2, 1)).transpose(0, 2, 1))
    assert not soa.x.flags.c_contiguous
    z = rng.standard_normal((B, 3))
    d = np.array([True, False, True, True])
    a, ia = bootstrap.update(aos, z, model, decision=d, rng=np.random.default_rng(0))
    s, is_ = bootstrap.update(soa, z, model, decision=d, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(a.x, s.x)
    np.testing.assert_allclose(a.log_w, s.log_w, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ia.nis, is_.nis, rtol=1e-10)
    assert s.x.transpose(0, 2, 1).flags.c_contiguous  # still structure of arrays
    full = bootstrap.resample(soa, True, np.random.default_rng(1))
    np.testing.assert_array_equal(full.x, bootstrap.resample(aos, True, np.random.default_rng(1)).x)
    assert full.x.transpose(0, 2, 1).flags.c_contiguous


def test_random_steps_draw_the_same_numbers_in_either_layout():
    """from_gaussian, predict (full, diagonal and rank-deficient Q) and roughening draw their
    normals component-major, so an "soa" cloud equals the "aos" one draw for draw and stays
    in its layout."""
    from filters.particle import regularization

    base = cv_model()
    B, N, n = 3, 40, 2
    m0 = np.random.default_rng(3).standard_normal((B, n))
    for Q in (np.array([[0.5, 0.1], [0.1, 0.3]]), np.diag([0.5, 0.3]), np.diag([0.0, 0.3])):
        model = base._replace(Q=Q)
        clouds = {}
        for layout in ("aos", "soa"):
            gens = [np.random.default_rng(20 + b) for b in range(B)]
            st = bootstrap.from_gaussian(m0, np.eye(n), N, gens, layout=layout)
            st = bootstrap.predict(st, model, None, 1.0, gens)
            st = regularization.roughen(st, gens, K=0.2, decision=np.array([True, False, True]))
            clouds[layout] = st.x
        assert clouds["aos"].flags.c_contiguous and bootstrap.is_component_major(clouds["soa"])
        np.testing.assert_allclose(clouds["soa"], clouds["aos"], rtol=1e-13, atol=1e-13)
    with pytest.raises(ValueError, match="layout"):
        bootstrap.from_gaussian(m0, np.eye(n), N, np.random.default_rng(0), layout="columns")


def test_float32_particles_stay_float32_and_track_the_float64_filter():
    """A float32 cloud (same draws, rounded) keeps its dtype through predict, update and
    resampling, with float64 weights and diagnostics, and its estimates match the float64 run
    to float32 precision."""
    model = cv_model()
    B, N, T = 3, 2000, 5
    _, zs = simulate_linear(model, B, T, np.random.default_rng(4))
    runs = {}
    for dt in (np.float64, np.float32):
        g = [np.random.default_rng(30 + b) for b in range(B)]
        st = bootstrap.from_gaussian(np.zeros((B, 2)), np.eye(2), N, g, layout="soa")
        st = st._replace(x=st.x.astype(dt))
        for k in range(T):
            st = bootstrap.predict(st, model, None, 1.0, g)
            st, info = bootstrap.update(st, zs[k], model, decision=k % 2 == 1, rng=g)
            assert st.x.dtype == dt and st.log_w.dtype == np.float64
            assert info.S.dtype == np.float64 and info.nis.dtype == np.float64
        runs[dt] = (estimates.mean(st), info)
    (m64, i64), (m32, i32) = runs[np.float64], runs[np.float32]
    np.testing.assert_allclose(m32, m64, rtol=1e-4, atol=1e-4)
    # NIS of a resampled cloud moves by O(1/N) when a float32 weight's rounding moves one
    # systematic ancestor (it does for one filter on the compiled path: 1.0e-3 with N = 2000)
    np.testing.assert_allclose(i32.nis, i64.nis, rtol=3e-3)
    np.testing.assert_allclose(i32.log_likelihood, i64.log_likelihood, rtol=1e-4, atol=1e-4)


def test_full_outage_leaves_weights_unchanged():
    """Every row masked (GNSS outage): weights unchanged, log p(z | past) = 0, healthy."""
    model = two_sensor_model()
    rng = np.random.default_rng(6)
    B, N = 3, 20
    state = ParticleState(rng.standard_normal((B, N, 2)), np.log(rng.dirichlet(np.ones(N), B)))
    mask = np.zeros((B, 3), bool)
    mask[0] = True
    post, info = bootstrap.update(state, np.where(mask, 1.0, np.nan), model, mask)
    np.testing.assert_allclose(post.log_w[1:], state.log_w[1:], atol=MASK_ATOL)
    np.testing.assert_allclose(info.log_likelihood[1:], 0.0, atol=MASK_ATOL)
    np.testing.assert_array_equal(info.nis[1:], 0.0)
    assert info.n_meas.tolist() == [3, 0, 0] and info.healthy.all()


def test_diagonal_q_with_noise_free_components_draws_the_driven_ones_only():
    """Shared diagonal Q with zero variances: exactly zero noise there, N(0, Q_ii) elsewhere,
    and per-filter generators give each filter the same draws as a batch of one."""
    n, B, N = 5, 3, 20000
    q = np.array([0.0, 4.0, 0.0, 0.25, 0.0])
    model = LinearGaussianModel(np.eye(n), np.eye(1, n), np.diag(q), np.eye(1))
    gens = [np.random.default_rng(10 + b) for b in range(B)]
    w = bootstrap.process_noise(model, B, N, n, gens)
    assert w.shape == (B, N, n)
    assert (w[:, :, q == 0] == 0).all()
    np.testing.assert_allclose(w[:, :, q > 0].var(axis=1), np.broadcast_to(q[q > 0], (B, 2)), rtol=0.05)
    single = bootstrap.process_noise(model, 1, N, n, [np.random.default_rng(11)])
    np.testing.assert_array_equal(single[0], w[1])


@pytest.mark.parametrize("layout", ["soa", "aos"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_predict_with_noise_free_components_adds_exactly_the_process_noise(layout, dtype):
    """predict adds only the driven components' noise: the same particles as f(x) + w bit for bit
    (x + 0 is x), the input untouched, for either layout, precision and an f that aliases x."""
    n, B, N = 5, 3, 400
    q = np.array([0.0, 4.0, 0.0, 0.25, 0.0])
    F = np.eye(n)
    F[0, 1] = 0.5
    for f_model in (LinearGaussianModel(F, np.eye(1, n), np.diag(q), np.eye(1)), _IdentityTransition(q)):
        state = bootstrap.from_gaussian(
            np.zeros((B, n)), np.eye(n), N, np.random.default_rng(1), layout=layout
        )
        state = state._replace(x=state.x.astype(dtype))
        before = state.x.copy()
        pred = bootstrap.predict(state, f_model, None, 1.0, [np.random.default_rng(20 + b) for b in range(B)])
        w = bootstrap.process_noise(
            f_model, B, N, n, [np.random.default_rng(20 + b) for b in range(B)], dtype=dtype
        )
        want = f_model.f(state.x, None, 1.0) + w
        np.testing.assert_array_equal(pred.x, want)
        assert pred.x.dtype == dtype
        np.testing.assert_array_equal(state.x, before)


class _IdentityTransition:
    """f(x) = x (returns its input: predict must not add the noise in place)."""

    def __init__(self, q: np.ndarray) -> None:
        self.Q = np.diag(q)

    def f(self, x: np.ndarray, u: object, dt: float) -> np.ndarray:
        return x


@pytest.mark.parametrize(
    ("Q", "match"), [(np.diag([-1.0, 1.0]), "variance"), (np.array([[1.0, 2.0], [2.0, 1.0]]), "eigenvalue")]
)
def test_an_indefinite_process_noise_or_prior_raises(Q, match):
    from filters.core.models import LinearGaussianModel

    model = LinearGaussianModel(np.eye(2), np.eye(2), Q, np.eye(2))
    state = bootstrap.from_gaussian(np.zeros((2, 2)), np.eye(2), 50, np.random.default_rng(0))
    with pytest.raises(ValueError, match=match):
        bootstrap.predict(state, model, rng=np.random.default_rng(1))
    with pytest.raises(ValueError, match="P must be positive semi-definite"):
        bootstrap.from_gaussian(
            np.zeros((2, 2)), np.array([[1.0, 2.0], [2.0, 1.0]]), 50, np.random.default_rng(0)
        )
