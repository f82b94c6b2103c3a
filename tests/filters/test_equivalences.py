"""Cross-filter identities: linear-Gaussian problems, information forms, quadrature rules."""

import numpy as np
import pytest

from filters import FILTERS, GaussianState, Unscented, information, kalman, sigma_point
from filters.core.quadrature import Cubature, GaussHermite

from .problems import RandomNonlinear, random_linear
from .tolerances import ATOL, RTOL

T = 30


def run(flt, model, m0, P0, zs):
    state = GaussianState(m0, P0)
    out = []
    for z in zs:
        state, info = flt.update(flt.predict(state, model), z, model)
        out.append((state, info))
    return out


# "kf" and "ekf" are the reference itself (kalman.predict / update); they are checked against
# independent implementations (filterpy in test_filterpy.py, pykalman in test_known_answer.py).
@pytest.mark.parametrize("name", sorted(set(FILTERS) - {"kf", "ekf"}))
@pytest.mark.parametrize("n,m,seed", [(3, 2, 0), (5, 4, 1)])
def test_every_gaussian_filter_equals_kf_on_linear_models(name, n, m, seed):
    model = random_linear(n, m, seed)
    rng = np.random.default_rng(seed)
    B = 4
    m0 = rng.standard_normal((B, n))
    P0 = np.broadcast_to(np.eye(n) * 2.0, (B, n, n)).copy()
    zs = rng.standard_normal((T, B, m))
    ref = run(FILTERS["kf"], model, m0, P0, zs)
    got = run(FILTERS[name], model, m0, P0, zs)
    for (s_ref, i_ref), (s, i) in zip(ref, got, strict=True):
        np.testing.assert_allclose(s.m, s_ref.m, rtol=RTOL, atol=ATOL)
        np.testing.assert_allclose(s.P, s_ref.P, rtol=RTOL, atol=ATOL)
        np.testing.assert_allclose(i.nis, i_ref.nis, rtol=RTOL, atol=ATOL)
        np.testing.assert_allclose(i.log_likelihood, i_ref.log_likelihood, rtol=RTOL, atol=ATOL)


