import numpy as np
import pytest

from navgym.motion.profiles import segment_index, smootherstep

SEEDS = [0, 1, 2]


def _reference(t_start, t):
    """max{i : t_start[b, i] <= t[b, k]} (0 before the first start), one row at a time."""
    rows = [np.searchsorted(r, q, side="right") - 1 for r, q in zip(t_start, t, strict=True)]
    return np.maximum(np.stack(rows), 0)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("segments", [5, 11, 40], ids=["5-segments", "11-segments", "40-segments"])
@pytest.mark.parametrize("queries", [1, 4, 5, 200], ids=["one", "direct-max", "search-min", "many"])
def test_segment_index_equals_per_row_searchsorted(seed, segments, queries):
    # few segments or few queries: direct comparison; otherwise the batched searchsorted
    rng = np.random.default_rng(seed)
    B, S = 37, segments
    grid = np.linspace(-3.0, 40.0, 44)  # shared grid: many exact ties between starts and times
    t_start = np.sort(rng.choice(grid, size=(B, S)), axis=1)
    t_start[:, 0] = np.minimum(t_start[:, 0], 0.0)
    t_start[rng.random(B) < 0.5, -3:] = np.inf  # padded rows
    t = rng.choice(np.concatenate([grid, grid + 1e-9, grid - 1e-9, [-10.0, 100.0]]), size=(B, queries))
    np.testing.assert_array_equal(segment_index(t_start, t), _reference(t_start, t))


def test_segment_index_is_exact_at_boundaries_of_a_large_batch():
    # the many-queries path shifts rows by large offsets; ties must still resolve exactly
    starts = np.concatenate([[0.0, 0.1, 0.30000000000000004, 1e3], np.full(16, np.inf)])
    times = np.array(
        [0.1, np.nextafter(0.1, 0.0), 0.30000000000000004, np.nextafter(0.30000000000000004, 0.0)]
    )
    times = np.concatenate([times, [1e3, np.nextafter(1e3, 0.0), 5e3, -1.0, 0.0]])
    t_start = np.broadcast_to(starts, (4096, starts.size))
    t = np.broadcast_to(times, (4096, 9))
    expected = np.broadcast_to(np.array([1, 0, 2, 1, 3, 2, 3, 0, 0]), (4096, 9))
    np.testing.assert_array_equal(segment_index(t_start, t), expected)


def test_segment_index_rejects_bad_input():
    with pytest.raises(ValueError, match="t_start must be"):
        segment_index(np.zeros((2, 3)), np.zeros((3, 1)))
    with pytest.raises(ValueError, match="finite"):
        segment_index(np.zeros((2, 3)), np.full((2, 20), np.nan))
    assert segment_index(np.zeros((2, 3)), np.zeros((2, 0))).shape == (2, 0)


def test_smootherstep_antiderivative_integrates_the_profile():
    tau = np.linspace(0.0, 1.5, 31)
    x = np.linspace(0.0, 1.5, 300001)
    ref = np.concatenate([[0.0], np.cumsum(0.5 * (smootherstep(x[1:]) + smootherstep(x[:-1])) * np.diff(x))])
    np.testing.assert_allclose(smootherstep(tau, -1), np.interp(tau, x, ref), atol=1e-10)
