"""Training, checkpoint/resume and loading of SB3 agents (agents.training), on tiny configs."""

from __future__ import annotations

import json
import shutil
import tempfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

from agents.seeds import seeds
from agents.training import (
    AgentLoadError,
    UnknownEnvError,
    latest_checkpoint,
    load_agent,
    load_config,
    train,
)
from agents.training.config import build_hyperparameters, split_entry
from agents.training.loading import read_normalization, space_from_dict, write_manifest
from agents.training.sanity import agent_policy, run_episodes
from agents.training.train import env_base_seed

ENV = "navgym/GpsInsFading-v0"
SHORT = {"episode_steps": 50, "max_episode_steps": 50}
#: A tiny PPO entry: 8 short episodes in parallel, small network, normalized observations.
TINY = {
    "n_envs": 8,
    "n_timesteps": 6144,
    "policy": "MlpPolicy",
    "normalize": {"norm_obs": True, "norm_reward": True},
    "env_kwargs": {"eval_info": False, **SHORT},
    "n_steps": 64,
    "batch_size": 128,
    "n_epochs": 5,
    "gamma": 0.95,
    "learning_rate": 1.0e-3,
    "policy_kwargs": {"net_arch": [32, 32], "activation_fn": "tanh"},
    "checkpoint_freq": 2048,
}


def rewrite_manifest(folder, drop=()):
    """Rewrite ``folder``'s manifest to match its files now (what someone editing them could do)."""
    old = json.loads((folder / "manifest.json").read_text())
    write_manifest(
        folder,
        [n for n in old["files"] if n not in drop and (folder / n).is_file()],
        algo=old["algo"],
        env_id=old["env_id"],
        num_timesteps=old["num_timesteps"],
        observation_space=space_from_dict(old["observation_space"]),
        action_space=space_from_dict(old["action_space"]),
    )


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("tiny") / "ppo"
    return train(ENV, "ppo", config=TINY, seed=0, out_dir=out, progress=False)


def test_training_outputs(trained):
    for name in ("model.zip", "vecnormalize.npz", "config.yml", "meta.json", "manifest.json"):
        assert (trained / name).is_file(), name
    assert not (trained / "vecnormalize.pkl").exists()
    manifest = json.loads((trained / "manifest.json").read_text())
    assert set(manifest["files"]) == {"model.zip", "vecnormalize.npz", "config.yml", "meta.json"}
    assert manifest["num_timesteps"] == 6144 and manifest["env_id"] == ENV
    meta = json.loads((trained / "meta.json").read_text())
    assert meta["total_timesteps"] == 6144
    assert meta["seed"] == 0 and meta["env_id"] == ENV and meta["algo"] == "ppo"
    assert meta["command"].startswith("navgym train navgym/GpsInsFading-v0 --algo ppo --seed 0")
    assert {"torch", "stable_baselines3", "gymnasium", "numpy"} <= set(meta["versions"])
    assert meta["wall_time_s"] > 0
    assert any((trained / "tb").rglob("events.out.tfevents.*"))
    assert meta["env_seeds_this_session"] == [0, TINY["n_envs"] - 1]  # seed 0: train seeds 0..n-1


class _FirstReset(Exception):
    pass


def test_training_resets_its_envs_on_the_documented_train_seeds(tmp_path, monkeypatch):
    """Sub-env i starts from ``seed * 1000 + i``, not SB3's ``seed + i`` (its set_random_seed
    reseeds the env whenever a model is built or loaded)."""
    from navgym.envs.sb3 import NavSB3VecEnv

    seen = []

    def spy(self):
        seen.append(list(self._seeds))
        raise _FirstReset  # the reset that starts learning: no need to train

    monkeypatch.setattr(NavSB3VecEnv, "reset", spy)
    with pytest.raises(_FirstReset):
        train(ENV, "ppo", config=TINY, seed=3, out_dir=tmp_path / "run", progress=False)
    assert seen == [seeds("train", TINY["n_envs"], offset=3000)]


def test_training_leaves_no_log_folder_in_the_temp_directory(tmp_path, monkeypatch):
    """Left to SB3, a run without TensorBoard makes an empty ``SB3-<date>`` folder there per ``learn``."""
    temp = tmp_path / "temp"
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    cfg = {**TINY, "checkpoint_freq": 0}
    out = tmp_path / "run"
    train(ENV, "ppo", config=cfg, seed=2, total_timesteps=512, out_dir=out, progress=False, tensorboard=False)
    assert (out / "manifest.json").is_file() and not (out / "tb").exists()
    assert not list(temp.glob("SB3-*"))  # (torch may keep its own caches there)