@pytest.mark.parametrize("seed", [0, 1])
def test_kf_log_likelihood_is_gaussian_density_of_innovation(seed):
    from scipy.stats import multivariate_normal

    model = random_linear(4, 3, seed)
    rng = np.random.default_rng(seed)
    state = kalman.predict(GaussianState(rng.standard_normal((2, 4)), np.eye(4)[None].repeat(2, 0)), model)
    z = rng.standard_normal((2, 3))
    _, info = kalman.update(state, z, model)
    for b in range(2):
        S = model.observation_matrix @ state.P[b] @ model.observation_matrix.T + model.R
        v = z[b] - model.observation_matrix @ state.m[b]
        assert info.log_likelihood[b] == pytest.approx(
            multivariate_normal(np.zeros(3), S).logpdf(v), rel=1e-12
        )
        assert info.nis[b] == pytest.approx(v @ np.linalg.solve(S, v), rel=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_eif_equals_ekf_on_nonlinear_problem(seed):
    p = RandomNonlinear.draw(4, 3, seed)
    m0, P0, zs = p.simulate(3, T, seed)
    g = GaussianState(m0, P0)
    i = information.to_information(g)
    for z in zs:
        g, gi = kalman.update(kalman.predict(g, p), z, p)
        i, ii = information.eif_update(information.eif_predict(i, p), z, p)
        back = information.to_gaussian(i)
        np.testing.assert_allclose(back.m, g.m, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(back.P, g.P, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(ii.nis, gi.nis, rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("seed", [0, 1])
def test_cif_equals_ckf_on_linear_problem(seed):
    model = random_linear(5, 3, seed)
    rng = np.random.default_rng(seed)
    g = GaussianState(rng.standard_normal((3, 5)), np.broadcast_to(np.eye(5), (3, 5, 5)).copy())
    i = information.to_information(g)
    for z in rng.standard_normal((T, 3, 3)):
        g = sigma_point.update(sigma_point.predict(g, model), z, model)[0]
        i = information.cif_update(information.cif_predict(i, model), z, model)[0]
        back = information.to_gaussian(i)
        np.testing.assert_allclose(back.m, g.m, rtol=RTOL, atol=ATOL)
        np.testing.assert_allclose(back.P, g.P, rtol=RTOL, atol=ATOL)


def test_cubature_equals_unscented_alpha1_beta0_kappa0():
    for n in (1, 3, 9):
        c = Cubature().sigma_points(n)
        u = Unscented(1.0, 0.0, 0.0).sigma_points(n)
        # The unscented rule has an extra centre point of weight 0.
        assert u.wm[0] == 0.0 and u.wc[0] == 0.0
        np.testing.assert_allclose(u.xi[1:], c.xi, rtol=0, atol=1e-15)
        np.testing.assert_allclose(u.wm[1:], c.wm, rtol=1e-15)
        np.testing.assert_allclose(u.wc[1:], c.wc, rtol=1e-15)
    p = RandomNonlinear.draw(4, 3, 3)
    m0, P0, zs = p.simulate(2, T, 3)
    a = b = GaussianState(m0, P0)
    for z in zs:
        a = sigma_point.update(sigma_point.predict(a, p, rule=Cubature()), z, p, rule=Cubature())[0]
        r = Unscented(1.0, 0.0, 0.0)
        b = sigma_point.update(sigma_point.predict(b, p, rule=r), z, p, rule=r)[0]
    np.testing.assert_allclose(a.m, b.m, rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(a.P, b.P, rtol=RTOL, atol=ATOL)


@pytest.mark.parametrize("p", [3, 5])
def test_gauss_hermite_integrates_polynomials_exactly(p):
    """A p-point rule is exact for degree <= 2p - 1 per coordinate (Benzerrouk 2014, eq. 47-50)."""
    from math import prod

    n = 2
    sp = GaussHermite(p).sigma_points(n)
    assert sp.xi.shape == (p**n, n)
    np.testing.assert_allclose(sp.wm.sum(), 1.0, rtol=1e-14)

    def normal_moment(k):  # E[x^k] for N(0, 1)
        return 0.0 if k % 2 else float(prod(range(1, k, 2)))

    for k1 in range(2 * p):
        for k2 in range(2 * p - k1):
            est = sp.wm @ (sp.xi[:, 0] ** k1 * sp.xi[:, 1] ** k2)
            assert est == pytest.approx(
                normal_moment(k1) * normal_moment(k2), abs=1e-9 * (1 + normal_moment(2 * p))
            )


def test_ghkf_more_accurate_than_ckf_on_strong_nonlinearity():
    """A cubic transform: GH(5) captures the 4th-order moment terms the cubature rule misses."""
    x = GaussianState(np.array([[1.0, -0.5]]), np.array([[[0.5, 0.1], [0.1, 0.3]]]))

    class Cubic:
        Q = np.zeros((2, 2))

        def f(self, x, u=None, dt=1.0):
            return x**3

    rng = np.random.default_rng(0)
    samples = rng.multivariate_normal(x.m[0], x.P[0], size=2_000_000) ** 3
    true_cov = np.cov(samples.T)
    gh = sigma_point.predict(x, Cubic(), rule=GaussHermite(5))
    ck = sigma_point.predict(x, Cubic(), rule=Cubature())
    assert np.abs(gh.P[0] - true_cov).max() < 0.05 * np.abs(true_cov).max()
    assert np.abs(gh.P[0] - true_cov).max() < np.abs(ck.P[0] - true_cov).max()


class _Heading:
    """A heading measured directly, ``z = x_0`` on the circle: innovations must be wrapped."""

    R = np.eye(1) * 0.01

    def h(self, x):
        return x[..., :1]

    def H(self, x):
        return np.broadcast_to(np.eye(1, 2), (*x.shape[:-1], 1, 2))

    def residual(self, z, z_hat):
        return np.angle(np.exp(1j * (z - z_hat)))


@pytest.mark.parametrize("name", [*sorted(set(FILTERS) - {"kf"}), "eif", "cif"])
def test_every_gaussian_filter_takes_the_models_residual(name):
    """A heading of -3.1 rad seen from a prior at +3.1 rad is 0.083 rad away, not 6.2."""
    B = 3
    prior = GaussianState(
        np.tile([3.1, 0.0], (B, 1)), np.broadcast_to(np.diag([0.04, 1.0]), (B, 2, 2)).copy()
    )
    z = np.full((B, 1), -3.1)
    model = _Heading()
    if name in ("eif", "cif"):
        upd = information.eif_update if name == "eif" else information.cif_update
        post = information.to_gaussian(upd(information.to_information(prior), z, model)[0])
    else:
        post = FILTERS[name].update(prior, z, model)[0]
    wrapped = 2 * np.pi - 6.2  # the innovation the residual gives
    np.testing.assert_allclose(post.m[:, 0], 3.1 + 0.04 / 0.05 * wrapped, rtol=1e-6, atol=1e-9)
