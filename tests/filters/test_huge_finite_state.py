"""A finite state near the float range is not bad input: the step runs (and flags it), never raises.

``check_gaussian`` tests finiteness with one sum, which also overflows for finite entries of
1e307 (a diverging member under a huge fading factor); it then confirms entry by entry.
"""

import numpy as np
import pytest

from filters import GaussianState, kalman
from filters.core.validation import check_gaussian

from .problems import RandomNonlinear


def test_check_gaussian_accepts_entries_whose_sum_overflows():
    P = np.broadcast_to(np.eye(3) * 1e307 + 1e307, (2, 3, 3)).copy()
    with np.errstate(over="ignore"):
        assert not np.isfinite(P.sum())
    assert check_gaussian(GaussianState(np.full((2, 3), 1e307), P)) == (2, 3)


@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_check_gaussian_still_refuses_non_finite_entries(bad):
    P = np.broadcast_to(np.eye(3), (2, 3, 3)).copy()
    P[1, 2, 2] = bad
    with pytest.raises(ValueError, match="state.P has non-finite entries"):
        check_gaussian(GaussianState(np.zeros((2, 3)), P))
    m = np.zeros((2, 3))
    m[0, 1] = bad
    with pytest.raises(ValueError, match="state.m has non-finite entries"):
        check_gaussian(GaussianState(m, np.broadcast_to(np.eye(3), (2, 3, 3))))


def test_a_member_near_the_float_range_is_updated_without_raising_and_the_others_unchanged():
    p = RandomNonlinear.draw(3, 2, 0)
    m0, P0, zs = p.simulate(4, 1, 1)
    P = P0.copy()
    P[2] = (np.ones((3, 3)) + np.eye(3)) * 3e307  # positive definite, its sum overflows
    with np.errstate(over="ignore", invalid="ignore"):
        post, info = kalman.update(GaussianState(m0, P), zs[0], p)
    keep = [0, 1, 3]
    ref, ref_info = kalman.update(GaussianState(m0[keep], P0[keep]), zs[0][keep], p)
    assert info.healthy[keep].all()
    finite = np.isfinite(post.m[2]).all() and np.isfinite(post.P[2]).all()
    assert finite or not info.healthy[2]  # a finite result, or flagged
    np.testing.assert_allclose(post.m[keep], ref.m, rtol=1e-12)
    np.testing.assert_allclose(post.P[keep], ref.P, rtol=1e-12)
