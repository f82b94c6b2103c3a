"""Box-Muller normals from raw words: distribution, independence, bounds, per-row determinism."""

import numpy as np
import pytest
from scipy import stats

from filters.core.normal import MAX_ABS, box_muller, standard_normal_block
from filters.core.resampling import standard_normal

N_SIGMA = 5.0


def test_known_words_give_the_textbook_transform():
    """A word with radius field k and angle field j maps to sqrt(-2 ln u1) (cos, sin)(2 pi u2)."""
    k, j = np.uint64(123_456_789), np.uint64(7_654_321)
    word = np.array([(k << np.uint64(24)) | j], dtype=np.uint64)
    z = box_muller(word)
    u1, u2 = (float(k) + 0.5) * 2.0**-40, (float(j) + 0.5) * 2.0**-24
    r = np.sqrt(-2 * np.log(u1))
    np.testing.assert_allclose(z, [r * np.cos(2 * np.pi * u2), r * np.sin(2 * np.pi * u2)], rtol=3e-7)
    extreme = box_muller(np.array([0], dtype=np.uint64))  # smallest u1: the largest radius
    assert np.isclose(np.hypot(*extreme), MAX_ABS) and MAX_ABS == pytest.approx(7.54, abs=0.01)


def test_moments_and_ks_against_the_normal():
    """10^6 variates: mean, variance, skewness, excess kurtosis within 5 standard errors; KS."""
    z = standard_normal_block(np.random.default_rng(1), (1_000_000,))[0]
    n = z.size
    assert abs(z.mean()) < N_SIGMA / np.sqrt(n)
    assert abs(z.var() - 1) < N_SIGMA * np.sqrt(2 / n)
    assert abs(stats.skew(z)) < N_SIGMA * np.sqrt(6 / n)
    assert abs(stats.kurtosis(z)) < N_SIGMA * np.sqrt(24 / n)
    assert stats.kstest(z, "norm").pvalue > 1e-4
    # tail mass beyond 3 sigma: binomial standard error
    p3 = 2 * stats.norm.sf(3)
    assert abs((np.abs(z) > 3).mean() - p3) < N_SIGMA * np.sqrt(p3 * (1 - p3) / n)
    assert np.abs(z).max() <= MAX_ABS


def test_cos_and_sin_halves_are_uncorrelated_normals():
    """The two branches of each pair are independent: their correlation and that of squares ~ 0."""
    z = standard_normal_block(np.random.default_rng(2), (400_000,))[0]
    a, b = z[:200_000], z[200_000:]
    n = a.size
    assert abs(np.corrcoef(a, b)[0, 1]) < N_SIGMA / np.sqrt(n)
    assert abs(np.corrcoef(a * a, b * b)[0, 1]) < N_SIGMA / np.sqrt(n)
    assert stats.kstest(b, "norm").pvalue > 1e-4


def test_rows_come_from_their_own_generators_and_odd_sizes():
    """Row b depends on generator b only (batched == separate); odd sizes drop one variate."""
    shape = (3, 5)  # 15 variates: 8 words
    gens = [np.random.default_rng(s) for s in (4, 5, 6)]
    block = standard_normal_block(gens, shape)
    assert block.shape == (3, 3, 5)
    for b, s in enumerate((4, 5, 6)):
        alone = standard_normal_block(np.random.default_rng(s), shape)[0]
        np.testing.assert_array_equal(block[b], alone)
        g = np.random.default_rng(s)
        np.testing.assert_array_equal(alone.ravel(), box_muller(g.bit_generator.random_raw(8))[:15])
    # the generators advanced by exactly 8 words each
    ref = np.random.default_rng(4)
    ref.bit_generator.random_raw(8)
    assert gens[0].random() == ref.random()


def test_resampling_standard_normal_keeps_the_draw_semantics():
    """One Generator: one block; a sequence: per-filter rows; ``rows`` selects who draws."""
    gens = [np.random.default_rng(10 + b) for b in range(4)]
    rows = np.array([1, 3])
    e = standard_normal(gens, 4, (6, 2), rows)
    assert e.shape == (2, 6, 2)
    np.testing.assert_array_equal(e[1], standard_normal_block(np.random.default_rng(13), (6, 2))[0])
    assert gens[0].random() == np.random.default_rng(10).random()  # untouched: did not draw
    one = standard_normal(np.random.default_rng(0), 4, (6, 2))
    np.testing.assert_array_equal(one, standard_normal_block(np.random.default_rng(0), (4, 6, 2))[0])


def test_bad_input():
    with pytest.raises(ValueError, match="uint64"):
        box_muller(np.zeros(3, dtype=np.int64))
    with pytest.raises(ValueError, match="non-negative"):
        standard_normal_block(np.random.default_rng(0), (-1, 2))


def test_compiled_transform_equals_the_numpy_reference_within_two_float32_ulps():
    """The Numba kernel of box_muller against its NumPy twin (numpy_only) on the same words.

    Random words, and the edges: the smallest and largest radius and angle fields, and angles
    next to every quadrant boundary of the kernel's range reduction.
    """
    from filters.core.compiled import numpy_only

    rng = np.random.default_rng(7)
    j = np.array(
        [0, 1, 2**22 - 1, 2**22, 2**23 - 1, 2**23, 3 * 2**22 - 1, 3 * 2**22, 2**24 - 1], dtype=np.uint64
    )
    k = np.array([0, 1, 2**39, 2**40 - 1, 12345], dtype=np.uint64)
    edges = ((k[:, None] << np.uint64(24)) | j[None, :]).ravel()
    words = np.concatenate([edges, rng.bit_generator.random_raw(200_000)]).reshape(5, -1)
    for dtype in (np.float64, np.float32):
        compiled = box_muller(words, dtype)
        with numpy_only():
            reference = box_muller(words, dtype)
        assert compiled.dtype == reference.dtype == dtype and compiled.shape == reference.shape
        ulp = np.spacing(np.abs(reference).astype(np.float32)).astype(np.float64)
        assert (np.abs(compiled.astype(np.float64) - reference) <= 2 * ulp).all()
        assert np.abs(compiled).max() <= MAX_ABS * (1 + 1e-6)
    one = box_muller(words[0, :1])  # a 1-D word array keeps its shape
    assert one.shape == (2,)
