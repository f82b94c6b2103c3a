"""Policies with memory: RecurrentPPO (``ppo_lstm``), frame stacking, and the PolicyRunner seam."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")
pytest.importorskip("sb3_contrib")
pytest.importorskip("torch")

from agents.evaluation.cli import parse_policies
from agents.evaluation.runner import evaluate, make_vector_env, rollout
from agents.policy_runner import (
    CallableRunner,
    FrameStack,
    PolicyRunner,
    PredictRunner,
    StackedState,
)
from agents.seeds import seeds
from agents.training import AgentLoadError, load_agent, load_config, train
from agents.training.config import (
    build_hyperparameters,
    check_algo_entry,
    split_entry,
)
from agents.training.loading import space_from_dict, write_manifest
from agents.training.sanity import agent_policy, as_runner, run_episodes
from agents.training.train import make_vec_env

ENV = "navgym/Robot2dNoiseScale-v2"
SHORT = {"episode_steps": 40, "max_episode_steps": 40}
V2_IDS = (
    "navgym/Robot2dFading-v2",
    "navgym/Robot2dNoiseScale-v2",
    "navgym/Robot2dMixture-v2",
    "navgym/Robot2dResample-v2",
)
#: Keys a run writes into its config.yml; a shipped configuration holds none of them.
BOOKKEEPING = ("env_id", "algo", "seed", "env_seed", "meta")
#: A tiny RecurrentPPO entry: 2 short episodes in parallel, an 8-unit LSTM.
TINY_LSTM = {
    "n_envs": 2,
    "n_timesteps": 256,
    "policy": "MlpLstmPolicy",
    "normalize": {"norm_obs": True, "norm_reward": True},
    "env_kwargs": {"eval_info": False, **SHORT},
    "n_steps": 64,
    "batch_size": 64,
    "n_epochs": 2,
    "gamma": 0.95,
    "policy_kwargs": {"net_arch": [16], "lstm_hidden_size": 8, "n_lstm_layers": 1},
    "checkpoint_freq": 128,
}
#: A tiny PPO entry stacking 3 observations.
TINY_STACK = {
    "n_envs": 2,
    "n_timesteps": 256,
    "policy": "MlpPolicy",
    "normalize": {"norm_obs": True, "norm_reward": True},
    "env_kwargs": {"eval_info": False, **SHORT},
    "frame_stack": 3,
    "n_steps": 64,
    "batch_size": 64,
    "n_epochs": 2,
    "policy_kwargs": {"net_arch": [16]},
    "checkpoint_freq": 10_000,
}


# --- configuration --------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", V2_IDS)
def test_shipped_ppo_lstm_entries_parse(env_id):
    entry = load_config(env_id, "ppo_lstm")
    assert not set(BOOKKEEPING) & set(entry), "configs hold hyperparameters and run keys only"
    run, hyper = split_entry(entry)
    check_algo_entry("ppo_lstm", run, hyper)
    assert run["n_envs"] == 16 and run["normalize"] == {"norm_obs": True, "norm_reward": True}
    assert run["env_kwargs"] == {"eval_info": False}
    kw = build_hyperparameters(hyper)
    assert kw["n_steps"] == 128 and kw["batch_size"] == 512 and 0.96 <= kw["gamma"] <= 0.99
    assert kw["policy_kwargs"]["lstm_hidden_size"] == 64


@pytest.mark.parametrize("bad", [0, -2, 2.5, "4", True, [4]])
def test_bad_frame_stack_is_rejected_naming_the_key(bad):
    with pytest.raises(ValueError, match="frame_stack"):
        split_entry({"n_envs": 2, "frame_stack": bad})


def test_frame_stack_is_a_run_key():
    run, hyper = split_entry({"n_envs": 2, "frame_stack": 4, "gamma": 0.9})
    assert run == {"n_envs": 2, "frame_stack": 4} and hyper == {"gamma": 0.9}


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"lstm_hidden_size": 0}, "lstm_hidden_size"),
        ({"lstm_hidden_size": "64"}, "lstm_hidden_size"),
        ({"n_lstm_layers": 1.5}, "n_lstm_layers"),
        ({"shared_lstm": "yes"}, "shared_lstm"),
        ({"enable_critic_lstm": 1}, "enable_critic_lstm"),
        ({"shared_lstm": True}, "shared_lstm"),  # the critic's own LSTM is on by default
    ],
)
def test_bad_lstm_options_are_rejected_naming_the_key(kwargs, key):
    with pytest.raises(ValueError, match=key):
        build_hyperparameters({"policy_kwargs": kwargs})


def test_lstm_options_pass_through():
    pk = {"lstm_hidden_size": 32, "n_lstm_layers": 2, "shared_lstm": True, "enable_critic_lstm": False}
    assert (
        build_hyperparameters({"policy_kwargs": dict(pk, activation_fn="tanh")})["policy_kwargs"][
            "lstm_hidden_size"
        ]
        == 32
    )


def test_policy_and_lstm_options_must_fit_the_algorithm():
    with pytest.raises(ValueError, match="lstm_hidden_size"):
        check_algo_entry("ppo", {}, {"policy_kwargs": {"lstm_hidden_size": 8}})
    with pytest.raises(ValueError, match="ppo_lstm"):
        check_algo_entry("ppo", {"policy": "MlpLstmPolicy"}, {})
    with pytest.raises(ValueError, match="policy"):
        check_algo_entry("ppo_lstm", {"policy": "MlpPolicy"}, {})
    check_algo_entry("ppo_lstm", {}, {})  # MlpLstmPolicy by default


def test_train_rejects_a_bad_frame_stack_before_building_anything(tmp_path):
    with pytest.raises(ValueError, match="frame_stack"):
        train(ENV, "ppo", config=dict(TINY_STACK, frame_stack=0), out_dir=tmp_path / "x", progress=False)
    assert not (tmp_path / "x").exists()


# --- the PolicyRunner seam ------------------------------------------------------------------


class StepCounter:
    """A fake recurrent policy: its state counts each row's steps since its episode started, and
    its action is that count (so a state carried across an episode start shows in the actions)."""

    def __init__(self):
        self.calls = []

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        B = np.asarray(observation).shape[0]
        count = np.zeros(B, dtype=np.int64) if state is None else state.copy()
        starts = np.asarray(episode_start, dtype=bool)
        self.calls.append(starts.copy())
        count[starts] = 0
        return count.copy(), count + 1


def test_predict_runner_carries_state_and_resets_rows():
    policy = StepCounter()
    runner = PredictRunner(policy)
    assert isinstance(runner, PolicyRunner)
    obs = np.zeros((3, 2))
    runner.reset()
    assert [runner.act(obs).tolist() for _ in range(3)] == [[0, 0, 0], [1, 1, 1], [2, 2, 2]]
    runner.reset(np.array([True, False, False]))  # row 0 autoreset: a new episode there only
    assert runner.act(obs).tolist() == [0, 3, 3]
    runner.reset(np.array([2]))  # indices work too
    runner.reset(np.array([1, 2]))
    assert runner.act(obs).tolist() == [1, 0, 0]
    runner.reset()  # every row: the state is dropped
    assert runner.act(obs).tolist() == [0, 0, 0]
    assert policy.calls[0].all() and not policy.calls[1].any()


def test_callable_runner_and_sanity_policies():
    runner = as_runner(lambda obs: obs[:, :1] * 0)
    assert isinstance(runner, CallableRunner)
    assert runner.act(np.ones((2, 3))).shape == (2, 1)
    counting = agent_policy(StepCounter())
    assert as_runner(counting) is counting


def test_rollout_resets_a_recurrent_policy_at_each_episode_start():
    """The evaluation rollout carries the state step to step and starts every episode afresh:
    the knob of step t is the action of count t, in the first rollout and in the next one."""
    env = make_vector_env("navgym/Robot2dFading-v2", 3, SHORT)
    policy = StepCounter()

    class CountToAction:  # the count as a fading action in [-1, 1]
        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            count, state = policy.predict(observation, state, episode_start, deterministic)
            return (-1.0 + 0.05 * count.astype(np.float32)).reshape(-1, 1), state

    s = seeds("eval", 3)
    first = rollout(env, CountToAction(), s)
    n_calls = len(policy.calls)
    second = rollout(env, CountToAction(), s, autoreset=True)
    np.testing.assert_array_equal(first.steps["knob"], second.steps["knob"])
    assert policy.calls[0].all() and policy.calls[n_calls].all()
    assert not any(c.any() for c in policy.calls[1:n_calls])
    knob = first.steps["knob"]
    assert np.unique(knob[:, 0]).size == 1 and np.all(np.diff(knob[0, :10]) > 0)  # grows with t


def test_frame_stack_matches_vec_frame_stack_across_autoresets():
    """:class:`FrameStack` stacks as SB3's VecFrameStack does, resets included."""
    from stable_baselines3.common.vec_env import VecFrameStack

    venv = make_vec_env(ENV, 2, 7, {"eval_info": False, "episode_steps": 6, "max_episode_steps": 6})
    stacked = VecFrameStack(venv, 3)
    inner = []
    orig_step_wait = venv.step_wait

    def spy():
        out = orig_step_wait()
        inner.append(out[0].copy())
        return out

    venv.step_wait = spy
    obs = stacked.reset()
    d = venv.observation_space.shape[0]
    stack = FrameStack(3, d)
    assert not obs[:, : 2 * d].any()  # zeros before the episode's first step
    frames = stack.push(None, obs[:, -d:], None)
    np.testing.assert_array_equal(frames, obs)
    rng = np.random.default_rng(0)
    dones = np.zeros(2, dtype=bool)
    for _ in range(15):  # crosses two autoresets
        action = rng.uniform(-1, 1, size=(2, 2)).astype(np.float32)
        obs, _, dones, _ = stacked.step(action)
        frames = stack.push(frames, inner[-1], dones)
        np.testing.assert_array_equal(frames, obs)
    stacked.close()


