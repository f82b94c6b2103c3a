"""Equality with filterpy 2.0.0 on random nonlinear problems over 120 steps."""

import warnings

import numpy as np
import pytest

from filters import GaussianState, Unscented, kalman, sigma_point
from filters.core.quadrature import Cubature

from .problems import RandomNonlinear, random_linear
from .tolerances import ATOL, RTOL

warnings.filterwarnings("ignore", category=DeprecationWarning)
filterpy_kalman = pytest.importorskip("filterpy.kalman")

T = 120


def assert_close(a, b):
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=ATOL)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kf_matches_filterpy(seed):
    model = random_linear(4, 3, seed)
    rng = np.random.default_rng(seed)
    zs = rng.standard_normal((T, 1, 3)) * 3
    kf = filterpy_kalman.KalmanFilter(dim_x=4, dim_z=3)
    kf.F, kf.H, kf.Q, kf.R = model.transition_matrix, model.observation_matrix, model.Q, model.R
    kf.x, kf.P = np.ones(4), np.eye(4) * 2.0
    state = GaussianState(np.ones((1, 4)), np.eye(4)[None] * 2.0)
    for z in zs:
        kf.predict()
        kf.update(z[0])
        state = kalman.update(kalman.predict(state, model), z, model)[0]
        assert_close(state.m[0], kf.x)
        assert_close(state.P[0], kf.P)


@pytest.mark.parametrize("seed,n,m", [(0, 4, 3), (1, 6, 2), (2, 3, 5)])
def test_ekf_matches_filterpy(seed, n, m):
    p = RandomNonlinear.draw(n, m, seed)
    m0, P0, zs = p.simulate(1, T, seed)
    ekf = filterpy_kalman.ExtendedKalmanFilter(dim_x=n, dim_z=m)
    ekf.x, ekf.P, ekf.Q, ekf.R = m0[0].copy(), P0[0].copy(), p.Q, p.R
    state = GaussianState(m0, P0)
    for z in zs:
        # filterpy's EKF predicts linearly (x = F x); the nonlinear prediction is done by hand.
        ekf.F = p.F(ekf.x)
        ekf.x = p.f(ekf.x)
        ekf.P = ekf.F @ ekf.P @ ekf.F.T + ekf.Q
        ekf.update(z[0], p.H, p.h)
        state = kalman.update(kalman.predict(state, p), z, p)[0]
        assert_close(state.m[0], ekf.x)
        assert_close(state.P[0], ekf.P)


@pytest.mark.parametrize(
    "seed,alpha,beta,kappa", [(0, 1.0, 2.0, 0.0), (1, 0.5, 2.0, 1.0), (2, 1.0, 0.0, 0.0)]
)
def test_ukf_matches_filterpy(seed, alpha, beta, kappa):
    n, m = 4, 3
    p = RandomNonlinear.draw(n, m, seed)
    m0, P0, zs = p.simulate(1, T, seed)
    points = filterpy_kalman.MerweScaledSigmaPoints(n, alpha=alpha, beta=beta, kappa=kappa)
    ukf = filterpy_kalman.UnscentedKalmanFilter(n, m, 1.0, p.hx, p.fx, points)
    ukf.x, ukf.P, ukf.Q, ukf.R = m0[0].copy(), P0[0].copy(), p.Q, p.R
    rule = Unscented(alpha, beta, kappa)
    state = GaussianState(m0, P0)
    for z in zs:
        # filterpy's UKF redraws sigma points from (x, P) after predict, as our update does.
        ukf.predict()
        ukf.update(z[0])
        state = sigma_point.update(sigma_point.predict(state, p, rule=rule), z, p, rule=rule)[0]
        assert_close(state.m[0], ukf.x)
        assert_close(state.P[0], ukf.P)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ckf_matches_filterpy_with_redrawn_points(seed):
    """filterpy's CKF reuses the propagated points (Q unseen by h); we redraw from N(m-, P-).

    With the points redrawn after filterpy's predict (its own ``spherical_radial_sigmas``) the
    formulations are the same, and the results must agree.
    """
    from filterpy.kalman.CubatureKalmanFilter import spherical_radial_sigmas

    n, m = 5, 3
    p = RandomNonlinear.draw(n, m, seed)
    m0, P0, zs = p.simulate(1, T, seed)
    ckf = filterpy_kalman.CubatureKalmanFilter(n, m, 1.0, p.hx, p.fx)
    ckf.x, ckf.P, ckf.Q, ckf.R = m0[0].reshape(-1, 1).copy(), P0[0].copy(), p.Q, p.R
    state = GaussianState(m0, P0)
    for z in zs:
        ckf.predict()
        ckf.sigmas_f = spherical_radial_sigmas(ckf.x.ravel(), ckf.P)
        ckf.update(z[0].reshape(-1, 1))
        state = sigma_point.update(sigma_point.predict(state, p, rule=Cubature()), z, p, rule=Cubature())[0]
        assert_close(state.m[0], ckf.x.ravel())
        assert_close(state.P[0], ckf.P)


def test_ckf_differs_from_filterpy_without_redraw():
    """Documents the formulation difference: without the redraw filterpy's CKF gives other numbers."""
    n, m = 5, 3
    p = RandomNonlinear.draw(n, m, 7)
    m0, P0, zs = p.simulate(1, 5, 7)
    ckf = filterpy_kalman.CubatureKalmanFilter(n, m, 1.0, p.hx, p.fx)
    ckf.x, ckf.P, ckf.Q, ckf.R = m0[0].reshape(-1, 1).copy(), P0[0].copy(), p.Q, p.R
    ckf.predict()
    ckf.update(zs[0, 0].reshape(-1, 1))
    ours = sigma_point.update(sigma_point.predict(GaussianState(m0, P0), p), zs[0], p)[0]
    assert not np.allclose(ours.P[0], ckf.P, rtol=1e-6)
