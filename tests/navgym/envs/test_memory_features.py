"""Memory features (``memory_features=True``): hand recursions, reset, autoreset, snapshot, pickle.

The averages equal a hand recursion of the module docstring's formulas on the published
``info``; the memory restarts with each episode and follows the core's snapshot/restore, so a
vector env's sub-env ``i`` equals a single env seeded ``s + i`` across autoresets; without the
argument nothing changes.
"""

from __future__ import annotations

import pickle
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)
from navgym.envs.memory import TIME_CONSTANTS_S, WINDOW_STEPS, InnovationMemory
from navgym.scenarios import Outage, Scenario
from tests.navgym.envs.toy_v2 import ToyEnv, ToyVectorEnv

MEMORY_COLUMNS = ("log_nis_avg_1s", "log_nis_avg_10s", "innovation_avg", "innovation_whiteness")


def _info(y: np.ndarray, used: np.ndarray) -> SimpleNamespace:
    """Update diagnostics whose normalized innovations are ``y (B, m)`` (S = 4 I, NIS of y)."""
    B, m = y.shape
    S = np.broadcast_to(4.0 * np.eye(m), (B, m, m))
    v = 2.0 * y
    return SimpleNamespace(
        innovation=np.where(used, v, 0.0),
        S=S,
        nis=np.where(used, y * y, 0.0).sum(axis=1),
        n_meas=used.sum(axis=1),
    )


def _cols(env, obs: np.ndarray) -> dict[str, np.ndarray]:
    fs = env.unwrapped.observation_features
    return {name: obs[fs.index(name)] for name in MEMORY_COLUMNS}


def test_whiteness_known_answers_and_its_window():
    mem = InnovationMemory(dt=1.0, m_max=2, window=4)
    state = mem.initial_state(3)
    used = np.array([[True, True], [True, False], [False, False]])
    for k in range(6):  # constant innovations: r = +1; alternating: r = -1; nothing received: 0
        y = np.array([[1.0, 2.0], [(-1.0) ** k, 0.0], [0.0, 0.0]])
        state, cols = mem.update(state, np.full(3, k), _info(y, used), used)
    np.testing.assert_allclose(cols["innovation_whiteness"], [1.0, -1.0, 0.0])
    # after 4 steps of alternating signs in row 0 the window forgot the constant ones
    for k in range(6, 10):
        y = np.array([[(-1.0) ** k, 2.0], [1.0, 0.0], [0.0, 0.0]])
        state, cols = mem.update(state, np.full(3, k), _info(y, used), used)
    # filter 0, row 0: pairs +1 (the last constant one, then +1), -1, -1, -1; row 1: 4 pairs of +4
    assert cols["innovation_whiteness"][0] == pytest.approx((-2.0 + 16.0) / np.sqrt(20.0 * 20.0))
    # filter 1: -1 (the last alternating one, then +1), then +1, +1, +1
    assert cols["innovation_whiteness"][1] == pytest.approx(0.5)
    # a gap breaks the pairs: the step after a missing row pairs nothing for it
    gap = np.array([[False, True], [True, False], [False, False]])
    state, _ = mem.update(state, np.full(3, 10), _info(np.ones((3, 2)), gap), gap)
    assert state.pairs[0, 10 % 4].tolist() == [2.0, 1.0, 4.0]  # row 1 only: y=1 after y_last=2
    assert mem.values(mem.initial_state(2))["innovation_whiteness"].tolist() == [0.0, 0.0]


def test_averages_start_at_the_first_value_and_hold_through_gaps():
    mem = InnovationMemory(dt=0.5, m_max=1)
    state = mem.initial_state(1)
    used = np.array([[True]])
    state, cols = mem.update(state, np.array([0]), _info(np.array([[3.0]]), used), used)
    assert cols["innovation_avg"][0, 0] == pytest.approx(3.0)  # the first value, no pull to 0
    assert cols["log_nis_avg_1s"][0] == pytest.approx(np.log1p(9.0))
    none = np.array([[False]])
    held, cols2 = mem.update(state, np.array([1]), _info(np.array([[0.0]]), none), none)
    for k in ("log_nis_avg_1s", "log_nis_avg_10s", "innovation_avg"):
        np.testing.assert_array_equal(cols2[k], cols[k])  # no measurement: nothing learned
    np.testing.assert_allclose(mem.alphas, -np.expm1(-0.5 / np.array(TIME_CONSTANTS_S)))


