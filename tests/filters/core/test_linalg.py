"""Batched small-matrix helpers of filters.core.linalg."""

import numpy as np
import pytest

from filters.core.linalg import trace_of_spd_inverse


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
