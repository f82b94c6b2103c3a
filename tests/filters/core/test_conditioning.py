import numpy as np
import pytest

from filters.core.conditioning import mask_moments, masked_covariance


@pytest.mark.parametrize(
    ("c_shape", "w_shape"),
    [((5, 5), (7, 5)), ((7, 5, 5), (7, 5)), ((7, 3, 5, 5), (7, 1, 5))],
    ids=["shared", "batched", "per-particle"],
)
def test_masked_covariance_keeps_the_used_block_and_isolates_masked_rows(c_shape, w_shape):
    rng = np.random.default_rng(0)
    C = rng.standard_normal(c_shape)
    C_before = C.copy()
    w = (rng.random(w_shape) < 0.6).astype(np.float64)
    got = masked_covariance(C, w)
    m = c_shape[-1]
    ref = C * (w[..., :, None] * w[..., None, :]) + np.eye(m) * (1.0 - w)[..., None, :]
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(C, C_before)  # a new array: the input is untouched
    used = w[..., :, None] * w[..., None, :] > 0
    np.testing.assert_array_equal(
        np.where(used, got, 0.0), np.where(used, np.broadcast_to(C, got.shape), 0.0)
    )


def test_mask_moments_zeroes_masked_rows_and_gives_them_unit_variance():
    rng = np.random.default_rng(1)
    B, m, n = 4, 3, 2
    v, S, P_xz = rng.standard_normal((B, m)), rng.standard_normal((B, m, m)), rng.standard_normal((B, n, m))
    mask = np.array([[True, False, True]] * B)
    v2, S2, P2 = mask_moments(v, S, P_xz, mask)
    assert (v2[:, 1] == 0).all() and (P2[:, :, 1] == 0).all()
    np.testing.assert_array_equal(S2[:, 1], np.broadcast_to([0.0, 1.0, 0.0], (B, 3)))
    np.testing.assert_array_equal(S2[:, [0, 2]][:, :, [0, 2]], S[:, [0, 2]][:, :, [0, 2]])
    assert mask_moments(v, S, P_xz, np.ones((B, m), bool))[1] is S  # nothing masked: no copy