# --- training, saving, loading --------------------------------------------------------------


@pytest.fixture(scope="module")
def lstm_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("lstm") / "ppo_lstm"
    return train(ENV, "ppo_lstm", config=TINY_LSTM, seed=0, out_dir=out, progress=False, tensorboard=False)


@pytest.fixture(scope="module")
def stack_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("stack") / "ppo"
    return train(ENV, "ppo", config=TINY_STACK, seed=0, out_dir=out, progress=False, tensorboard=False)


def test_manifest_records_algo_frame_stack_and_lstm(lstm_run, stack_run):
    m = json.loads((lstm_run / "manifest.json").read_text())
    assert m["algo"] == "ppo_lstm" and m["frame_stack"] == 1
    assert m["lstm"] == {
        "lstm_hidden_size": 8,
        "n_lstm_layers": 1,
        "shared_lstm": False,
        "enable_critic_lstm": True,
    }
    assert "env_observation_space" not in m
    s = json.loads((stack_run / "manifest.json").read_text())
    assert s["algo"] == "ppo" and s["frame_stack"] == 3 and s["lstm"] is None
    d = s["env_observation_space"]["shape"][0]
    assert s["observation_space"]["shape"] == [3 * d]
    meta = json.loads((stack_run / "meta.json").read_text())
    assert meta["frame_stack"] == 3 and "sb3_contrib" in meta["versions"]
    ck = sorted((lstm_run / "checkpoints").iterdir())[-1]
    assert json.loads((ck / "manifest.json").read_text())["lstm"]["lstm_hidden_size"] == 8


