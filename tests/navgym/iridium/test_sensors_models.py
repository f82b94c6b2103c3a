"""Iridium fixes (CEP law, errors) and the filter models (constant velocity, virtual beacon)."""

import numpy as np
import pytest

from filters import GaussianState
from filters import get as get_filter
from navgym.iridium.models import BeaconFix, ConstantVelocity, cv_process_noise
from navgym.iridium.sensors import CEP_PER_SIGMA, IridiumFixNoise, cep_sigma


def test_half_the_fixes_fall_within_the_cep_radius():
    """``sigma = CEP / sqrt(2 ln 2)``: the CEP is the median of the Rayleigh radius (100k draws)."""
    cep = 900.0
    e = cep_sigma(cep) * np.random.default_rng(1).standard_normal((100_000, 2))
    assert np.mean(np.hypot(e[:, 0], e[:, 1]) <= cep) == pytest.approx(0.5, abs=0.005)
    assert CEP_PER_SIGMA == pytest.approx(1.17741, abs=1e-5)


def test_cep_law_of_the_serving_elevation():
    f = IridiumFixNoise()
    np.testing.assert_allclose(f.cep(np.pi / 2), 650.0)
    np.testing.assert_allclose(f.cep(np.radians(8.2)), 650.0 / np.sqrt(np.sin(np.radians(8.2))))
    assert f.cep(np.nan) == f.cep_max and f.cep(np.radians(0.01)) == f.cep_max


def test_outlier_kinds_and_rates():
    f = IridiumFixNoise()
    rng = np.random.default_rng(2)
    u, v = rng.random(400_000), rng.random(400_000)
    var = f.outlier_variance(u, v)
    s = np.sqrt(var[var > 0])
    gross = s >= 80e3
    assert np.mean(var > 0) == pytest.approx(f.outlier_rate + f.gross_rate, abs=0.001)
    assert np.mean(gross) * np.mean(var > 0) == pytest.approx(f.gross_rate, abs=2e-4)
    assert s[~gross].min() >= 1600.0 and s[~gross].max() <= 8000.0 and s[gross].max() <= 240e3
    # the source's sizes: outliers' mean errors of 2-10 km, gross ones above 100 km
    assert 1.25 * 1600 == pytest.approx(2000, rel=0.01) and 1.2533 * 80e3 > 100e3


def test_bad_fix_noise_is_refused():
    with pytest.raises(ValueError, match="outlier_rate"):
        IridiumFixNoise(outlier_rate=1.5)
    with pytest.raises(ValueError, match="cep_zenith"):
        IridiumFixNoise(cep_zenith=0.0)


def test_constant_velocity_f_F_and_Q():
    dt = 10.0
    x = np.array([[1.0, 2.0, 3.0, -4.0], [0.0, 0.0, 1.0, 1.0]])
    model = ConstantVelocity(cv_process_noise(np.array([0.1, 0.2]), dt))
    np.testing.assert_allclose(model.f(x, None, dt), np.einsum("bij,bj->bi", model.F(x, None, dt), x))
    np.testing.assert_allclose(model.f(x, None, dt)[0], [31.0, -38.0, 3.0, -4.0])
    Q = model.Q[1]
    np.testing.assert_allclose([Q[0, 0], Q[0, 2]], [0.2 * dt**3 / 3, 0.2 * dt**2 / 2])
    assert Q[0, 1] == 0.0 and Q[2, 2] == pytest.approx(0.2 * dt)
    # f broadcasts over sigma points (B, S, n)
    pts = np.repeat(x[:, None, :], 3, axis=1)
    np.testing.assert_allclose(model.f(pts, None, dt)[:, 1], model.f(x, None, dt))
    assert model.repeat_batch(2).Q.shape == (4, 4, 4)


def test_the_kalman_update_with_the_beacon_pulls_toward_it_by_the_cep_weight():
    """Equal prior and fix sigma: the estimate moves half way to the beacon (innovation = eq. 83's rho)."""
    s = 700.0
    prior = GaussianState(np.zeros((1, 4)), np.diag([s**2, s**2, 100.0, 100.0])[None])
    obs = BeaconFix((s**2 * np.eye(2))[None])
    z = np.array([[300.0, -400.0]])
    post, info = get_filter("ekf").update(prior, z, obs, mask=np.ones((1, 2), bool))
    np.testing.assert_allclose(post.m[0, :2], [150.0, -200.0])
    assert np.hypot(*info.innovation[0]) == pytest.approx(500.0)  # rho from the estimate to the beacon
