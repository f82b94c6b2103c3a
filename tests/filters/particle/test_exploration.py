"""n-conditional exploration (Carvalho et al. 1997, §III-C)."""

import numpy as np

from filters import GaussianState, LinearGaussianModel, ParticleState, kalman
from filters.particle import bootstrap, estimates, exploration

from .problems import cv_model, simulate_linear
from .tolerances import EXACT_ATOL, EXACT_RTOL, N_SIGMA


def test_one_auxiliary_particle_is_the_bootstrap_filter():
    model = cv_model()
    B, N = 4, 64
    rng = np.random.default_rng(0)
    st = bootstrap.from_gaussian(np.zeros((B, 2)), np.eye(2), N, rng)
    st = st._replace(log_w=np.log(rng.dirichlet(np.ones(N), B)))
    z = rng.standard_normal((B, 1))
    a, ia = exploration.explore(st, model, z, np.random.default_rng(5), M=1)
    pred = bootstrap.predict(st, model, None, 1.0, np.random.default_rng(5))
    b, ib = bootstrap.update(pred, z, model)
    np.testing.assert_allclose(a.x, b.x, rtol=EXACT_RTOL, atol=EXACT_ATOL)
    np.testing.assert_allclose(a.log_w, b.log_w, rtol=EXACT_RTOL, atol=EXACT_ATOL)
    for f in ("log_likelihood", "nis", "ess", "innovation", "S"):
        np.testing.assert_allclose(getattr(ia, f), getattr(ib, f), rtol=EXACT_RTOL, atol=EXACT_ATOL)


def test_a_separate_observation_model_equals_the_combined_model():
    """``observation=`` (the bootstrap's predict/update split) gives the combined model's result;
    the transition model's h and R are not used then."""
    model = cv_model()
    B, N = 3, 32
    rng = np.random.default_rng(2)
    st = bootstrap.from_gaussian(np.zeros((B, 2)), np.eye(2), N, rng)
    z = rng.standard_normal((B, 1))
    a, ia = exploration.explore(st, model, z, np.random.default_rng(6), M=4)

    class TransitionOnly:
        Q = model.Q

        def f(self, x, u=None, dt=1.0):
            return model.f(x, u, dt)

    b, ib = exploration.explore(st, TransitionOnly(), z, np.random.default_rng(6), M=4, observation=model)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.log_w, b.log_w)
    np.testing.assert_array_equal(ia.log_likelihood, ib.log_likelihood)


def _errors(model, zs, N, M, T, seed, B):
    rng = np.random.default_rng(seed)
    m0, P0 = np.zeros((B, 2)), np.broadcast_to(np.eye(2) * 4, (B, 2, 2))
    kf = GaussianState(m0, P0)
    st = bootstrap.from_gaussian(m0, P0, N, rng)
    err = []
    for k in range(T):
        kf = kalman.predict(kf, model)
        kf, _ = kalman.update(kf, zs[k], model)
        if M == 0:
            st = bootstrap.predict(st, model, None, 1.0, rng)
            st, _ = bootstrap.update(st, zs[k], model, decision=True, rng=rng)
        else:
            st, info = exploration.explore(st, model, zs[k], rng, M)
            st = bootstrap.resample(st, True, rng)
        err.append((estimates.mean(st) - kf.m) / np.sqrt(np.diagonal(kf.P, axis1=1, axis2=2)))
    return np.sqrt(np.mean(np.square(err)))


def test_auxiliary_exploration_beats_bootstrap_with_an_informative_sensor():
    """Precise measurements, diffuse dynamics: the prior proposal wastes particles; M auxiliary
    particles per base particle condition the exploration on the observation (Carvalho et al.
    1997, §III-C)."""
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    model = LinearGaussianModel(F, np.eye(2), np.diag([2.0, 2.0]), np.diag([0.01, 0.01]))
    B, T, N = 32, 10, 100
    _, zs = simulate_linear(model, B, T, np.random.default_rng(1))
    e_boot = _errors(model, zs, N, 0, T, 2, B)
    e_expl = _errors(model, zs, N, 16, T, 2, B)
    print(
        f"\nmean error vs KF (KF std units), N={N}: bootstrap {e_boot:.3f}, n-conditional M=16 {e_expl:.3f}"
    )
    assert e_expl < 0.6 * e_boot


def test_section_of_two_measurements_estimates_the_joint_likelihood():
    """L = 2: the estimate of log p(y1, y2 | past) is centred on the KF's (sum of the two
    log-likelihoods) and the section's posterior mean is close to the KF's.

    Each of 16 measurement records is filtered by 4 replicate filters (B = 64), so the spread of
    the error gives the standard error of its mean.
    """
    model = cv_model(q=0.5, r=0.4)
    B0, rep, N, M = 16, 4, 4000, 8
    B = B0 * rep
    rng = np.random.default_rng(3)
    _, zs = simulate_linear(model, B0, 2, rng)
    zs = np.tile(zs, (1, rep, 1))
    m0, P0 = np.zeros((B, 2)), np.broadcast_to(np.eye(2), (B, 2, 2))
    st = bootstrap.from_gaussian(m0, P0, N, rng)
    st2, info = exploration.explore(st, model, zs, rng, M)
    kf, ll = GaussianState(m0, P0), 0.0
    for k in range(2):
        kf = kalman.predict(kf, model)
        kf, ki = kalman.update(kf, zs[k], model)
        ll = ll + ki.log_likelihood
    err = info.log_likelihood - ll
    print(f"\nlog p(y1, y2) error: mean {err.mean():.4f}, sd {err.std():.4f}")
    assert abs(err.mean()) < N_SIGMA * err.std(ddof=1) / np.sqrt(B)
    assert err.std() < 0.05
    g = estimates.mean_and_covariance(st2)
    sd = np.sqrt(np.diagonal(kf.P, axis1=1, axis2=2))
    assert np.sqrt(np.mean(np.square((g.m - kf.m) / sd))) < 0.06  # RMS, in KF std units
    assert info.healthy.all() and ((info.ess > 1) & (info.ess <= N)).all()


def test_exploration_batch_equals_separate_runs():
    model = cv_model()
    B, N, M = 3, 20, 4
    _, zs = simulate_linear(model, B, 3, np.random.default_rng(4))
    x0 = np.random.default_rng(5).standard_normal((B, N, 2))

    def run(idx, gens):
        st = ParticleState(x0[idx], np.full((len(idx), N), -np.log(N)))
        return exploration.explore(st, model, zs[:, idx], gens, M)[0]

    together = run(np.arange(B), [np.random.default_rng(9 + b) for b in range(B)])
    for b in range(B):
        alone = run(np.array([b]), np.random.default_rng(9 + b))
        np.testing.assert_allclose(together.x[b], alone.x[0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(together.log_w[b], alone.log_w[0], rtol=1e-12, atol=1e-12)