def test_memory_columns_equal_a_hand_recursion_of_the_published_info():
    scenario = Scenario(outages=(Outage(10.0, 17.0),), duration=40.0)
    env = ToyEnv(task="fading", memory_features=True)
    obs, _ = env.reset(seed=2, options={"scenario": scenario})
    assert all((v == 0).all() for v in _cols(env, obs).values())
    dt = env.unwrapped.platform.dt
    a_nis = 1.0 - np.exp(-dt / np.array(TIME_CONSTANTS_S))
    a_row = 1.0 - np.exp(-dt / max(TIME_CONSTANTS_S))
    s_nis, w_nis = np.zeros(2), np.zeros(2)
    s_row, w_row = np.zeros(2), np.zeros(2)
    last_y, last_used = np.zeros(2), np.zeros(2, dtype=bool)
    pairs: list[tuple[float, float, float]] = []
    gaps = 0
    rng = np.random.default_rng(0)
    for _ in range(40):
        obs, _, term, trunc, info = env.step(rng.uniform(-1.0, 1.0, 1).astype(np.float32))
        used = np.repeat(info["gnss_available"], 2)
        gaps += not used.any()
        S = np.diag(info["innovation_cov"])
        y = np.clip(np.where(used, info["innovation"] / np.sqrt(S), 0.0), -10, 10)
        if info["n_meas"] > 0:
            x = np.log1p(info["nis"] / info["n_meas"])
            s_nis = (1 - a_nis) * s_nis + a_nis * x
            w_nis = (1 - a_nis) * w_nis + a_nis
        s_row = np.where(used, (1 - a_row) * s_row + a_row * y, s_row)
        w_row = np.where(used, (1 - a_row) * w_row + a_row, w_row)
        both = used & last_used
        pairs.append(((y * last_y)[both].sum(), (y * y)[both].sum(), (last_y * last_y)[both].sum()))
        last_y, last_used = y, used
        c, a, b = np.sum(pairs[-WINDOW_STEPS:], axis=0)
        want = {
            "log_nis_avg_1s": s_nis[0] / w_nis[0] if w_nis[0] > 0 else 0.0,
            "log_nis_avg_10s": s_nis[1] / w_nis[1] if w_nis[1] > 0 else 0.0,
            "innovation_avg": np.where(w_row > 0, s_row / np.where(w_row > 0, w_row, 1.0), 0.0),
            "innovation_whiteness": c / np.sqrt(a * b) if a * b > 0 else 0.0,
        }
        got = _cols(env, obs)
        for k, v in want.items():
            np.testing.assert_allclose(got[k], np.reshape(v, got[k].shape), rtol=1e-5, atol=1e-6, err_msg=k)
        if term or trunc:
            break
    assert gaps == 7 and w_nis[1] > 0 and abs(want["innovation_whiteness"]) > 0


def test_memory_restarts_with_each_episode():
    env = ToyEnv(task="noisescale", memory_features=True)
    env.reset(seed=0)
    for _ in range(10):
        obs, *_ = env.step(env.action_space.sample())
    assert any((v != 0).any() for v in _cols(env, obs).values())
    obs, _ = env.reset(seed=1)
    assert all((v == 0).all() for v in _cols(env, obs).values())
    assert all(not np.any(a) for a in env.unwrapped.core.memory)
    # a vector env resets one row's memory only
    venv = ToyVectorEnv(num_envs=3, task="fading", memory_features=True)
    venv.reset(seed=0)
    for _ in range(5):
        venv.step(np.zeros((3, 1), np.float32))
    core = venv.unwrapped.core
    before = core.memory
    core.reset(np.array([1]), [np.random.default_rng(9)], [None])
    for old, new in zip(before, core.memory, strict=True):
        np.testing.assert_array_equal(new[[0, 2]], old[[0, 2]])
        assert not np.any(new[1])


