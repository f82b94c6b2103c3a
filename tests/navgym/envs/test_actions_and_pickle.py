"""Rejected actions change nothing, every rejection names the action and the space; the SB3
adapter refuses a step before reset; a pickled Resample vector env continues bit for bit."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)

FADING, RESAMPLE = "navgym/Robot2dFading-v1", "navgym/Robot2dResample-v1"


def _vec(env_id, n, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


# ----------------------------------------------------------------- rejected action at autoreset
def test_a_rejected_action_at_the_autoreset_step_does_not_change_the_next_episode():
    """Robot2dResample-v1, max_episode_steps=3: Discrete action 2 at the autoreset step raises
    and leaves the next episode as an env that never saw it plays it."""
    B = 2
    env, ref = _vec(RESAMPLE, B, max_episode_steps=3), _vec(RESAMPLE, B, max_episode_steps=3)
    env.reset(seed=5)
    ref.reset(seed=5)
    for _ in range(3):
        env.step(np.zeros(B, np.int64))
        _, _, _, trunc, _ = ref.step(np.zeros(B, np.int64))
    assert trunc.all()  # the next step autoresets
    for bad in (np.array([2, 0]), np.array([0, 2]), np.array([1, -1])):
        with pytest.raises(ValueError, match=r"Discrete\(2\)"):
            env.step(bad)
    for k in range(5):  # the autoreset step and the next episode
        a = np.array([k % 2, 1 - k % 2])
        out, out_ref = env.step(a), ref.step(a)
        for x, y in zip(out[:4], out_ref[:4], strict=True):
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(out[4]["pos_err_m"], out_ref[4]["pos_err_m"])


# --------------------------------------------------------------------------- action checks
@pytest.mark.parametrize(
    "action",
    [
        np.array([0.5 + 0.0j]),  # complex: the imaginary part used to be dropped
        np.array([0.5 + 1.0j]),
        "0.5",
        np.array(["0.5"]),
        np.array([True]),
        [None],
        np.array([0.5, 0.5]),
        np.array([[0.5]]),
        np.array([np.nan]),
        np.array([-np.inf]),
    ],
    ids=repr,
)
def test_box_actions_of_other_kinds_are_refused_naming_action_and_space(action):
    env = gym.make(FADING, episode_steps=5).unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action .* is not an action of the action space Box\(-1.0, 1.0"):
        env.step(action)


@pytest.mark.parametrize(
    "action",
    [1 + 1j, np.complex128(1), "1", b"1", True, np.bool_(False), 2, -1, 0.5, np.nan, [0, 1], [[1]], None],
    ids=repr,
)
def test_discrete_actions_of_other_kinds_are_refused_naming_action_and_space(action):
    env = gym.make(RESAMPLE, episode_steps=5, n_particles=50).unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"is not an action of the action space Discrete\(2\)"):
        env.step(action)


def test_a_huge_unsigned_discrete_action_is_reported_as_given():
    env = gym.make(RESAMPLE, episode_steps=5, n_particles=50).unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match="18446744073709551615") as caught:
        env.step(np.uint64(2**64 - 1))
    assert "-1" not in str(caught.value)
    env.step(np.uint64(1))  # an unsigned 1 is the decision "resample"


def test_the_vector_env_message_names_the_batch():
    env = _vec(FADING, 3, episode_steps=5)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"batched over 3 sub-environments\): shape \(2, 1\)"):
        env.step(np.zeros((2, 1), np.float32))


def test_out_of_range_box_actions_are_clipped_and_counted():
    env = gym.make(FADING, episode_steps=5).unwrapped
    ref = gym.make(FADING, episode_steps=5).unwrapped
    env.reset(seed=1)
    ref.reset(seed=1)
    for big, edge in ((1e300, 1.0), (-7.0, -1.0), (np.float32(3.0), 1.0), (np.int64(-2), -1.0)):
        o, r, *_, info = env.step(np.array([big]))
        o_ref, r_ref, *_, info_ref = ref.step(np.array([edge]))
        assert info["action_clipped"] and not info_ref["action_clipped"]
        np.testing.assert_array_equal(o, o_ref)
        assert r == r_ref


# ------------------------------------------------------------------------------------ SB3
def test_the_sb3_adapter_refuses_a_step_before_reset():
    pytest.importorskip("stable_baselines3")
    from navgym.envs.sb3 import NavSB3VecEnv

    venv = NavSB3VecEnv(FADING, num_envs=2, seed=0, episode_steps=5)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, 1), np.float32))
    venv.reset()
    with pytest.raises(ValueError, match=r"action space Box"):
        venv.step(np.array([[0.5 + 1j], [0.0]]))
    obs, reward, done, infos = venv.step(np.zeros((2, 1), np.float32))
    assert obs.shape[0] == 2 and infos[0]["divergence_reason"] == ""


# ---------------------------------------------------------------------------------- pickle
def test_a_pickled_resample_vector_env_continues_bit_for_bit():
    """The (B, N, n) particle view laid out (B, n, N) keeps its layout through pickle."""
    B = 3
    env = _vec(RESAMPLE, B, max_episode_steps=40)
    env.reset(seed=11)
    rng = np.random.default_rng(0)
    actions = [rng.integers(0, 2, B) for _ in range(210)]
    for a in actions[:10]:
        env.step(a)
    x = env.unwrapped.core.state.particles.x
    clone = pickle.loads(pickle.dumps(env))
    copied = copy.deepcopy(env)
    assert clone.unwrapped.core.state.particles.x.strides == x.strides
    for a in actions[10:]:
        out = env.step(a)
        for other in (clone, copied):
            o = other.step(a)
            for u, v in zip(out[:4], o[:4], strict=True):
                np.testing.assert_array_equal(u, v)
            np.testing.assert_array_equal(out[4]["pos_err_m"], o[4]["pos_err_m"])
