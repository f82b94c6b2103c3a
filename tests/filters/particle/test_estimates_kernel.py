"""The compiled centring pass of estimates._covariance leaves the weighted moments bit for bit."""

import numpy as np
import pytest

from filters.core.compiled import numpy_only
from filters.core.types import ParticleState
from filters.particle import estimates


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize(("B", "N", "n"), [(64, 500, 8), (3, 7, 2), (5, 1, 3)])
def test_moments_of_a_component_major_cloud_equal_the_numpy_path(dtype, B, N, n):
    r = np.random.default_rng(B + N + n)
    xT = (r.standard_normal((B, n, N)) * 100.0 + 1e3).astype(dtype)
    if N > 3 and B > 2:
        xT[2, 1, 3] = np.nan  # a non-finite particle: NaN moments in that filter only
    state = ParticleState(xT.transpose(0, 2, 1), r.normal(0.0, 3.0, (B, N)))
    with np.errstate(invalid="ignore"):
        got = estimates.mean_and_covariance(state)
        cov = estimates.covariance(state)
        with numpy_only():
            want = estimates.mean_and_covariance(state)
    np.testing.assert_array_equal(got.m, want.m)
    np.testing.assert_array_equal(got.P, want.P)
    np.testing.assert_array_equal(cov, want.P)
