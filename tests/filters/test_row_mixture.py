"""Per-row mixture noise update (filters.row_mixture): known answers, masks, batches, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from filters import kalman, row_mixture
from filters.core.models import LinearGaussianModel
from filters.core.types import GaussianState

from .tolerances import ATOL, MASK_ATOL, MASK_RTOL, RTOL


def _problem(rng, B=5, n=4, m=3):
    A = rng.normal(size=(B, n, n))
    P = A @ A.transpose(0, 2, 1) + n * np.eye(n)
    state = GaussianState(rng.normal(size=(B, n)), P)
    H = rng.normal(size=(m, n))
    R = np.diag(rng.uniform(0.5, 2.0, m))
    model = LinearGaussianModel(np.eye(n), H, np.eye(n), R)
    z = (state.m @ H.T) + rng.normal(size=(B, m))
    return state, model, z


@pytest.mark.parametrize("base", ["ekf", "ckf", "ukf"])
@pytest.mark.parametrize("seed", [0, 1])
def test_no_outliers_equals_the_kalman_update(seed, base):
    """eps = 0: sequential processing of independent rows equals the batch KF update (linear model)."""
    rng = np.random.default_rng(seed)
    state, model, z = _problem(rng)
    post, info = row_mixture.update(state, z, model, eps=np.zeros(3), base=base)
    ref, ref_info = kalman.update(state, z, model)
    np.testing.assert_allclose(post.m, ref.m, rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(post.P, ref.P, rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(info.log_likelihood, ref_info.log_likelihood, rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(info.outlier_posterior, 0.0)


def test_all_outliers_equals_the_kalman_update_with_inflated_noise():
    rng = np.random.default_rng(2)
    state, model, z = _problem(rng)
    ratio = np.array([10.0, 100.0, 4.0])
    post, _ = row_mixture.update(state, z, model, eps=np.ones(3), variance_ratio=ratio, base="ekf")
    inflated = model._replace(R=model.R * ratio)
    ref, _ = kalman.update(state, z, inflated)
    np.testing.assert_allclose(post.m, ref.m, rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(post.P, ref.P, rtol=RTOL, atol=ATOL)


def test_one_row_is_the_exact_two_component_posterior():
    """m = 1: the moment-matched exact posterior of the two-component noise (eq. 72-76)."""
    rng = np.random.default_rng(3)
    state, model, z = _problem(rng, m=1)
    eps, ratio = 0.2, 50.0
    post, info = row_mixture.update(state, z, model, eps=np.full(1, eps), variance_ratio=ratio, base="ekf")
    comps = []
    for w, Rk in ((1 - eps, model.R), (eps, ratio * model.R)):
        p, i = kalman.update(state, z, model._replace(R=Rk))
        comps.append((np.log(w) + i.log_likelihood, p))
    lw = np.stack([c[0] for c in comps], axis=1)
    a = np.exp(lw - np.logaddexp(lw[:, 0], lw[:, 1])[:, None])
    mean = a[:, 0, None] * comps[0][1].m + a[:, 1, None] * comps[1][1].m
    cov = sum(
        a[:, k, None, None]
        * (comps[k][1].P + np.einsum("bi,bj->bij", comps[k][1].m - mean, comps[k][1].m - mean))
        for k in range(2)
    )
    np.testing.assert_allclose(info.outlier_posterior[:, 0], a[:, 1], rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(post.m, mean, rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(post.P, cov, rtol=RTOL, atol=ATOL)


def test_a_masked_row_contributes_nothing():
    rng = np.random.default_rng(4)
    state, model, z = _problem(rng)
    mask = np.ones((5, 3), dtype=bool)
    mask[:, 1] = False
    z_nan = z.copy()
    z_nan[:, 1] = np.nan
    eps = np.array([0.1, 0.5, 0.3])
    post, info = row_mixture.update(state, z_nan, model, mask, eps=eps, base="ckf")
    keep = [0, 2]
    small = model._replace(observation_matrix=model.observation_matrix[keep], R=model.R[np.ix_(keep, keep)])
    ref, ref_info = row_mixture.update(state, z[:, keep], small, eps=eps[keep], base="ckf")
    np.testing.assert_allclose(post.m, ref.m, rtol=MASK_RTOL, atol=MASK_ATOL)
    np.testing.assert_allclose(post.P, ref.P, rtol=MASK_RTOL, atol=MASK_ATOL)
    np.testing.assert_array_equal(info.outlier_posterior[:, 1], 0.5)  # prior kept
    assert (info.n_meas == 2).all() and (info.innovation[:, 1] == 0).all()


def test_fully_masked_filter_keeps_its_belief_bit_for_bit():
    rng = np.random.default_rng(5)
    state, model, z = _problem(rng)
    mask = np.ones((5, 3), dtype=bool)
    mask[2] = False
    post, info = row_mixture.update(state, z, model, mask, eps=np.full(3, 0.3), base="ckf")
    np.testing.assert_array_equal(post.m[2], state.m[2])
    np.testing.assert_array_equal(post.P[2], state.P[2])
    assert info.healthy.all() and info.log_likelihood[2] == 0.0


def test_batch_equals_loop_and_per_filter_weights():
    rng = np.random.default_rng(6)
    state, model, z = _problem(rng)
    eps = rng.uniform(0.0, 0.6, (5, 3))
    post, info = row_mixture.update(state, z, model, eps=eps, base="ckf")
    for b in range(5):
        one = GaussianState(state.m[b : b + 1], state.P[b : b + 1])
        p, i = row_mixture.update(one, z[b : b + 1], model, eps=eps[b : b + 1], base="ckf")
        np.testing.assert_allclose(p.m[0], post.m[b], rtol=RTOL, atol=ATOL)
        np.testing.assert_allclose(i.outlier_posterior[0], info.outlier_posterior[b], rtol=RTOL, atol=ATOL)


def test_the_row_with_the_gross_error_is_the_one_called_an_outlier():
    rng = np.random.default_rng(7)
    state, model, z = _problem(rng, B=1)
    state = GaussianState(state.m, 0.01 * state.P)
    z = state.m @ model.observation_matrix.T
    z[0, 1] += 30.0  # row 1 only
    post, info = row_mixture.update(state, z, model, eps=np.full(3, 0.1), variance_ratio=1000.0, base="ekf")
    assert info.outlier_posterior[0, 1] > 0.9
    assert info.outlier_posterior[0, 0] < 0.1 and info.outlier_posterior[0, 2] < 0.1


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"eps": np.full(3, 1.5)}, "eps must lie in"),
        ({"eps": np.full(2, 0.1)}, "eps must have shape"),
        ({"eps": np.full(3, 0.1), "variance_ratio": 1.0}, "variance_ratio"),
        ({"eps": np.full(3, np.nan)}, "eps must lie in"),
    ],
)
def test_bad_input_names_the_argument(kwargs, match):
    rng = np.random.default_rng(8)
    state, model, z = _problem(rng)
    with pytest.raises(ValueError, match=match):
        row_mixture.update(state, z, model, **kwargs)


def test_correlated_rows_are_refused():
    rng = np.random.default_rng(9)
    state, model, z = _problem(rng)
    R = model.R.copy()
    R[0, 1] = R[1, 0] = 0.1
    with pytest.raises(ValueError, match="diagonal"):
        row_mixture.update(state, z, model._replace(R=R), eps=np.zeros(3))
