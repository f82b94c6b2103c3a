"""Batched small-matrix helpers of filters.core.linalg."""

import numpy as np
import pytest

from filters.core import linalg
from filters.core.linalg import gram, trace_of_spd_inverse


@pytest.mark.parametrize("n", [1, 2, 4, 5])
def test_trace_of_spd_inverse_equals_numpy(n):
    rng = np.random.default_rng(n)
    M = rng.normal(size=(64, n + 3, n))
    A = np.swapaxes(M, 1, 2) @ M
    np.testing.assert_allclose(
        trace_of_spd_inverse(A), np.trace(np.linalg.inv(A), axis1=1, axis2=2), rtol=1e-12
    )


def test_trace_of_spd_inverse_is_nan_where_not_positive_definite():
    A = np.stack([np.eye(3), np.diag([1.0, 1.0, 0.0]), np.diag([1.0, -1.0, 1.0])])
    tr = trace_of_spd_inverse(A)
    assert tr[0] == pytest.approx(3.0)
    assert np.isnan(tr[1:]).all()


def _ill_conditioned_pd() -> np.ndarray:
    """A GNSS/INS-like covariance: 9e10 m^2 clock against 1e-6 attitude (condition 1e17)."""
    return np.diag([9e10, 1.0, 1e-6])


def test_cholesky_of_a_member_does_not_depend_on_the_rest_of_the_batch():
    good = _ill_conditioned_pd()
    indefinite = np.diag([1.0, -1.0, 1.0])
    L, ok = linalg.cholesky(np.stack([good, indefinite, np.full((3, 3), np.nan)]))
    L_alone, ok_alone = linalg.cholesky(good[None])
    assert ok_alone.all() and ok.tolist() == [True, False, False]
    np.testing.assert_allclose(L[0], L_alone[0], rtol=1e-15)
    np.testing.assert_array_equal(L[2], np.eye(3))  # non-finite: the identity
    shift = L[1] @ L[1].T - indefinite  # the indefinite member only is shifted: by s I, s > 1
    np.testing.assert_allclose(shift, shift[0, 0] * np.eye(3), atol=1e-12)
    assert shift[0, 0] > 1.0


def test_spd_inverse_of_a_member_does_not_depend_on_the_rest_of_the_batch():
    good = _ill_conditioned_pd()
    S_inv, logdet, ok = linalg.spd_inverse(np.stack([good, np.diag([1.0, -1.0, 1.0])]))
    assert ok.tolist() == [True, False]
    np.testing.assert_allclose(S_inv[0], np.diag(1.0 / np.diag(good)), rtol=1e-12)
    assert logdet[0] == pytest.approx(np.log(np.diag(good)).sum(), rel=1e-12)
    assert np.isfinite(S_inv[1]).all()


@pytest.mark.parametrize("n", [1, 3, 8, 15])
def test_cholesky_unrolled_equals_numpy_and_flags_failures(n):
    rng = np.random.default_rng(n)
    M = rng.normal(size=(16, n + 2, n))
    A = np.swapaxes(M, 1, 2) @ M
    A[3] = -A[3]  # negative definite
    L, ok = linalg.cholesky_unrolled(A)
    assert ok.tolist() == [i != 3 for i in range(16)]
    np.testing.assert_allclose(L[ok], np.linalg.cholesky(A[ok]), rtol=1e-10, atol=1e-12)


def test_spd_inverse_fallback_keeps_extra_leading_axes():
    """The Rao-Blackwellized PF inverts (B, N, m, m) batches: one bad member must not raise."""
    rng = np.random.default_rng(3)
    M = rng.normal(size=(3, 4, 5, 3))
    S = np.swapaxes(M, -1, -2) @ M
    S[1, 2] = -np.eye(3)
    S_inv, logdet, ok = linalg.spd_inverse(S)
    assert S_inv.shape == (3, 4, 3, 3) and logdet.shape == ok.shape == (3, 4)
    assert ok.sum() == 11 and not ok[1, 2]
    np.testing.assert_allclose(S_inv[ok], np.linalg.inv(S[ok]), rtol=1e-10)
    np.testing.assert_allclose(logdet[ok], np.linalg.slogdet(S[ok])[1], rtol=1e-10)


@pytest.mark.parametrize("shape", [(7, 12, 3), (5, 4, 9), (3, 16, 2), (2, 3, 4, 5)])
def test_gram_equals_the_product_with_the_transpose(shape):
    A = np.random.default_rng(3).standard_normal(shape)
    G = gram(A)
    np.testing.assert_allclose(G, np.einsum("...ik,...jk->...ij", A, A), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(G, np.swapaxes(G, -1, -2), rtol=1e-15, atol=1e-15)
