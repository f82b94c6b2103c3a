"""The RL ecosystem's front doors: gym.make_vec async, a CleanRL-style loop, rl-zoo3 (slow)."""

import importlib.util
import math
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401

ROOT = Path(__file__).resolve().parents[3]
ENV = "navgym/Robot2dFading-v2"
SHORT = {"episode_steps": 12, "max_episode_steps": 12}


def _run(env, steps):
    obs, _ = env.reset(seed=[11, 12])
    out = [obs]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        a = rng.uniform(-1, 1, size=env.action_space.shape).astype(env.action_space.dtype)
        obs, r, term, trunc, _ = env.step(a)
        out += [obs, r, term, trunc]
    env.close()
    return out


def test_make_vec_async_with_spawned_workers_equals_sync():
    """Spawned workers import nothing of the parent: they must find the navgym id on their own."""
    kw = {"vector_kwargs": {"context": "spawn"}, **SHORT}
    async_env = gym.make_vec(ENV, num_envs=2, vectorization_mode="async", **kw)
    assert type(async_env).__name__ == "AsyncVectorEnv"
    got = _run(async_env, 15)  # past the end of an episode: the autoreset too
    want = _run(gym.make_vec(ENV, num_envs=2, vectorization_mode="sync", **SHORT), 15)
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)


def _example():
    pytest.importorskip("torch")
    spec = importlib.util.spec_from_file_location("cleanrl_ppo", ROOT / "examples" / "cleanrl_ppo.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("env_id", [ENV, "navgym/Robot2dResample-v2"])  # Box and Discrete actions
def test_cleanrl_style_ppo_runs_on_the_native_vector_env(env_id):
    mod = _example()
    args = ["--env-id", env_id, "--num-envs", "4", "--num-steps", "16", "--total-timesteps", "128"]
    stats = mod.main([*args, "--env-kwargs", '{"episode_steps": 12, "max_episode_steps": 12}'])
    assert stats["steps"] == 128 and stats["iteration"] == 2
    assert stats["episodes"] >= 4 and math.isfinite(stats["mean_return"])  # episodes ended and were counted


@pytest.mark.slow
def test_rl_zoo3_trains_and_enjoys_with_the_shipped_config(tmp_path):
    pytest.importorskip("rl_zoo3")
    env_id = "navgym/Robot2dFading-v1"
    shutil.copy(ROOT / "agents" / "configs" / "ppo.yml", tmp_path / "ppo.yml")
    common = ["--algo", "ppo", "--env", env_id, "--gym-packages", "navgym", "-f", str(tmp_path / "logs")]
    train = subprocess.run(
        [
            sys.executable,
            "-m",
            "rl_zoo3.train",
            *common,
            "-n",
            "2048",
            "--seed",
            "0",
            "--conf-file",
            "ppo.yml",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert train.returncode == 0, train.stderr[-3000:]
    assert "Using 16 environments" in train.stdout and "'eval_info': False" in train.stdout
    model = tmp_path / "logs" / "ppo" / "navgym-Robot2dFading-v1_1" / "navgym-Robot2dFading-v1.zip"
    assert model.is_file()
    enjoy = subprocess.run(
        [sys.executable, "-m", "rl_zoo3.enjoy", *common, "--exp-id", "1", "-n", "650", "--no-render"]
        + ["--deterministic"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert enjoy.returncode == 0, enjoy.stderr[-3000:]
    assert "Episode Length 600" in enjoy.stdout and "Mean reward:" in enjoy.stdout
