"""Rows reset with the same seed are simulated once (navgym.envs.distinct) and equal separate resets."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.envs.distinct import distinct_rows
from navgym.envs.registration import ENVIRONMENTS

IDS = [e[0] for e in ENVIRONMENTS]
SEEDS = [11, 11, 12, 11]  # rows 0, 1, 3 share one episode


def test_distinct_rows_merges_equal_generators_with_drawn_scenarios_only():
    g = [np.random.default_rng(s) for s in (1, 1, 2, 1)]
    assert distinct_rows(g, [None] * 4).tolist() == [0, 0, 2, 0]
    pinned = object()
    assert distinct_rows(g, [None, pinned, None, None]).tolist() == [0, 1, 2, 0]


@pytest.mark.parametrize("env_id", IDS)
def test_duplicate_seeds_equal_separate_resets(env_id, monkeypatch):
    from navgym.envs import distinct

    calls = []
    real = distinct._simulate
    monkeypatch.setattr(distinct, "_simulate", lambda p, r, s, T: calls.append(len(r)) or real(p, r, s, T))
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
