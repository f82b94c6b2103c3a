"""The update's linear weights carried to the next steps (bootstrap.update_weighted and the
``weights=`` keywords of the moments and the redistribution rule) give what the log-weights give."""

import numpy as np
import pytest

from filters import ParticleState
from filters.core.compiled import numpy_only
from filters.particle import bootstrap, estimates, triggers

from .problems import cv_model


def _cloud(B=6, N=400, seed=0, dtype=np.float64):
    rng = np.random.default_rng(seed)
    xT = rng.normal(size=(B, 2, N)).astype(dtype)
    lw = rng.normal(scale=2.0, size=(B, N))
    lw -= np.log(np.exp(lw).sum(axis=1, keepdims=True))
    return ParticleState(xT.transpose(0, 2, 1), lw)


@pytest.mark.parametrize("compiled", [True, False])
def test_update_weighted_is_update_and_returns_the_posterior_linear_weights(compiled):
    model = cv_model()
    state = _cloud()
    z = np.random.default_rng(1).normal(size=(6, 1))
    with numpy_only() if not compiled else np.errstate():
        plain, info = bootstrap.update(state, z, model)
        out = bootstrap.update_weighted(state, z, model)
    np.testing.assert_array_equal(out.state.log_w, plain.log_w)
    np.testing.assert_array_equal(out.info.ess, info.ess)
    np.testing.assert_allclose(out.weights, estimates.weights(plain.log_w), rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(out.weights.sum(axis=1), 1.0, rtol=1e-12)


def test_given_prior_weights_equal_the_computed_ones_to_rounding():
    model = cv_model()
    state = _cloud(seed=2)
    z = np.random.default_rng(3).normal(size=(6, 1))
    computed = bootstrap.update_weighted(state, z, model)
    given = bootstrap.update_weighted(state, z, model, prior_weights=estimates.weights(state.log_w))
    np.testing.assert_allclose(given.state.log_w, computed.state.log_w, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(given.weights, computed.weights, rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(given.info.nis, computed.info.nis, rtol=1e-9)
    with pytest.raises(ValueError, match="prior_weights must have shape"):
        bootstrap.update_weighted(state, z, model, prior_weights=np.ones((6, 3)))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_moments_with_given_weights_equal_the_moments_of_the_log_weights(dtype):
    state = _cloud(seed=4, dtype=dtype)
    w = estimates.weights(state.log_w)
    ref = estimates.mean_and_covariance(state)
    got = estimates.mean_and_covariance(state, weights=w)
    tol = 1e-12 if dtype == np.float64 else 1e-5
    np.testing.assert_allclose(got.m, ref.m, rtol=tol, atol=tol)
    np.testing.assert_allclose(got.P, ref.P, rtol=tol, atol=tol)
    with pytest.raises(ValueError, match="weights must have shape"):
        estimates.mean_and_covariance(state, weights=w[:, :3])


def test_the_redistribution_rule_from_given_weights_decides_as_from_the_log_weights():
    rng = np.random.default_rng(5)
    B, N = 64, 200
    # a spread of cases: uniform rows (never light), rows with a few heavy particles (light
    # majority), and rows near the rule's count threshold
    lw = rng.normal(scale=rng.uniform(0.0, 3.0, (B, 1)), size=(B, N))
    w = estimates.weights(lw)
    ref = triggers.redistribution_trigger(lw)
    got = triggers.redistribution_trigger(lw, weights=w)
    np.testing.assert_array_equal(got, ref)
    assert 0 < ref.sum() < B  # both outcomes occur
    with pytest.raises(ValueError, match="weights must have shape"):
        triggers.redistribution_trigger(lw, weights=w[:3])
