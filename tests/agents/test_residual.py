"""Residual agents over a classical baseline (``residual`` run key, :mod:`agents.training.residual`)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

from agents.baselines import make_baseline
from agents.evaluation.cli import parse_policies
from agents.evaluation.runner import evaluate, make_vector_env
from agents.policy_runner import PredictRunner
from agents.seeds import seeds
from agents.training import AgentLoadError, load_agent, load_config, train
from agents.training.config import residual_of, split_entry
from agents.training.residual import (
    ResidualState,
    ResidualVecEnv,
    combine,
    resolve_residual,
)
from agents.training.train import make_vec_env
from navgym.envs.sb3 import NavSB3VecEnv

ENV = "navgym/Robot2dNoiseScale-v2"
PARAMS = {"b": 0.8, "beta": 1.5}
#: Short episodes that end at different steps per row (divergence at 3 m) and autoreset.
RAGGED = {"episode_steps": 40, "max_episode_steps": 40, "divergence_m": 3.0}
RESIDUAL = {"baseline": "sage_husa", "params": PARAMS, "scale": 0.5, "observe_base": True}
#: A tiny residual PPO entry (one rollout of 2 x 64 steps).
TINY = {
    "n_envs": 2,
    "n_timesteps": 128,
    "policy": "MlpPolicy",
    "normalize": {"norm_obs": True, "norm_reward": True},
    "env_kwargs": {"eval_info": False, **RAGGED},
    "n_steps": 64,
    "batch_size": 64,
    "n_epochs": 1,
    "policy_kwargs": {"net_arch": [16]},
    "residual": RESIDUAL,
    "checkpoint_freq": 10_000,
}


def spec_of(value=None, env_id=ENV, env_kwargs=None):
    env = make_vector_env(env_id, 1, env_kwargs)
    try:
        return resolve_residual(RESIDUAL if value is None else value, env_id, env)
    finally:
        env.close()


# --- configuration --------------------------------------------------------------------------


def test_residual_is_a_run_key_with_defaults():
    run, hyper = split_entry({"n_envs": 2, "gamma": 0.9, "residual": {"baseline": "sage_husa"}})
    assert hyper == {"gamma": 0.9}
    assert run["residual"] == {"baseline": "sage_husa", "params": "tuned", "scale": 0.5, "observe_base": True}
    assert residual_of(None) is None and residual_of(False) is None


@pytest.mark.parametrize(
    ("value", "key"),
    [
        ("sage_husa", "residual must be a mapping"),
        ({"params": "tuned"}, "residual.baseline"),
        ({"baseline": 3}, "residual.baseline"),
        ({"baseline": "sage_husa", "scale": 0}, "residual.scale"),
        ({"baseline": "sage_husa", "scale": -0.5}, "residual.scale"),
        ({"baseline": "sage_husa", "scale": "0.5"}, "residual.scale"),
        ({"baseline": "sage_husa", "scale": float("nan")}, "residual.scale"),
        ({"baseline": "sage_husa", "observe_base": "yes"}, "residual.observe_base"),
        ({"baseline": "sage_husa", "params": "best"}, "residual.params"),
        ({"baseline": "sage_husa", "params": {"b": "0.8"}}, r"residual.params.b"),
        ({"baseline": "sage_husa", "params": {"b": True}}, r"residual.params.b"),
        ({"baseline": "sage_husa", "gain": 2}, r"unknown keys \['gain'\]"),
    ],
)
def test_bad_residual_fields_are_rejected_naming_the_key(value, key):
    with pytest.raises(ValueError, match=key):
        split_entry({"n_envs": 2, "residual": value})


def test_resolving_checks_the_baseline_and_its_parameters_against_the_env():
    spec = spec_of()
    assert spec.baseline == "sage_husa" and spec.task == "NoiseScale" and spec.params_source == "explicit"
    assert spec.params == PARAMS and spec.scale == 0.5 and spec.observe_base
    with pytest.raises(ValueError, match=r"residual.baseline: no baseline 'chi_square' for the NoiseScale"):
        spec_of({"baseline": "chi_square", "params": {}})
    with pytest.raises(ValueError, match=r"residual.params: \['window'\] are not parameters of sage_husa"):
        spec_of({"baseline": "sage_husa", "params": {"window": 5.0}})
    # the per-row Mixture v2 ids use the RowMixture baselines
    row = spec_of({"baseline": "chi_square", "params": {}}, "navgym/Robot2dMixture-v2")
    assert row.task == "RowMixture" and set(row.params) >= {"alpha", "eps_low", "decay"}


def test_a_discrete_task_rejects_a_residual():
    with pytest.raises(ValueError, match=r"residual: .*Discrete.*Box action only"):
        spec_of({"baseline": "ess", "params": {}}, "navgym/Robot2dResample-v2")


def test_tuned_params_come_from_the_tuned_file_or_a_clear_error(tmp_path, monkeypatch):
    import agents.baselines.registry as registry

    monkeypatch.setattr(registry, "TUNED_DIR", tmp_path)
    tuned = {**RESIDUAL, "params": "tuned"}
    want = rf"does not exist; run `navgym tune --env {ENV} --episodes 256 --out "
    with pytest.raises(ValueError, match=want):
        spec_of(tuned)
    entry = {"params": {"b": 0.9, "beta": 2.0}}
    (tmp_path / "Robot2dNoiseScale-v2.json").write_text(
        json.dumps({"env_id": ENV, "baselines": {"iae": {"params": {"window": 5.0, "gain": 1.0}}}})
    )
    with pytest.raises(ValueError, match="has no entry for sage_husa"):
        spec_of(tuned)
    (tmp_path / "Robot2dNoiseScale-v2.json").write_text(
        json.dumps({"env_id": ENV, "baselines": {"sage_husa": entry}})
    )
    spec = spec_of(tuned)
    assert spec.params == entry["params"] and spec.params_source.startswith("tuned:")


def test_train_rejects_a_bad_residual_before_writing_anything(tmp_path):
    with pytest.raises(ValueError, match="residual.scale"):
        train(
            ENV, "ppo", dict(TINY, residual={**RESIDUAL, "scale": 0}), out_dir=tmp_path / "a", progress=False
        )
    with pytest.raises(ValueError, match="residual.baseline"):
        train(ENV, "ppo", dict(TINY, residual={"baseline": "nope"}), out_dir=tmp_path / "b", progress=False)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.parametrize(
    ("env_id", "baseline"), [(ENV, "sage_husa"), ("navgym/Robot2dMixture-v2", "chi_square")]
)
def test_shipped_residual_entries(env_id, baseline):
    entry = load_config(env_id, "ppo")
    run, _ = split_entry(entry)
    assert run["residual"]["baseline"] == baseline and run["residual"]["params"] == "tuned"
    spec = spec_of(run["residual"], env_id)  # the tuned file is committed
    assert spec.params_source == f"tuned: agents/baselines/tuned/{env_id.split('/')[-1]}.json"


# --- the vector-env wrapper -----------------------------------------------------------------


@pytest.mark.parametrize("observe_base", [True, False])
def test_observation_and_action_spaces(observe_base):
    spec = spec_of({**RESIDUAL, "observe_base": observe_base})
    raw = NavSB3VecEnv(ENV, num_envs=3, seed=5, **RAGGED)
    venv = ResidualVecEnv(raw, spec)
    d, n = raw.observation_space.shape[0], raw.action_space.shape[0]
    assert venv.action_space.shape == (n,) and (venv.action_space.low == -1).all()
    width = d + n if observe_base else d
    assert venv.observation_space.shape == (width,)
    if observe_base:
        np.testing.assert_array_equal(venv.observation_space.low[d:], raw.action_space.low)
        np.testing.assert_array_equal(venv.observation_space.low[:d], raw.observation_space.low)
    obs = venv.reset()
    assert obs.shape == (3, width) and obs.dtype == np.float32
    assert venv.observation_space.contains(obs[0])


def test_combine_clips_and_keeps_a_zero_residual_exact():
    from gymnasium import spaces

    box = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    base = np.array([[0.3, -0.9], [1.0, -1.0]], dtype=np.float32)
    np.testing.assert_array_equal(combine(base, np.zeros((2, 2)), 0.5, box), base)
    out = combine(base, np.array([[1.0, -1.0], [1.0, 1.0]]), 0.5, box)
    np.testing.assert_allclose(out, [[0.8, -1.0], [1.0, -0.5]])
    assert out.dtype == np.float32


def run_baseline_alone(n, seed, kwargs, steps):
    """Actions and observations of the baseline alone on the SB3 adapter (memory reset on done)."""
    env = NavSB3VecEnv(ENV, num_envs=n, seed=seed, **kwargs)
    runner = PredictRunner(make_baseline(env, "sage_husa", **PARAMS))
    obs = env.reset()
    runner.reset()
    acts, obss, dones = [], [obs], []
    for _ in range(steps):
        a = runner.act(obs)
        obs, _, done, _ = env.step(a)
        runner.reset(done)
        acts.append(a)
        obss.append(obs)
        dones.append(done)
    return np.array(acts), np.array(obss), np.array(dones)


def test_zero_residual_is_the_baseline_exactly_across_autoresets():
    n, steps = 4, 120
    ref_a, ref_obs, dones = run_baseline_alone(n, 11, RAGGED, steps)
    ends = [np.flatnonzero(dones[:, i]) for i in range(n)]
    assert len({tuple(e) for e in ends}) > 1, "rows must end at different steps"
    assert all(len(e) >= 2 for e in ends), "every row autoresets"
    venv = ResidualVecEnv(NavSB3VecEnv(ENV, num_envs=n, seed=11, **RAGGED), spec_of())
    obs = venv.reset()
    for t in range(steps):
        np.testing.assert_array_equal(obs[:, :-2], ref_obs[t])
        obs, _, done, infos = venv.step(np.zeros((n, 2), dtype=np.float32))
        np.testing.assert_array_equal(venv.last_actions, ref_a[t])
        np.testing.assert_array_equal(done, dones[t])
        # the observed base action is the one applied at the next step (zero residual)
        if t + 1 < steps:
            np.testing.assert_array_equal(obs[:, -2:], ref_a[t + 1])
        for i in np.flatnonzero(done):
            assert infos[i]["terminal_observation"].shape == (25,)


def test_terminal_observations_carry_the_finished_episodes_base_action():
    spec = spec_of()
    venv = ResidualVecEnv(NavSB3VecEnv(ENV, num_envs=4, seed=11, **RAGGED), spec)
    probe = make_baseline(NavSB3VecEnv(ENV, num_envs=4, seed=11, **RAGGED), "sage_husa", **PARAMS)
    venv.reset()
    checked = 0
    for _ in range(30):
        state = venv._state
        _, _, done, infos = venv.step(np.zeros((4, 2), dtype=np.float32))
        for i in np.flatnonzero(done):
            term = infos[i]["terminal_observation"]
            mem = {k: v[i : i + 1] for k, v in state.items()}
            a, _ = probe.predict(term[None, :-2], state=mem, episode_start=np.zeros(1, dtype=bool))
            np.testing.assert_array_equal(term[-2:], a[0])
            checked += 1
    assert checked >= 2


# --- trained agents: save, load, evaluate ---------------------------------------------------


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("residual") / "ppo"
    return train(ENV, "ppo", TINY, seed=0, out_dir=out, progress=False, tensorboard=False)


def test_manifest_config_and_meta_record_the_residual(tiny_run):
    manifest = json.loads((tiny_run / "manifest.json").read_text())
    rec = manifest["residual"]
    assert {k: rec[k] for k in ("baseline", "params", "scale", "observe_base", "task")} == {
        **RESIDUAL,
        "task": "NoiseScale",
    }
    assert rec["params_source"] == "explicit" and rec["env_observation_space"]["shape"] == [23]
    assert manifest["observation_space"]["shape"] == [25] and manifest["action_space"]["shape"] == [2]
    cfg = yaml.safe_load((tiny_run / "config.yml").read_text())
    assert cfg["residual"] == RESIDUAL
    assert json.loads((tiny_run / "meta.json").read_text())["residual"]["baseline"] == "sage_husa"


def test_loaded_agent_takes_raw_observations_and_carries_the_baselines_memory(tiny_run):
    agent = load_agent(tiny_run, env=ENV)
    assert agent.observation_space.shape == (23,) and agent.frame_space.shape == (25,)
    assert agent.has_memory and agent.residual.spec.params == PARAMS
    env = NavSB3VecEnv(ENV, num_envs=3, seed=2, **RAGGED)
    obs = env.reset()
    a, state = agent.predict(obs)
    assert a.shape == (3, 2) and isinstance(state, ResidualState) and set(state.base) >= {"r"}
    a1, s1 = agent.predict(obs[0])
    np.testing.assert_array_equal(a1, a[0])
    with pytest.raises(AgentLoadError, match="observation"):
        load_agent(tiny_run, env="navgym/Robot2dFading-v2")


def zero_residual(agent):
    import torch

    with torch.no_grad():
        agent.model.policy.action_net.weight.zero_()
        agent.model.policy.action_net.bias.zero_()
    return agent


def test_zero_residual_agent_acts_as_the_baseline_through_the_policy_runner(tiny_run):
    agent = zero_residual(load_agent(tiny_run))
    n, steps = 4, 120
    ref_a, _, dones = run_baseline_alone(n, 11, RAGGED, steps)
    env = NavSB3VecEnv(ENV, num_envs=n, seed=11, **RAGGED)
    runner = PredictRunner(agent)
    obs = env.reset()
    runner.reset()
    for t in range(steps):
        a = runner.act(obs)
        np.testing.assert_array_equal(a, ref_a[t])
        obs, _, done, _ = env.step(a)
        runner.reset(done)
    assert dones.any(axis=0).all()


def test_saved_agent_acts_as_the_training_env_stack(tiny_run):
    """load_agent's predict (raw obs) == the model acting through train's wrapper chain."""
    agent = load_agent(tiny_run)
    chain = make_vec_env(
        ENV,
        3,
        21,
        RAGGED,
        normalize_path=tiny_run / "vecnormalize.npz",
        training=False,
        residual=agent.residual.spec,
    )
    res_env = chain.venv.venv  # VecNormalize(VecMonitor(ResidualVecEnv))
    assert isinstance(res_env, ResidualVecEnv)
    raw = NavSB3VecEnv(ENV, num_envs=3, seed=21, **RAGGED)
    runner = PredictRunner(agent)
    obs_chain, obs_raw = chain.reset(), raw.reset()
    runner.reset()
    ended = 0
    for _ in range(60):
        a_res, _ = agent.model.predict(obs_chain, deterministic=True)
        obs_chain, _, done_chain, _ = chain.step(a_res)
        a = runner.act(obs_raw)
        np.testing.assert_allclose(a, res_env.last_actions, atol=1e-6)
        obs_raw, _, done, _ = raw.step(a)
        runner.reset(done)
        np.testing.assert_array_equal(done, done_chain)
        ended += int(done.sum())
    assert ended > 0


def test_config_and_manifest_must_agree_on_the_residual(tiny_run, tmp_path):
    import shutil

    from agents.training.loading import read_manifest, sha256_file

    bad = tmp_path / "bad"
    shutil.copytree(tiny_run, bad)
    cfg = yaml.safe_load((bad / "config.yml").read_text())
    cfg["residual"]["scale"] = 0.25
    (bad / "config.yml").write_text(yaml.safe_dump(cfg))
    m = read_manifest(bad)
    m["files"]["config.yml"] = sha256_file(bad / "config.yml")
    (bad / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(AgentLoadError, match="residual"):
        load_agent(bad)


@pytest.mark.slow
def test_tiny_training_run_saves_loads_and_evaluates(tmp_path):
    cfg = dict(TINY, n_timesteps=512, env_kwargs={"eval_info": False})
    out = train(ENV, "ppo", cfg, seed=1, out_dir=tmp_path / "run", progress=False, tensorboard=False)
    pols = parse_policies(["sage_husa", f"residual=ppo:{out}"], ENV)
    pols = {"sage_husa": make_baseline(ENV, "sage_husa", **PARAMS), "residual": pols["residual"]}
    res = evaluate(ENV, pols, seeds("eval", 2), n_boot=50, progress=False)
    for name in pols:
        assert np.isfinite(res.episodes[name]["rmse_m"]).all()
    assert res.row("residual")["rmse_m"] > 0


@pytest.mark.parametrize(
    ("algo", "extra"),
    [
        ("sac", {"learning_starts": 64, "batch_size": 32, "buffer_size": 1000, "train_freq": 8}),
        ("ppo_lstm", {"policy": "MlpLstmPolicy", "frame_stack": 2, "policy_kwargs": {"lstm_hidden_size": 8}}),
        ("ppo", {"frame_stack": 3, "residual": {**RESIDUAL, "observe_base": False}}),
    ],
)
def test_other_algorithms_and_frame_stack_round_trip(tmp_path, algo, extra):
    cfg = dict(TINY, **extra)
    if algo == "sac":
        for k in ("n_steps", "n_epochs"):
            cfg.pop(k)
        cfg["policy_kwargs"] = {"net_arch": [16]}
    out = train(ENV, algo, cfg, seed=0, out_dir=tmp_path / algo, progress=False, tensorboard=False)
    agent = load_agent(out, env=ENV)
    fs = int(cfg.get("frame_stack", 1))
    width = 23 + (2 if cfg["residual"]["observe_base"] else 0)
    assert agent.frame_stack == fs and agent.model.observation_space.shape == (width * fs,)
    chain = make_vec_env(
        ENV,
        3,
        21,
        RAGGED,
        normalize_path=out / "vecnormalize.npz",
        training=False,
        frame_stack=fs,
        residual=agent.residual.spec,
    )
    from agents.training.residual import find_residual_env

    res_env = find_residual_env(chain)
    raw = NavSB3VecEnv(ENV, num_envs=3, seed=21, **RAGGED)
    runner = PredictRunner(agent)
    obs_chain, obs_raw = chain.reset(), raw.reset()
    runner.reset()
    state, starts = None, np.ones(3, dtype=bool)
    for _ in range(50):
        a_res, state = agent.model.predict(obs_chain, state=state, episode_start=starts, deterministic=True)
        obs_chain, _, starts, _ = chain.step(a_res)
        a = runner.act(obs_raw)
        np.testing.assert_allclose(a, res_env.last_actions, atol=1e-6)
        obs_raw, _, done, _ = raw.step(a)
        runner.reset(done)


def test_a_residual_run_resumes_with_the_baseline_it_recorded(tmp_path):
    out = train(
        ENV,
        "ppo",
        dict(TINY, checkpoint_freq=128),
        seed=0,
        out_dir=tmp_path / "r",
        progress=False,
        tensorboard=False,
    )
    assert (out / "checkpoints" / "step_128" / "manifest.json").is_file()
    ck = json.loads((out / "checkpoints" / "step_128" / "manifest.json").read_text())
    assert ck["residual"]["params"] == PARAMS
    train(
        ENV,
        "ppo",
        None,
        seed=0,
        total_timesteps=256,
        out_dir=out,
        resume=True,
        progress=False,
        tensorboard=False,
    )
    agent = load_agent(out)
    assert agent.model.num_timesteps == 256 and agent.residual.spec.params == PARAMS
