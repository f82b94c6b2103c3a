"""The per-row shared policy (:mod:`agents.training.row_policy`) and the supervised residual base."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

from gymnasium import spaces  # noqa: E402

from agents.evaluation.runner import make_vector_env  # noqa: E402
from agents.supervised.files import load_policy  # noqa: E402
from agents.training.config import residual_of  # noqa: E402
from agents.training.residual import ResidualVecEnv, resolve_residual  # noqa: E402
from agents.training.row_policy import RowSharedPolicy, row_layout  # noqa: E402
from navgym.envs.base import navigation_env  # noqa: E402
from navgym.envs.sb3 import NavSB3VecEnv  # noqa: E402
from tests.agents.training.tiny import tiny_row_scale_entry  # noqa: E402

ENV = "navgym/Robot2dRowScale-v3"
SUPERVISED = "agents/zoo/Robot2dRowScale-v3-supervised"
BASE = {"baseline": "supervised", "agent": SUPERVISED, "scale": 0.5, "observe_base": True}


@pytest.fixture(scope="module")
def features():
    env = make_vector_env(ENV, 1)
    nav = navigation_env(env)
    yield nav.observation_features, nav.task.m_max
    env.close()


def test_row_layout_gives_each_row_its_own_columns_and_covers_every_column_once(features):
    f, m = features
    lay = row_layout(f, m, observe_base=True)
    rows, glob = np.asarray(lay["row_columns"]), lay["global_columns"]
    assert rows.shape[0] == m
    every = np.concatenate([rows.ravel(), glob])
    assert sorted(every.tolist()) == list(range(f.dim + m + 1))
    for name in ("innovation", "row_cn0", "row_reported_sigma", "log_row_scale", "innovation_avg"):
        s = f.index(name)
        np.testing.assert_array_equal(rows[:, list(rows[0]).index(s.start)], np.arange(s.start, s.start + m))
    prev = f.index("previous_action")
    assert prev.stop - 1 in glob  # the process-noise scale's previous action is global
    np.testing.assert_array_equal(rows[:, -1], f.dim + np.arange(m))  # each row's base action
    assert glob[-1] == f.dim + m
    assert f.index("log_nis").start in glob and f.index("imu_activity").start in glob


def test_row_layout_refuses_an_observation_without_per_row_features(features):
    f, m = features
    with pytest.raises(ValueError, match="no per-row feature of width m=7"):
        row_layout(f, 7)


def _policy(m=4, f_r=3, g=5, hidden=16):
    d = m * f_r + g
    rows = [[i * f_r + j for j in range(f_r)] for i in range(m)]
    glob = list(range(m * f_r, d))
    obs = spaces.Box(-np.inf, np.inf, (d,), np.float32)
    act = spaces.Box(-1.0, 1.0, (m + 1,), np.float32)
    torch.manual_seed(0)
    pol = RowSharedPolicy(obs, act, lambda _: 1e-3, row_columns=rows, global_columns=glob, hidden=hidden)
    return pol, m, f_r, d


def _mean(pol, x):
    with torch.no_grad():
        return pol.get_distribution(torch.as_tensor(x)).distribution.mean.numpy()


def test_permuting_the_rows_permutes_the_row_actions_and_keeps_the_global_one():
    pol, m, f_r, d = _policy()
    # a trained-like head: the orthogonal init's gain 0.01 makes means tiny, so scale them up
    with torch.no_grad():
        for p in pol.action_net.parameters():
            p.mul_(100.0)
    x = np.random.default_rng(1).normal(size=(3, d)).astype(np.float32)
    perm = np.array([2, 0, 3, 1])
    xp = x.copy()
    xp[:, : m * f_r] = x[:, : m * f_r].reshape(3, m, f_r)[:, perm].reshape(3, -1)
    a, ap = _mean(pol, x), _mean(pol, xp)
    assert a.shape == (3, m + 1)
    np.testing.assert_allclose(ap[:, :m], a[:, perm], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(ap[:, m], a[:, m], rtol=1e-5, atol=1e-6)
    assert np.ptp(a[:, :m]) > 1e-3  # rows with different inputs get different actions


def test_the_row_network_is_f_of_the_row_and_the_global_columns():
    """The split first layer computes the row network on ``[x_i, g]`` (module docstring)."""
    pol, m, f_r, d = _policy()
    ext = pol.mlp_extractor
    x = torch.as_tensor(np.random.default_rng(4).normal(size=(6, d)).astype(np.float32))
    with torch.no_grad():
        latent = ext.forward_actor(x)
        g = x[:, m * f_r :]
        for i in range(m):
            row_in = torch.cat([x[:, i * f_r : (i + 1) * f_r], g], dim=-1)
            want = ext.row_net(row_in)
            got = latent[:, i * ext.hidden : (i + 1) * ext.hidden]
            np.testing.assert_allclose(got.numpy(), want.numpy(), rtol=1e-5, atol=1e-6)


def test_the_action_head_starts_near_zero_for_a_residual_warm_start():
    pol, _, _, d = _policy()
    x = np.random.default_rng(2).normal(size=(64, d)).astype(np.float32)
    assert np.abs(_mean(pol, x)).max() < 0.1


def test_the_policy_needs_an_action_of_one_entry_per_row_and_one_more():
    obs = spaces.Box(-1.0, 1.0, (10,), np.float32)
    with pytest.raises(ValueError, match="action of m \\+ 1 entries"):
        RowSharedPolicy(obs, spaces.Box(-1, 1, (3,), np.float32), lambda _: 1e-3, [[0], [1], [2]], [3])


def test_the_policy_saves_its_layout_with_its_constructor_parameters():
    pol, m, f_r, _ = _policy()
    data = pol._get_constructor_parameters()
    assert data["row_columns"] == pol.row_columns and len(data["row_columns"]) == m
    assert data["hidden"] == 16


def test_residual_agent_key_goes_with_the_supervised_baseline_only():
    assert residual_of(BASE)["agent"] == SUPERVISED and residual_of(BASE)["params"] == {}
    assert "agent" not in residual_of({"baseline": "sage_husa"})
    with pytest.raises(ValueError, match="residual.agent"):
        residual_of({"baseline": "supervised"})
    with pytest.raises(ValueError, match="residual.agent"):
        residual_of({"baseline": "row_iae", "agent": SUPERVISED})
    with pytest.raises(ValueError, match="takes no parameters"):
        residual_of({**BASE, "params": {"b": 0.5}})


def test_a_supervised_base_of_another_id_or_a_missing_folder_is_refused():
    env = make_vector_env(ENV, 1)
    try:
        with pytest.raises(
            ValueError, match="residual.agent: .*QuadrotorRowScale-v3.*not navgym/Robot2dRowScale"
        ):
            resolve_residual({**BASE, "agent": "agents/zoo/QuadrotorRowScale-v3-supervised"}, ENV, env)
        with pytest.raises(ValueError, match="residual.agent: .*missing"):
            resolve_residual({**BASE, "agent": "no/such/folder"}, ENV, env)
    finally:
        env.close()


def test_zero_residual_over_the_supervised_agent_acts_as_the_supervised_agent():
    n, steps = 3, 40
    env = make_vector_env(ENV, 1)
    spec = resolve_residual(BASE, ENV, env)
    env.close()
    venv = ResidualVecEnv(NavSB3VecEnv(ENV, num_envs=n, seed=5), spec)
    alone = NavSB3VecEnv(ENV, num_envs=n, seed=5)
    sup = load_policy(SUPERVISED, alone)
    obs, ref = venv.reset(), alone.reset()
    state, start = None, np.ones(n, dtype=bool)
    m1 = alone.action_space.shape[0]
    for _ in range(steps):
        a, state = sup.predict(ref, state=state, episode_start=start)
        np.testing.assert_array_equal(obs[:, -m1:], a)  # each row sees its base action
        obs, _, done, _ = venv.step(np.zeros((n, m1), dtype=np.float32))
        np.testing.assert_array_equal(venv.last_actions, a)
        ref, _, start, _ = alone.step(a)
        np.testing.assert_array_equal(done, start)
    venv.close()
    alone.close()


def test_a_row_shared_residual_agent_trains_saves_and_loads_with_its_layout(tmp_path):
    from agents.training import load_agent, train

    entry = tiny_row_scale_entry(checkpoint_freq=10_000)
    out = train(ENV, "ppo", config=entry, seed=3, out_dir=tmp_path / "run", progress=False)
    agent = load_agent(out)
    assert isinstance(agent.model.policy, RowSharedPolicy)
    assert agent.residual is not None and agent.residual.spec.agent == SUPERVISED
    saved = (out / "config.yml").read_text()
    assert "row_columns" in saved and "global_columns" in saved
    env = make_vector_env(ENV, 2, entry["env_kwargs"])
    obs, _ = env.reset(seed=[1, 2])
    action, _ = agent.predict(obs, episode_start=np.ones(2, dtype=bool))
    assert action.shape == (2, env.single_action_space.shape[0]) and np.isfinite(action).all()
    env.close()
