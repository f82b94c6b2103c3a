"""Numerical failures of the batched linear algebra are health flags, never exceptions."""

import numpy as np
import pytest

from filters.core import linalg

#: Exactly singular (``[[a, a], [a, a]]``) yet its element-wise Cholesky pivot rounds to a positive
#: number: LAPACK's LU then finds the zero pivot (a particle cloud spread by 1e9 m roughening).
_ROUNDED_PIVOT = 1.368761715425752e18


def test_the_singular_example_passes_the_pivots_but_not_lapack():
    a = _ROUNDED_PIVOT
    _, ok = linalg.cholesky_unrolled(np.array([[[a, a], [a, a]]]))
    assert ok[0]


def test_spd_inverse_flags_a_member_that_is_singular_to_working_precision():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((5, 2, 2))
    S = A @ A.transpose(0, 2, 1) + np.eye(2)
    S[1] = np.diag([1.0, -1.0])  # indefinite: takes the per-member path
    S[3] = _ROUNDED_PIVOT  # singular: passes the pivots, not np.linalg.inv
    S_inv, logdet, ok = linalg.spd_inverse(S)
    assert ok.tolist() == [True, False, True, False, True]
    assert np.isfinite(S_inv).all() and np.isfinite(logdet).all()
    for i in (0, 2, 4):  # the others: exactly what the batched call gives them
        ref_inv, ref_logdet, _ = linalg.spd_inverse(S[[i]])
        np.testing.assert_array_equal(S_inv[i], ref_inv[0])
        np.testing.assert_array_equal(S_inv[i], np.linalg.inv(S[i]))
        np.testing.assert_allclose(logdet[i], ref_logdet[0], rtol=1e-14)


@pytest.mark.parametrize("n", [2, 3, 8, 15])
def test_a_failing_member_does_not_change_the_others_bits(n):
    """The fallbacks give the members that factorize the fast path's own numbers, so a filter
    that fails in one row leaves the other rows exactly as in a batch without it."""
    rng = np.random.default_rng(n)
    A = rng.standard_normal((40, n, n))
    P = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(n)
    bad = P.copy()
    bad[7] = -np.eye(n)  # indefinite
    bad[11] = np.nan
    keep = [i for i in range(40) if i not in (7, 11)]
    L_ref, _ = linalg.cholesky(P[keep])
    L, ok = linalg.cholesky(bad)
    assert not ok[7] and not ok[11] and ok[keep].all()
    np.testing.assert_array_equal(L[keep], L_ref)
    inv_ref, logdet_ref, _ = linalg.spd_inverse(P[keep])
    inv, logdet, ok = linalg.spd_inverse(bad)
    assert not ok[7] and not ok[11] and ok[keep].all()
    np.testing.assert_array_equal(inv[keep], inv_ref)
    np.testing.assert_array_equal(logdet[keep], logdet_ref)