def _reference_actions(run, algo, frame_stack, n_steps=90):
    """Actions of the archive loaded by SB3 itself (trusted: we made it) in the training env
    chain (VecNormalize with the saved statistics, VecFrameStack outside it), and the raw
    observations and episode starts that produced them."""
    from agents.training.loading import algo_class

    cfg = yaml.safe_load((run / "config.yml").read_text())
    env = make_vec_env(
        ENV,
        2,
        seeds("train", 2, offset=500_000)[0],
        cfg["env_kwargs"],
        normalize_path=run / "vecnormalize.npz",
        training=False,
        frame_stack=frame_stack,
    )
    vn = env.venv if frame_stack > 1 else env
    model = algo_class(algo).load(run / "model.zip", device="cpu")
    obs = env.reset()
    raw, starts, actions = [], [], []
    state, start = None, np.ones(2, dtype=bool)
    for _ in range(n_steps):  # 40-step episodes: two episode starts per row
        raw.append(vn.get_original_obs().copy())
        starts.append(start.copy())
        a, state = model.predict(obs, state=state, episode_start=start, deterministic=True)
        actions.append(a)
        obs, _, start, _ = env.step(a)
    env.close()
    return raw, starts, actions


@pytest.mark.parametrize("which", ["lstm", "stack"])
def test_saved_agent_round_trips_with_its_memory(which, lstm_run, stack_run):
    """save -> load (pickle-free) -> the same deterministic actions as the model in its training
    env chain, on the same observation sequence, with the LSTM state / frames reset per episode."""
    run, algo, n = (lstm_run, "ppo_lstm", 1) if which == "lstm" else (stack_run, "ppo", 3)
    raw, starts, expected = _reference_actions(run, algo, n)
    agent = load_agent(run, env=ENV)
    assert agent.has_memory and agent.frame_stack == n and agent.algo == algo
    assert (agent.lstm is not None) == (which == "lstm")
    assert agent.observation_space.shape == raw[0].shape[1:]
    runner = PredictRunner(agent)
    for obs, start, want in zip(raw, starts, expected, strict=True):
        runner.reset(start)
        np.testing.assert_array_equal(runner.act(obs), want)
    again = PredictRunner(load_agent(run))
    again.reset()
    for obs, start, want in zip(raw, starts, expected, strict=True):
        again.reset(start)
        np.testing.assert_array_equal(again.act(obs), want)
    if which == "stack":
        assert isinstance(runner.state, StackedState) and runner.state.frames.shape == (
            2,
            3 * raw[0].shape[1],
        )


