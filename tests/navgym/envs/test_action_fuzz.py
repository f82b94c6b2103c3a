"""Registry-wide action fuzz, single and vector envs.

Every registered id is fed actions outside its space: NaN, infinities, complex numbers,
strings, bytes, None and objects, bools, wrong shapes, integers beyond int64, out-of-range and
non-integral values for ``Discrete``. Each must raise ``ValueError`` naming the action space
before the env changes: a valid step afterwards equals the valid step of a fresh env reset with
the same seed, bit for bit. Valid but out-of-range ``Box`` values (huge finite ones included)
are clipped and counted in ``info["action_clipped"]``, and step exactly like the box's bound.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)
from navgym.envs.registration import ENVIRONMENTS, superseded_ids_quiet

IDS = [e[0] for e in ENVIRONMENTS]
#: Short episodes and small clouds: the fuzz checks the action path, not the filters.
KWARGS = {"episode_steps": 8}
PARTICLES = {"n_particles": 64}
B = 3
SEED = 17


class _Opaque:
    """An object that is no number."""


def _kwargs(env_id: str) -> dict:
    return {**KWARGS, **(PARTICLES if "Resample" in env_id else {})}


def _single(env_id: str):
    with superseded_ids_quiet():
        return gym.make(env_id, **_kwargs(env_id)).unwrapped


def _vector(env_id: str):
    with superseded_ids_quiet():
        return gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point", **_kwargs(env_id))


def _bad_single(space: gym.Space) -> list:
    size = int(np.prod(space.shape)) if space.shape else 1
    common = [
        None,
        _Opaque(),
        "0",
        b"1",
        np.array(["1"]),
        True,
        np.bool_(False),
        np.array([True]),
        1 + 1j,
        np.complex64(1),
        np.array([0.5 + 0.5j]),
        [10**30],  # beyond int64: an object array
        [[0, 1], [1]],  # ragged
        np.zeros((0,)),
        np.zeros((size + 1,)),  # one entry too many
        np.zeros((1, 1, 1)),
    ]
    if isinstance(space, gym.spaces.Box):
        nan, inf = np.full(space.shape, np.nan), np.full(space.shape, np.inf, np.float32)
        return [*common, np.nan, np.inf, -np.inf, nan, inf]
    return [
        *common,
        np.nan,
        np.inf,
        2,
        -1,
        np.int64(-(2**63)),
        np.uint64(2**64 - 1),
        0.5,
        np.float32(1.5),
        1e300,
        [[1]],
    ]


def _bad_vector(space: gym.Space) -> list:
    ok = np.zeros((B, *space.shape), np.float32 if isinstance(space, gym.spaces.Box) else np.int64)
    one_bad = []
    for value in (np.nan, np.inf) if isinstance(space, gym.spaces.Box) else (2, -1):
        a = ok.astype(np.float64 if isinstance(space, gym.spaces.Box) else np.int64).copy()
        a[B - 1] = value
        one_bad.append(a)
    return [
        *one_bad,
        ok[:-1],  # one sub-env short
        np.concatenate([ok, ok[:1]]),
        ok[0],
        ok.reshape(B, -1)[..., None, None],
        ok.astype(np.complex128),
        ok.astype(bool),
        ok.astype(str),
        ok.astype(object),
        [ok[0]] * (B - 1) + [None],
        None,
        0.5,
    ]


def _valid(space: gym.Space):
    return np.full(space.shape, 0.25, np.float32) if isinstance(space, gym.spaces.Box) else np.int64(1)


def _equal(a, b):
    for x, y in zip(a[:4], b[:4], strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a[4]["pos_err_m"], b[4]["pos_err_m"])


@pytest.mark.parametrize("env_id", IDS)
def test_single_env_refuses_bad_actions_before_changing(env_id):
    env, fresh = _single(env_id), _single(env_id)
    env.reset(seed=SEED)
    fresh.reset(seed=SEED)
    space = env.action_space
    name = "Discrete" if isinstance(space, gym.spaces.Discrete) else "Box"
    for bad in _bad_single(space):
        with pytest.raises(ValueError, match=rf"is not an action of the action space {name}"):
            env.step(bad)
    _equal(env.step(_valid(space)), fresh.step(_valid(space)))
    if isinstance(space, gym.spaces.Box):  # clipped and counted, steps like the bound
        for big, edge in ((1e300, 1.0), (np.float32(-3.0), -1.0), (np.int64(7), 1.0)):
            out = env.step(np.full(space.shape, big))
            ref = fresh.step(np.full(space.shape, edge, np.float32))
            assert out[4]["action_clipped"] and not ref[4]["action_clipped"]
            _equal(out, ref)


@pytest.mark.parametrize("env_id", IDS)
def test_vector_env_refuses_bad_actions_before_changing(env_id):
    env, fresh = _vector(env_id), _vector(env_id)
    env.reset(seed=SEED)
    fresh.reset(seed=SEED)
    space = env.single_action_space
    name = "Discrete" if isinstance(space, gym.spaces.Discrete) else "Box"
    valid = np.stack([_valid(space)] * B)
    for bad in _bad_vector(space):
        with pytest.raises(ValueError, match=rf"is not an action of the action space {name}"):
            env.step(bad)
    _equal(env.step(valid), fresh.step(valid))
    if isinstance(space, gym.spaces.Box):
        big = valid.astype(np.float64).copy()
        big[1] = 1e300
        edge = valid.copy()
        edge[1] = 1.0
        out, ref = env.step(big), fresh.step(edge)
        assert out[4]["action_clipped"].tolist() == [False, True, False]
        _equal(out, ref)
