"""Rows reset with the same seed are simulated once (navgym.envs.distinct) and equal separate resets;
resets of the same episodes inside an EpisodeCache block are simulated once."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.envs.distinct import EpisodeCache, distinct_rows
from navgym.envs.registration import ENVIRONMENTS
from navgym.envs.rows import epoch_index
from tests.navgym.envs.simulations import count_simulations

IDS = [e[0] for e in ENVIRONMENTS]
SEEDS = [11, 11, 12, 11]  # rows 0, 1, 3 share one episode


def test_distinct_rows_merges_equal_generators_with_drawn_scenarios_only():
    g = [np.random.default_rng(s) for s in (1, 1, 2, 1)]
    assert distinct_rows(g, [None] * 4).tolist() == [0, 0, 2, 0]
    pinned = object()
    assert distinct_rows(g, [None, pinned, None, None]).tolist() == [0, 1, 2, 0]


@pytest.mark.parametrize("env_id", IDS)
def test_duplicate_seeds_equal_separate_resets(env_id, monkeypatch):
    calls = count_simulations(monkeypatch)
    venv = gym.make_vec(env_id, num_envs=len(SEEDS), vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=SEEDS)
    assert calls == [2]  # two distinct episodes simulated, not four
    states = [pickle.dumps(g.bit_generator.state) for g in venv.unwrapped.rngs]
    singles = {}
    for s in sorted(set(SEEDS)):
        e = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point")
        o, _ = e.reset(seed=[s])
        singles[s] = e
        rows = [i for i, x in enumerate(SEEDS) if x == s]
        for i in rows:
            np.testing.assert_array_equal(obs[i], o[0])
            assert states[i] == pickle.dumps(e.unwrapped.rngs[0].bit_generator.state)
    space = venv.single_action_space
    space.seed(0)
    for _ in range(3):
        per_seed = {s: space.sample() for s in singles}
        vo, vr, *_, vinfo = venv.step(np.stack([per_seed[s] for s in SEEDS]))
        for s, e in singles.items():
            o, r, *_, info = e.step(per_seed[s][None])
            for i in (i for i, x in enumerate(SEEDS) if x == s):
                np.testing.assert_array_equal(vo[i], o[0])
                assert vr[i] == r[0] and vinfo["pos_err_m"][i] == info["pos_err_m"][0]


def _object_fields(eps) -> list[np.ndarray]:
    out = []
    for a in eps:
        if isinstance(a, np.ndarray) and a.dtype == object and a.ndim >= 1:
            out.append(a)
        elif isinstance(a, tuple) and hasattr(a, "_fields"):
            out.extend(_object_fields(a))
    return out


@pytest.mark.parametrize("env_id", IDS)
def test_duplicate_rows_share_no_mutable_object(env_id):
    """An object array's rows are references: a duplicate must own copies (its own generators)."""
    venv = gym.make_vec(env_id, num_envs=len(SEEDS), vectorization_mode="vector_entry_point")
    venv.reset(seed=SEEDS)
    for a in _object_fields(venv.unwrapped.core.episodes):
        assert a[0] is not a[1] and a[0] is not a[3] and a[1] is not a[3]


def test_duplicate_rows_keep_equal_to_separate_resets_across_noise_refills():
    """GpsIns draws its pseudo-range noise in blocks of 64 steps from per-episode generators."""
    env_id = "navgym/GpsInsFading-v2"
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=[11, 11, 12])
    single = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point")
    single.reset(seed=[11])
    a = np.full((3, 1), -1.0, dtype=np.float32)
    for _ in range(140):  # two refills
        *_, vinfo = venv.step(a)
        *_, info = single.step(a[:1])
        assert vinfo["pos_err_m"][0] == vinfo["pos_err_m"][1] == info["pos_err_m"][0]


# ------------------------------------------------------------------------------ the episode cache
def _venv(env_id: str, n: int, **kw):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)