def test_trained_beats_random_policy(trained):
    """Random lambda in [1, 10] often diverges; a few thousand PPO steps learn to keep it low."""
    agent = load_agent(trained)
    assert agent.normalizer is not None and agent.env_id == ENV
    test_seeds = seeds("train", 24, offset=900_000)
    rng = np.random.default_rng(0)

    def random_policy(obs):
        return rng.uniform(-1.0, 1.0, size=(obs.shape[0], 1)).astype(np.float32)

    ours = run_episodes(agent_policy(agent), ENV, test_seeds, SHORT)
    rand = run_episodes(random_policy, ENV, test_seeds, SHORT)
    assert ours["return"].mean() > rand["return"].mean() + 15.0, (
        ours["return"].mean(),
        rand["return"].mean(),
    )
    assert ours["diverged"].sum() < rand["diverged"].sum()


def test_predict_normalizes_raw_observations(trained):
    agent = load_agent(trained)
    obs = np.zeros((3, agent.observation_space.shape[0]), dtype=np.float32)
    a, _ = agent.predict(obs)
    a_norm, _ = agent.model.predict(agent.normalizer(obs), deterministic=True)
    np.testing.assert_array_equal(a, a_norm)
    single, _ = agent.predict(obs[0])
    assert single.shape == agent.action_space.shape
    with pytest.raises(ValueError, match="observation must have shape"):
        agent.predict(np.zeros(3, dtype=np.float32))


def test_checkpoint_and_resume_continue_timesteps(tmp_path):
    cfg = dict(TINY, n_timesteps=2048, checkpoint_freq=1024, env_kwargs={"eval_info": False, **SHORT})
    out = tmp_path / "run"
    train(ENV, "ppo", config=cfg, seed=1, out_dir=out, progress=False)
    ck = latest_checkpoint(out)
    assert ck is not None and ck[2] == 2048 and ck[1] is not None
    # Simulate an interruption after the checkpoint: the final files are gone.
    (out / "model.zip").unlink()
    (out / "meta.json").unlink()
    from navgym.envs.sb3 import NavSB3VecEnv

    seen, real_reset = [], NavSB3VecEnv.reset

    def spy(self):
        seen.append(list(self._seeds))
        return real_reset(self)

    NavSB3VecEnv.reset = spy
    try:
        train(ENV, "ppo", seed=1, total_timesteps=3072, out_dir=out, resume=True, progress=False)
    finally:
        NavSB3VecEnv.reset = real_reset
    meta = json.loads((out / "meta.json").read_text())
    # the resumed session starts on fresh train seeds derived from (seed, steps done)
    base = env_base_seed(1, cfg["n_envs"], 2048)
    assert seen[0] == seeds("train", cfg["n_envs"], offset=base) and base != 1000
    assert meta["env_seeds_this_session"] == [base, base + cfg["n_envs"] - 1]
    assert meta["resumed_from_timesteps"] == 2048
    assert meta["total_timesteps"] == 3072
    assert meta["command"].endswith("--resume") and meta["history"] == []
    agent = load_agent(out)
    assert agent.model.num_timesteps == 3072
    # The normalization statistics continued too (more observations than at the checkpoint).
    at_checkpoint = float(read_normalization(ck[1])["count"])
    assert float(read_normalization(out / "vecnormalize.npz")["count"]) > at_checkpoint
    # TensorBoard continued in the same run folder.
    assert [p.name for p in (out / "tb").iterdir()] == ["PPO_1"]
    # A checkpoint loads on its own (folder or model archive), with its statistics beside it.
    assert load_agent(latest_checkpoint(out)[0]).normalizer is not None
    assert load_agent(latest_checkpoint(out)[0].parent).normalizer is not None
    # Extending a finished run keeps the earlier session in the history.
    train(ENV, "ppo", seed=1, total_timesteps=4096, out_dir=out, resume=True, progress=False)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["total_timesteps"] == 4096 and meta["resumed_from_timesteps"] == 3072
    assert [h["total_timesteps"] for h in meta["history"]] == [3072]


def test_load_agent_missing_path(tmp_path):
    missing = tmp_path / "nothing-here"
    with pytest.raises(FileNotFoundError, match="nothing-here"):
        load_agent(missing)
    tmp_path.joinpath("empty").mkdir()
    with pytest.raises(FileNotFoundError, match="model.zip"):
        load_agent(tmp_path / "empty")


def test_load_agent_corrupt_files(tmp_path, trained):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "model.zip").write_bytes(b"this is not a zip archive")
    with pytest.raises(AgentLoadError, match="manifest.json"):
        load_agent(bad)
    with pytest.raises(AgentLoadError, match="not a stable-baselines3 model archive"):
        load_agent(bad, trust=True)
    with pytest.raises(AgentLoadError):
        load_agent(bad, algo="ppo", trust=True)
    # A valid model with a corrupt statistics file, listed in a manifest that matches it.
    good = tmp_path / "good"
    shutil.copytree(trained, good, ignore=shutil.ignore_patterns("tb", "checkpoints"))
    (good / "vecnormalize.npz").write_bytes(b"PK\x03\x04garbage")
    rewrite_manifest(good)
    with pytest.raises(AgentLoadError, match="normalization statistics"):
        load_agent(good, algo="ppo")
    # A corrupt VecNormalize pickle of an older agent (trusted).
    (good / "vecnormalize.npz").unlink()
    (good / "manifest.json").unlink()
    (good / "vecnormalize.pkl").write_bytes(b"\x80\x04garbage")
    with pytest.raises(AgentLoadError, match="VecNormalize"):
        load_agent(good, algo="ppo", trust=True)


