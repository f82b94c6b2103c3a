"""The compiled PCG64 words (filters.core.pcg64) equal random_raw's, and leave the same states."""

import numpy as np
import pytest

from filters.core import pcg64
from filters.core.compiled import numpy_only
from filters.core.resampling import standard_normal


def _gens(G, seed=1000):
    return [np.random.default_rng(seed + i) for i in range(G)]


def test_the_kernel_is_checked_and_used():
    assert pcg64._kernel_matches_numpy()


@pytest.mark.parametrize("G", [1, 3, 4, 9])
@pytest.mark.parametrize("h", [1, 2, 17, 1001])
def test_words_and_states_equal_random_raw(G, h):
    a, b = _gens(G), _gens(G)
    for g in b[::2]:  # generators that drew before (a used 32-bit half-word stays as it is)
        g.integers(0, 10, dtype=np.uint32)
    for g in a[::2]:
        g.integers(0, 10, dtype=np.uint32)
    words = pcg64._compiled_words(a, h)
    np.testing.assert_array_equal(words, np.stack([g.bit_generator.random_raw(h) for g in b]))
    for x, y in zip(a, b, strict=True):
        assert x.bit_generator.state == y.bit_generator.state
        assert x.standard_normal(3).tolist() == y.standard_normal(3).tolist()


def test_raw_words_falls_back_to_random_raw():
    """numpy_only, another bit generator, a generator listed twice and h = 0 take random_raw."""
    a, b = _gens(3), _gens(3)
    with numpy_only():
        np.testing.assert_array_equal(pcg64.raw_words(a, 5), pcg64._numpy_words(b, 5))
    mt = [np.random.Generator(np.random.MT19937(s)) for s in range(3)]
    mt2 = [np.random.Generator(np.random.MT19937(s)) for s in range(3)]
    np.testing.assert_array_equal(
        pcg64.raw_words(mt, 4), np.stack([g.bit_generator.random_raw(4) for g in mt2])
    )
    g, h = np.random.default_rng(5), np.random.default_rng(5)
    np.testing.assert_array_equal(pcg64.raw_words([g, g], 3), h.bit_generator.random_raw(6).reshape(2, 3))
    assert pcg64.raw_words(a, 0).shape == (3, 0)


@pytest.mark.parametrize("rows", [[0, 2, 5], [4], [], [5, 1, 3], [2, 2]])
def test_words_of_a_subset_of_rows(rows):
    """rows picks generators of the whole list: compiled when increasing, random_raw otherwise."""
    a, b = _gens(6), _gens(6)
    words = pcg64.raw_words(a, 7, np.array(rows, dtype=int))
    assert words.shape == (len(rows), 7)
    expected = [b[r].bit_generator.random_raw(7) for r in rows]
    np.testing.assert_array_equal(words, np.stack(expected) if rows else np.empty((0, 7), np.uint64))
    assert [g.bit_generator.state for g in a] == [g.bit_generator.state for g in b]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_standard_normal_of_generator_rows_unchanged(dtype):
    """Rows of normals are those of one random_raw per generator, transformed (normal.box_muller)."""
    from filters.core.normal import standard_normal_block

    rows = np.array([0, 2, 3, 6])
    a, b = _gens(7), _gens(7)
    got = standard_normal(a, 7, (3, 5), rows, dtype)
    want = standard_normal_block([b[i] for i in rows], (3, 5), dtype)
    np.testing.assert_array_equal(got, want)
    assert all(x.bit_generator.state == y.bit_generator.state for x, y in zip(a, b, strict=True))


@pytest.mark.parametrize("shape", [(1,), (3, 4), (0,)])
def test_uniform_of_generator_rows_unchanged(shape):
    """resampling.uniform from the compiled words equals 1 - Generator.random per generator."""
    from filters.core.resampling import uniform

    rows = np.array([1, 2, 5])
    a, b = _gens(6), _gens(6)
    got = uniform(a, 6, shape, rows)
    want = np.stack([1.0 - b[i].random(shape) for i in rows])
    np.testing.assert_array_equal(got, want)
    assert all(x.bit_generator.state == y.bit_generator.state for x, y in zip(a, b, strict=True))


def test_a_snapshot_restores_the_states_and_the_draws():
    """snapshot / restore round-trip bit_generator.state, a buffered 32-bit half-word included."""
    gens = _gens(6)
    for g in gens[::2]:
        g.integers(0, 10, dtype=np.uint32)
    before = [g.bit_generator.state for g in gens]
    snap = pcg64.snapshot(gens)
    assert snap is not None and snap.shape == (6, 5)
    first = [(g.random(4).tolist(), int(g.integers(0, 2**32, dtype=np.uint32))) for g in gens]
    assert [g.bit_generator.state for g in gens] != before
    pcg64.restore(gens, snap)
    assert [g.bit_generator.state for g in gens] == before
    assert [(g.random(4).tolist(), int(g.integers(0, 2**32, dtype=np.uint32))) for g in gens] == first


def test_no_snapshot_where_it_does_not_apply():
    """numpy_only, another bit generator and a generator listed twice: None (callers record dicts)."""
    g = np.random.default_rng(1)
    assert pcg64.snapshot([g, g]) is None
    assert pcg64.snapshot([np.random.Generator(np.random.MT19937(0))]) is None
    with numpy_only():
        assert pcg64.snapshot(_gens(2)) is None
    with pytest.raises(ValueError, match="snap must be snapshot"):
        pcg64.restore(_gens(2), np.zeros((3, 5), dtype=np.uint64))