@pytest.mark.parametrize("env_id", IDS)
def test_episode_cache_serves_a_second_reset_of_the_same_episodes(env_id, monkeypatch):
    """A new env reset with the same seeds inside the block: no simulation, the same episodes."""
    calls = count_simulations(monkeypatch)
    cache = EpisodeCache()
    with cache.active():
        first = _venv(env_id, len(SEEDS))
        o1, _ = first.reset(seed=SEEDS)
        second = _venv(env_id, len(SEEDS))
        o2, _ = second.reset(seed=SEEDS)
    assert calls == [2] and (cache.hits, cache.misses) == (1, 1)
    np.testing.assert_array_equal(o1, o2)
    for g1, g2 in zip(first.unwrapped.rngs, second.unwrapped.rngs, strict=True):
        assert pickle.dumps(g1.bit_generator.state) == pickle.dumps(g2.bit_generator.state)
    objects = (_object_fields(venv.unwrapped.core.episodes) for venv in (first, second))
    for a1, a2 in zip(*objects, strict=True):
        assert all(x is not y for x, y in zip(a1, a2, strict=True))  # each env owns its generators
    for a in _object_fields(second.unwrapped.core.episodes):
        assert a[0] is not a[1] and a[0] is not a[3]
    space = first.single_action_space
    space.seed(1)
    for _ in range(3):
        act = np.stack([space.sample() for _ in SEEDS])
        r1 = first.step(act)
        r2 = second.step(act)
        np.testing.assert_array_equal(r1[0], r2[0])
        np.testing.assert_array_equal(r1[1], r2[1])
        np.testing.assert_array_equal(r1[4]["pos_err_m"], r2[4]["pos_err_m"])


def test_cached_episodes_stay_pristine_while_an_env_draws_from_its_copies():
    """GpsIns's per-episode noise generators draw every 64 steps: a later hit starts from fresh ones."""
    env_id = "navgym/GpsInsFading-v2"
    a = np.full((2, 1), -1.0, dtype=np.float32)
    single = _venv(env_id, 1)
    single.reset(seed=[11])
    errs = [single.step(a[:1])[4]["pos_err_m"][0] for _ in range(140)]
    cache = EpisodeCache()
    for _ in range(2):  # the miss, then the hit after the first env ran its generators on
        with cache.active():
            venv = _venv(env_id, 2)
            venv.reset(seed=[11, 11])
        got = [venv.step(a)[4]["pos_err_m"] for _ in range(140)]
        assert [g[0] for g in got] == [g[1] for g in got] == errs
    assert (cache.hits, cache.misses) == (1, 1)


def test_episode_cache_keys_the_platform_the_seeds_and_pinned_scenarios(monkeypatch):
    calls = count_simulations(monkeypatch)
    env_id = "navgym/Robot2dRowScale-v3"
    cache = EpisodeCache(maxsize=2)
    with cache.active():
        _venv(env_id, 2).reset(seed=[1, 2])
        _venv(env_id, 2).reset(seed=[1, 3])  # other seeds: simulated
        _venv(env_id, 2, episode_steps=50).reset(seed=[1, 2])  # another horizon: simulated
        assert len(cache) == 2  # the least recent dropped
        _venv(env_id, 2).reset(seed=[1, 2])  # dropped: simulated again
        _venv(env_id, 2, episode_steps=50).reset(seed=[1, 2])  # kept
    assert calls == [2, 2, 2, 2] and (cache.hits, cache.misses) == (1, 4)
    venv = _venv(env_id, 2)
    venv.reset(seed=[1, 2])
    scenario = venv.unwrapped.core.scenarios[0]
    with cache.active():
        venv.reset(seed=[1, 2], options={"scenario": scenario})  # pinned: never cached
    assert (cache.hits, cache.misses) == (1, 4)
    assert cache.key(object.__new__(_Unpicklable), [np.random.default_rng(0)], [None], 10) is None
    with pytest.raises(ValueError, match="maxsize must be at least 1; got 0"):
        EpisodeCache(0)


class _Unpicklable:
    def __reduce__(self):
        raise TypeError("not picklable")


def test_epoch_index_views_a_batch_in_lock_step_and_gathers_otherwise():
    a = np.arange(2 * 5 * 3, dtype=float).reshape(2, 5, 3)
    for t in (np.array([2, 2]), np.array([1, 4])):
        got = a[epoch_index(t)]
        np.testing.assert_array_equal(got, a[np.arange(2), t])
        assert np.shares_memory(got, a) == (t[0] == t[1])
