"""Linear-algebra building blocks and the iterated EKF's Gauss-Newton optimum."""

import numpy as np
import pytest
from scipy.optimize import minimize

from filters import GaussianState, kalman
from filters.core import linalg

from .problems import RandomNonlinear


def test_cholesky_fast_path_and_jitter_fallback():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((5, 4, 4))
    P = A @ A.transpose(0, 2, 1) + np.eye(4)
    L, ok = linalg.cholesky(P)
    np.testing.assert_allclose(L @ L.transpose(0, 2, 1), P, rtol=1e-12)
    assert ok.all()
    bad = P.copy()
    bad[2] = np.diag([1.0, 1.0, 1.0, -1e-14])  # barely indefinite
    bad[3] = np.nan
    L, ok = linalg.cholesky(bad)
    assert ok.tolist() == [True, True, False, False, True]
    np.testing.assert_allclose(L[0] @ L[0].T, P[0], rtol=1e-12)
    assert np.isfinite(L).all()


def test_spd_inverse_flags_indefinite_members():
    S = np.stack([np.eye(2) * 2.0, np.diag([1.0, -1.0])])
    S_inv, logdet, ok = linalg.spd_inverse(S)
    assert ok.tolist() == [True, False]
    np.testing.assert_allclose(S_inv[0], np.eye(2) / 2.0)
    assert logdet[0] == pytest.approx(2 * np.log(2.0))
    assert np.isfinite(S_inv).all() and np.isfinite(logdet).all()


def test_sandwich_and_cross_match_plain_products():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((6, 5, 5))
    P = A @ A.transpose(0, 2, 1)
    F = rng.standard_normal((3, 5))
    Fb = rng.standard_normal((6, 5, 5))
    np.testing.assert_allclose(linalg.sandwich(F, P), F @ P @ F.T, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(linalg.sandwich(Fb, P), Fb @ P @ Fb.transpose(0, 2, 1), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(linalg.cross(P, F), P @ F.T, rtol=1e-12, atol=1e-12)


def test_joseph_update_matches_factored_form():
    """The expanded Joseph form of the conditioning equals (I-KH)P(I-KH)^T + KRK^T."""
    rng = np.random.default_rng(2)
    A = rng.standard_normal((3, 4, 4))
    P = A @ A.transpose(0, 2, 1) + np.eye(4)
    H = rng.standard_normal((2, 4))
    R = np.eye(2) * 0.5
    from filters import LinearGaussianModel

    model = LinearGaussianModel(np.eye(4), H, np.eye(4), R)
    post, _ = kalman.update(GaussianState(np.zeros((3, 4)), P), np.ones((3, 2)), model)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    ref = linalg.joseph_update(P, K, H, R)
    np.testing.assert_allclose(post.P, ref, rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_iterated_ekf_reaches_the_map_estimate(seed):
    """Belles et al. 2022, eq. 14: the IEKF mean minimizes |x - m|^2_P^-1 + |z - h(x)|^2_R^-1."""
    p = RandomNonlinear.draw(3, 3, seed)
    p.c = 0.6  # strong measurement nonlinearity
    m0, P0, zs = p.simulate(1, 1, seed)
    prior = GaussianState(m0, P0 * 2.0)
    post, _ = kalman.iterated_update(prior, zs[0], p, max_iter=50, tol=1e-13)
    Pi, Ri = np.linalg.inv(prior.P[0]), np.linalg.inv(p.R)

    def cost(x):
        dx, dz = x - prior.m[0], zs[0, 0] - p.h(x)
        return dx @ Pi @ dx + dz @ Ri @ dz

    best = minimize(cost, post.m[0], method="BFGS", options={"gtol": 1e-12})
    assert cost(post.m[0]) <= best.fun + 1e-9
    ekf, _ = kalman.update(prior, zs[0], p)
    assert cost(post.m[0]) <= cost(ekf.m[0])
    one, _ = kalman.iterated_update(prior, zs[0], p, max_iter=1)
    np.testing.assert_allclose(one.m, ekf.m, rtol=1e-14)
