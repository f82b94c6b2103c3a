"""Cloud layout and precision helpers (filters.core.layout)."""

import numpy as np

from filters.core.layout import cloud_dtype, is_component_major, weights_in


def _degenerate_weights(B: int = 4, N: int = 500, seed: int = 0) -> np.ndarray:
    """Normalized float64 weights spread over 1 .. 1e-200, as in a never-resampled cloud."""
    rng = np.random.default_rng(seed)
    log_w = -rng.uniform(0.0, 460.0, (B, N))
    w = np.exp(log_w)
    return w / w.sum(axis=1, keepdims=True)


def test_float64_weights_pass_through():
    w = _degenerate_weights()
    assert weights_in(w, np.float64) is w


def test_float32_weights_have_no_subnormal_numbers():
    w = _degenerate_weights()
    tiny32 = np.finfo(np.float32).tiny
    plain = w.astype(np.float32)
    assert ((plain > 0) & (plain < tiny32)).any()  # the plain cast makes subnormals
    out = weights_in(w, np.float32)
    assert out.dtype == np.float32
    assert not ((out > 0) & (out < tiny32)).any()
    floor = tiny32 / np.finfo(np.float32).eps
    kept = plain >= floor
    np.testing.assert_array_equal(out[kept], plain[kept])  # weights above the floor as cast
    assert (out[~kept] == 0).all() and (~kept).any()


def test_flushed_weights_leave_the_moments_at_float32_rounding():
    w = _degenerate_weights(seed=1)
    rng = np.random.default_rng(2)
    x = rng.normal(0.0, 100.0, w.shape + (3,)).astype(np.float32)
    x64 = x.astype(np.float64)

    def moment(weights):  # in float64, so only the weights differ
        return np.einsum("bn,bni->bi", weights.astype(np.float64), x64)

    cast, flushed = moment(w.astype(np.float32)), moment(weights_in(w, np.float32))
    # the dropped weights (< 1e-31 each, 500 particles of |x| ~ 100 m) move the mean by < 1e-26 m
    np.testing.assert_allclose(flushed, cast, rtol=0, atol=1e-26)


def test_layout_predicates():
    buf = np.zeros((2, 3, 5), dtype=np.float32)
    assert is_component_major(buf.transpose(0, 2, 1))
    assert not is_component_major(np.zeros((2, 5, 3)))
    assert cloud_dtype(buf) == np.float32
    assert cloud_dtype(np.zeros(3, dtype=np.float16)) == np.float64