def test_memory_matters_to_the_actions(lstm_run):
    """Without its carried state the recurrent agent acts differently (the test above is not
    vacuous): the same observations, state dropped every step."""
    raw, starts, expected = _reference_actions(lstm_run, "ppo_lstm", 1, n_steps=20)
    agent = load_agent(lstm_run)
    memoryless = [agent.predict(o, deterministic=True)[0] for o in raw]
    assert any(not np.array_equal(a, b) for a, b in zip(memoryless, expected, strict=True))


def test_single_observation_predict_of_a_stacked_agent(stack_run):
    agent = load_agent(stack_run)
    obs = np.zeros(agent.observation_space.shape, dtype=np.float32)
    a, state = agent.predict(obs)
    assert a.shape == agent.action_space.shape and state.frames.shape == (1, 3 * obs.shape[0])


def test_frame_stack_of_config_and_manifest_must_agree(stack_run, tmp_path):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(stack_run, bad, ignore=shutil.ignore_patterns("checkpoints"))
    cfg = yaml.safe_load((bad / "config.yml").read_text())
    cfg["frame_stack"] = 2
    (bad / "config.yml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    old = json.loads((bad / "manifest.json").read_text())
    write_manifest(
        bad,
        list(old["files"]),
        algo=old["algo"],
        env_id=old["env_id"],
        num_timesteps=old["num_timesteps"],
        observation_space=space_from_dict(old["observation_space"]),
        action_space=space_from_dict(old["action_space"]),
        frame_stack=3,
        env_observation_space=space_from_dict(old["env_observation_space"]),
    )
    with pytest.raises(AgentLoadError, match="frame_stack"):
        load_agent(bad)


def test_lstm_record_must_match_the_model(lstm_run, tmp_path):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(lstm_run, bad, ignore=shutil.ignore_patterns("checkpoints"))
    m = json.loads((bad / "manifest.json").read_text())
    m["lstm"]["lstm_hidden_size"] = 16
    (bad / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(AgentLoadError, match="LSTM"):
        load_agent(bad)


def test_evaluation_and_sanity_run_a_recurrent_agent(lstm_run, stack_run):
    pols = parse_policies([f"lstm=ppo_lstm:{lstm_run}", f"stack=ppo:{stack_run}"], ENV, SHORT)
    assert pols["lstm"].lstm is not None and pols["stack"].frame_stack == 3
    s = seeds("eval", 3)
    r1 = evaluate(ENV, pols, s, SHORT, n_boot=50, progress=False)
    r2 = evaluate(ENV, pols, s, SHORT, n_boot=50, progress=False)
    for name in pols:
        np.testing.assert_array_equal(r1.episodes[name]["return"], r2.episodes[name]["return"])
        assert np.isfinite(r1.episodes[name]["return"]).all()
    out = run_episodes(agent_policy(pols["lstm"]), ENV, seeds("train", 2, offset=600_000), SHORT)
    assert out["steps"].max() <= 40 and np.isfinite(out["return"]).all()


def test_recurrent_frame_stacked_run_resumes_from_its_checkpoint(tmp_path):
    cfg = dict(TINY_LSTM, frame_stack=2, n_timesteps=128, checkpoint_freq=128)
    out = train(
        ENV, "ppo_lstm", config=cfg, seed=1, out_dir=tmp_path / "r", progress=False, tensorboard=False
    )
    (out / "manifest.json").unlink()  # the final agent gone: resume from the checkpoint
    train(
        ENV,
        "ppo_lstm",
        seed=1,
        total_timesteps=256,
        out_dir=out,
        resume=True,
        progress=False,
        tensorboard=False,
    )
    m = json.loads((out / "manifest.json").read_text())
    assert m["num_timesteps"] == 256 and m["frame_stack"] == 2 and m["lstm"]["lstm_hidden_size"] == 8
    agent = load_agent(out)
    runner = PredictRunner(agent)
    runner.reset()
    env = make_vector_env(ENV, 2, SHORT)
    obs, _ = env.reset(seed=seeds("eval", 2))
    assert runner.act(obs).shape == (2, 2)
    env.close()
