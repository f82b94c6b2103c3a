import pickle

import numpy as np
import pytest

from navgym.scenarios import default_rngs
from navgym.scenarios.seed_sequence import _MIN_BATCH, pcg64_seed_states

EDGE = [0, 1, 2**32 - 1, 2**32, 2**32 + 1, 2**63 - 1, 2**63, 2**64 - 1]


def _draws(g: np.random.Generator) -> np.ndarray:
    return np.concatenate([g.random(3), g.integers(0, 2**62, 3).astype(float), g.standard_normal(3)])


def test_states_equal_seed_sequence():
    drawn = np.random.default_rng(0).integers(0, 2**63 - 1, 500).tolist()
    seeds = np.array(drawn + EDGE, dtype=np.uint64)
    states = pcg64_seed_states(seeds)
    want = np.array([np.random.SeedSequence(int(s)).generate_state(4, np.uint64) for s in seeds])
    np.testing.assert_array_equal(states, want)


@pytest.mark.parametrize("n", [1, _MIN_BATCH - 1, _MIN_BATCH, 300])
def test_generators_draw_like_default_rng(n):
    seeds = np.random.default_rng(n).integers(0, 2**63 - 1, n)  # int64, as the envs draw them
    for g, s in zip(default_rngs(seeds), seeds, strict=True):
        np.testing.assert_array_equal(_draws(g), _draws(np.random.default_rng(s)))


def test_edge_seeds_and_shapes():
    seeds = np.array(EDGE * 10, dtype=np.uint64).reshape(10, -1)  # any shape, C order
    gens = default_rngs(seeds)
    assert len(gens) == seeds.size
    for g, s in zip(gens, seeds.ravel().tolist(), strict=True):
        np.testing.assert_array_equal(_draws(g), _draws(np.random.default_rng(s)))
    big = [2**64, 2**70 + 5] * 40  # beyond 64 bits: NumPy's own path
    for g, s in zip(default_rngs(big), big, strict=True):
        np.testing.assert_array_equal(_draws(g), _draws(np.random.default_rng(s)))
    assert default_rngs([]) == []


def test_negative_seed_rejected_like_numpy():
    with pytest.raises(ValueError, match="non-negative"):
        default_rngs(np.arange(-1, 100))


def test_pickle_and_spawn_like_default_rng():
    seeds = np.arange(1000, 1000 + _MIN_BATCH)
    g, ref = default_rngs(seeds)[7], np.random.default_rng(seeds[7])
    g.random(5), ref.random(5)
    g2 = pickle.loads(pickle.dumps(g))
    np.testing.assert_array_equal(_draws(g2), _draws(pickle.loads(pickle.dumps(ref))))
    for a, b in zip(g.spawn(2) + g.spawn(1), ref.spawn(2) + ref.spawn(1), strict=True):
        np.testing.assert_array_equal(_draws(a), _draws(b))
    assert g.bit_generator.seed_seq.entropy == int(seeds[7])
