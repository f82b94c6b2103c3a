"""Per-row mixture noise update (filters.row_mixture): known answers, masks, batches, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from filters import kalman, row_mixture
from filters.core import row_mixture_kernels
from filters.core.models import LinearGaussianModel, RowMaskable
from filters.core.types import GaussianState
from filters.examples import RangeTracking
from tests.filters.compiled_paths import both_paths, count_calls

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


def _ranges(rng, B=12):
    """RangeTracking's nonlinear ranges (n = 9, m = 4) with per-filter weights, some 0 or 1, and masks."""
    problem = RangeTracking()
    truth, m0, P0 = problem.initial_state(B, rng)
    z = problem.h(truth) + problem.sigma_range * rng.standard_normal((B, problem.m))
    z[1, 2] += 40.0  # a gross error on one row
    eps = rng.uniform(0.0, 0.5, (B, problem.m))
    eps[2, :2] = 0.0
    eps[3, 1] = 1.0
    mask = rng.uniform(size=(B, problem.m)) > 0.25
    mask[4] = False  # no row at all
    mask[:, 3] = False  # a row no filter has: skipped
    z[~mask] = np.nan
    return problem, GaussianState(m0, P0), z, mask, eps


def _same_update(a, b, rtol=RTOL, atol=ATOL):
    (pa, ia), (pb, ib) = a, b
    np.testing.assert_allclose(pa.m, pb.m, rtol=rtol, atol=atol, err_msg="m")
    np.testing.assert_allclose(pa.P, pb.P, rtol=rtol, atol=atol, err_msg="P")
    for name in ("innovation", "S", "nis", "log_likelihood", "outlier_posterior"):
        np.testing.assert_allclose(getattr(ia, name), getattr(ib, name), rtol=rtol, atol=atol, err_msg=name)
    np.testing.assert_array_equal(ia.healthy, ib.healthy)
    np.testing.assert_array_equal(ia.n_meas, ib.n_meas)


@pytest.mark.parametrize("base", ["ckf", "ukf", "dd1", "ekf"])
def test_the_compiled_rows_equal_the_numpy_path(monkeypatch, base):
    """The scalar row kernel (filters.core.row_mixture_kernels) = the base filter's banked update."""
    rng = np.random.default_rng(11)
    problem, state, z, mask, eps = _ranges(rng)
    ratio = np.array([50.0, 100.0, 20.0, 10.0])
    calls = count_calls(monkeypatch, row_mixture_kernels, ["row_pass"])

    def run():
        return row_mixture.update(state, z, problem, mask, eps=eps, variance_ratio=ratio, base=base)

    compiled, numpy = both_paths(run)
    assert calls == {"row_pass": 3}  # rows 0-2; row 3 is no filter's
    _same_update(compiled, numpy)
    post, info = compiled
    assert info.healthy.all()
    np.testing.assert_array_equal(post.m[4], state.m[4])  # no rows: the prior, bit for bit
    np.testing.assert_array_equal(post.P[4], state.P[4])
    np.testing.assert_array_equal(post.P, np.swapaxes(post.P, 1, 2))
    np.testing.assert_array_equal(info.outlier_posterior[~mask], eps[~mask])
    assert info.outlier_posterior[1, 2] > 0.99  # the gross error is called an outlier
    np.testing.assert_array_equal(info.outlier_posterior[3, 1][mask[3, 1]], 1.0)
    np.testing.assert_array_equal(info.outlier_posterior[2, :2][mask[2, :2]], 0.0)


def test_a_filter_the_kernel_does_not_take_sends_its_row_to_the_numpy_path(monkeypatch):
    """A prior that is not positive definite needs jittered points: that row takes the reference path."""
    rng = np.random.default_rng(12)
    problem, state, z, mask, eps = _ranges(rng)
    P = state.P.copy()
    P[0, 0, 0] = -1.0  # filter 0's points need the jitter fallback (unhealthy)
    state = GaussianState(state.m, P)
    mask[0] = True
    mask[:, 3] = True
    z = problem.h(state.m) + rng.standard_normal(z.shape)
    rows = {"kernel": 0, "reference": 0}
    compiled_row = row_mixture._compiled_row

    def counted_compiled(*args):
        out = compiled_row(*args)
        rows["kernel" if out is not None else "reference"] += 1
        return out

    monkeypatch.setattr(row_mixture, "_compiled_row", counted_compiled)

    def run():
        return row_mixture.update(state, z, problem, mask, eps=eps, base="ckf")

    compiled, numpy = both_paths(run)
    assert rows == {"kernel": 0, "reference": 4}  # filter 0 has every row: each row falls back
    _same_update(compiled, numpy)
    assert not compiled[1].healthy[0] and compiled[1].healthy[1:].all()


def test_a_row_no_filter_has_keeps_the_neutral_diagnostics():
    """A row masked in every filter is skipped: innovation 0, variance 1, the prior weight."""
    rng = np.random.default_rng(13)
    problem, state, z, mask, eps = _ranges(rng)
    post, info = row_mixture.update(state, z, problem, mask, eps=eps, base="ckf")
    assert (info.innovation[:, 3] == 0).all() and (np.diagonal(info.S, axis1=1, axis2=2)[:, 3] == 1).all()
    np.testing.assert_array_equal(info.outlier_posterior[:, 3], eps[:, 3])


class _MaskableRanges:
    """RangeTracking's ranges, predicting the rows asked for alone (filters.core.models.RowMaskable)."""

    def __init__(self, problem, rows=None):
        self.problem, self.rows, self.R = problem, rows, problem.R
        self.calls: list[list[int]] = []

    def h(self, x):
        if self.rows is None:
            return self.problem.h(x)
        out = np.zeros((*x.shape[:-1], self.problem.m))
        d = x[..., None, 0:3] - self.problem.beacons[self.rows]
        out[..., self.rows] = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2])
        return out

    def H(self, x):
        return self.problem.H(x)

    def only_rows(self, rows):
        self.calls.append(list(rows))
        return _MaskableRanges(self.problem, np.asarray(rows))


@pytest.mark.parametrize("base", ["ckf", "ekf"])
def test_a_row_maskable_model_predicts_each_row_alone_with_the_same_numbers(base):
    """A RowMaskable model's one-row predictions give the whole model's update bit for bit."""
    rng = np.random.default_rng(12)
    problem, state, z, mask, eps = _ranges(rng)
    maskable = _MaskableRanges(problem)
    assert isinstance(maskable, RowMaskable) and not isinstance(problem, RowMaskable)
    got = row_mixture.update(state, z, maskable, mask, eps=eps, base=base)
    ref = row_mixture.update(state, z, problem, mask, eps=eps, base=base)
    assert maskable.calls == [[0], [1], [2]]  # one per row some filter has (row 3: none)
    for a, b in zip((*got[0], *got[1]), (*ref[0], *ref[1]), strict=True):
        if a is not None:
            np.testing.assert_array_equal(a, b)
    one = maskable.only_rows([1])
    x = rng.standard_normal((3, 5, 9)) * 100
    h = one.h(x)
    np.testing.assert_array_equal(h[..., 1], problem.h(x)[..., 1])
    assert not h[..., [0, 2, 3]].any()