@pytest.mark.parametrize("task", ["fading", "noisescale", "mixture"])
def test_vector_sub_env_equals_single_env_across_autoresets_with_memory(task):
    """Sub-env i continues as the single env reset() without a seed; memory included."""
    B, seed, steps = 3, 5, 25
    kwargs = {"memory_features": True, "episode_steps": 7}
    if task == "mixture":
        kwargs["per_row"] = True
    venv = ToyVectorEnv(num_envs=B, task=task, **kwargs)
    singles = [ToyEnv(task=task, **kwargs) for _ in range(B)]
    vobs, _ = venv.reset(seed=seed)
    for i, e in enumerate(singles):
        np.testing.assert_array_equal(vobs[i], e.reset(seed=seed + i)[0])
    venv.action_space.seed(1)
    done = np.zeros(B, dtype=bool)
    resets = 0
    for _ in range(steps):
        a = venv.action_space.sample()
        vobs, *_ = venv.step(a)
        for i, e in enumerate(singles):
            if done[i]:
                o, _ = e.reset()
                done[i] = False
                resets += 1
            else:
                o, _, term, trunc, _ = e.step(a[i])
                done[i] = term or trunc
            np.testing.assert_array_equal(vobs[i], o)
    assert resets >= 2 * B


def test_snapshot_restore_and_the_episode_stepper_keep_the_memory():
    venv = ToyVectorEnv(num_envs=2, task="fading", memory_features=True, episode_steps=12)
    venv.reset(seed=0)
    a = np.zeros((2, 1), np.float32)
    for _ in range(3):
        venv.step(a)
    core = venv.unwrapped.core
    snap = core.snapshot(np.arange(2))
    assert "memory" in snap and "memory" in core.snapshot_rows(snap, np.array([1]))
    kept = core.memory
    for _ in range(4):
        venv.step(a)
    core.restore(np.array([0]), core.snapshot_rows(snap, np.array([0])))
    for was, now in zip(kept, core.memory, strict=True):
        np.testing.assert_array_equal(now[0], was[0])
    # the stepper: finished rows are put back to the memory at its start
    stepper = venv.unwrapped.episode_stepper()
    start = core.memory
    finished = np.zeros(2, dtype=bool)
    for _ in range(12):
        *_, term, trunc, _ = stepper.step(a)
        done = term | trunc
        for was, now in zip(start, core.memory, strict=True):
            np.testing.assert_array_equal(now[done], was[done])
        finished |= done
    assert finished.all()


def test_a_pickled_core_continues_with_its_memory():
    env = ToyEnv(task="fading", memory_features=True)
    env.reset(seed=3)
    for _ in range(5):
        env.step(np.array([0.0], np.float32))
    copy = pickle.loads(pickle.dumps(env))
    for _ in range(5):
        o1, *_ = env.step(np.array([0.3], np.float32))
        o2, *_ = copy.step(np.array([0.3], np.float32))
        np.testing.assert_array_equal(o1, o2)
    state = copy.unwrapped.core.__getstate__()  # a core pickled before the memory features
    del state["memory"], state["memory_model"]
    core = type(copy.unwrapped.core).__new__(type(copy.unwrapped.core))
    core.__setstate__(state)
    assert core.memory is None and core.memory_model is None


def test_without_the_argument_nothing_changes_and_with_it_columns_are_appended():
    plain = gym.make("navgym/Robot2dFading-v1", episode_steps=30)
    core = plain.unwrapped.core
    assert core.memory is None and core.memory_model is None
    assert not set(MEMORY_COLUMNS) & set(core.obs_features.names)
    with_memory = gym.make("navgym/Robot2dFading-v1", episode_steps=30, memory_features=True)
    n = core.obs_features.dim
    names = with_memory.unwrapped.core.obs_features.names
    assert names[: len(core.obs_features.names)] == core.obs_features.names
    assert names[len(core.obs_features.names) :] == list(MEMORY_COLUMNS)
    m_max = with_memory.unwrapped.platform.m_max
    assert with_memory.observation_space.shape == (n + 3 + m_max,)
    o1, _ = plain.reset(seed=0)
    o2, _ = with_memory.reset(seed=0)
    np.testing.assert_array_equal(o1, o2[:n])
    for _ in range(10):
        o1, r1, *_ = plain.step(np.array([0.2], np.float32))
        o2, r2, *_ = with_memory.step(np.array([0.2], np.float32))
        np.testing.assert_array_equal(o1, o2[:n])
        assert r1 == r2
    assert "memory" not in core.snapshot(np.arange(1))
    assert with_memory.observation_space.contains(o2)