def test_unknown_env_id_is_named():
    with pytest.raises(UnknownEnvError, match="navgym/NoSuchEnv-v0"):
        load_config("navgym/NoSuchEnv-v0", "ppo")
    with pytest.raises(KeyError):
        load_config("navgym/NoSuchEnv-v0", "ppo")
    with pytest.raises(ValueError, match="algo must be one of"):
        load_config(ENV, "trpo")


def test_shipped_configs_parse():
    from agents.training.config import CONFIG_DIR, read_config_file

    for path in sorted(CONFIG_DIR.glob("*.yml")):
        for env_id, entry in read_config_file(path).items():
            assert env_id.startswith("navgym/"), (path, env_id)
            run, hyper = split_entry(entry)
            assert run["n_envs"] >= 1 and run["n_timesteps"] >= 1, (path, env_id)
            build_hyperparameters(hyper)


def test_hyperparameter_parsing():
    run, hyper = split_entry(
        {"n_envs": 4, "n_timesteps": "1e4", "learning_rate": "lin_1e-3", "hyperparameters": {"gamma": 0.9}}
    )
    assert run == {"n_envs": 4, "n_timesteps": 10000}
    kw = build_hyperparameters(dict(hyper, policy_kwargs={"activation_fn": "relu", "net_arch": [8]}))
    assert kw["gamma"] == 0.9 and kw["learning_rate"](0.5) == pytest.approx(5e-4)
    with pytest.raises(ValueError, match="activation_fn"):
        build_hyperparameters({"policy_kwargs": {"activation_fn": "nope"}})
    with pytest.raises(ValueError, match="YAML mapping"):
        build_hyperparameters({"policy_kwargs": "dict(net_arch=[8])"})
    with pytest.raises(ValueError, match="both"):
        split_entry({"gamma": 0.9, "hyperparameters": {"gamma": 0.8}})


def test_zoo_agents_load_and_act():
    """Every shipped agent loads, acts in its environment's action space, and says how it was made."""
    import gymnasium as gym

    import navgym  # noqa: F401
    from agents.training.zoo import ZOO_DIR, load_zoo_agent, zoo_agents

    ids = zoo_agents()
    assert "navgym/GpsInsFading-v0" in ids
    for env_id in ids:
        agent = load_zoo_agent(env_id)
        env = gym.make(env_id)
        obs, _ = env.reset(seed=seeds("train", 1, offset=123)[0])
        action, _ = agent.predict(obs)
        assert env.action_space.contains(np.asarray(action, dtype=env.action_space.dtype)), (env_id, action)
        folder = ZOO_DIR / env_id.split("/")[-1]
        readme = (folder / "README.md").read_text()
        assert "command" in readme and "seed" in readme
        assert (folder / "model.zip").stat().st_size < 1_000_000
        env.close()


def test_zoo_quick_check_applies_the_tuned_constant_of_the_env_s_own_range():
    """QuadrotorFading has lambda_max = 1.122, not 10: the 'tuned constant' row must apply it."""
    import gymnasium as gym

    from agents.baselines import load_tuned
    from agents.training.zoo import reference_policies
    from navgym.envs.registration import superseded_ids_quiet

    env_id = "navgym/QuadrotorFading-v0"
    lam = float(load_tuned(env_id)["constant"]["lam"])
    with superseded_ids_quiet():
        (name,) = [k for k in reference_policies(env_id) if k.startswith("tuned constant")]
        policy = reference_policies(env_id)[name]
        env = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=1)
    applied, _ = env.unwrapped.core.task.knob(policy(obs), 1)
    assert applied[0] == pytest.approx(lam, rel=1e-6)


@pytest.mark.parametrize("env_id", ["navgym/Robot2dNoiseScale-v2", "navgym/Robot2dMixture-v2"])
def test_zoo_quick_check_plain_policy_is_the_task_s_neutral_action_on_vector_knobs(env_id):
    """NoiseScale (2 scales) and the per-row Mixture act with vectors: 'plain' must fit their space."""
    import gymnasium as gym

    from agents.training.zoo import reference_policies

    policies = reference_policies(env_id)
    (name,) = [k for k in policies if k.startswith("plain")]
    env = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=1)
    action = policies[name](obs)
    assert action.shape == (2, *env.single_action_space.shape)
    np.testing.assert_array_equal(action[0], env.unwrapped.core.task.neutral_action())
    env.step(action)  # accepted by the env
