"""Plain SB3 saves in and out (``navgym eval --trust``, ``navgym import``, ``navgym export``); labels."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import gymnasium as gym
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

import navgym  # noqa: F401
from agents.evaluation.cli import parse_policies, run_eval
from agents.training.agent_files import AgentLoadError
from agents.training.train import quiet_logger

FADING = "navgym/GpsInsFading-v0"
KW = {"max_episode_steps": 40}


@pytest.fixture(scope="module")
def sb3_save(tmp_path_factory):
    """A tiny PPO trained by plain SB3 (a few hundred steps): ``my.zip`` and ``my_vn.pkl``."""
    d = tmp_path_factory.mktemp("sb3")
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(FADING, **KW)]), norm_obs=True, norm_reward=True)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.set_logger(quiet_logger(d, 0))  # not SB3's default: an empty folder in the temp directory
    model.learn(256)
    model.save(d / "my.zip")
    venv.save(str(d / "my_vn.pkl"))
    return d / "my.zip", d / "my_vn.pkl"


def _obs(n=5):
    env = gym.make(FADING, **KW)
    out = np.stack([env.reset(seed=s)[0] for s in range(n)])
    env.close()
    return out


def _sb3_actions(zip_path, pkl_path, obs):
    venv = DummyVecEnv([lambda: gym.make(FADING, **KW)])
    vn = VecNormalize.load(str(pkl_path), venv)
    vn.training = False
    return PPO.load(zip_path, device="cpu").predict(vn.normalize_obs(obs), deterministic=True)[0]


def test_a_label_given_twice_is_an_error():
    """An agent labelled ``plain`` beside the baselines no longer replaces the baseline's row."""
    from agents.demo import ZOO

    with pytest.raises(ValueError, match="label 'plain' is given twice"):
        parse_policies(["baselines", f"plain=ppo:{ZOO / 'GpsInsFading-v0'}"], FADING, KW)
    with pytest.raises(ValueError, match="given twice"):
        parse_policies(["plain", "plain"], FADING, KW)


def test_eval_cli_reports_a_label_collision(capsys):
    from navgym.cli import main

    assert main(["eval", "--env", FADING, "--policies", "plain", "plain", "--episodes", "2"]) == 2
    assert "given twice" in capsys.readouterr().err


def test_a_plain_sb3_model_needs_trust_and_then_evaluates(sb3_save, tmp_path):
    zip_path, pkl = sb3_save
    with pytest.raises(AgentLoadError, match="--trust"):
        parse_policies([f"ppo:{zip_path}"], FADING, KW, vecnormalize=pkl)
    pols = parse_policies([f"mine=ppo:{zip_path}"], FADING, KW, vecnormalize=pkl, trust=True)
    obs = _obs()
    np.testing.assert_array_equal(
        pols["mine"].predict(obs, deterministic=True)[0], _sb3_actions(zip_path, pkl, obs)
    )
    res = run_eval(
        FADING,
        ["plain", f"mine=ppo:{zip_path}"],
        2,
        None,
        env_kwargs=KW,
        vecnormalize=pkl,
        trust=True,
        n_boot=50,
        progress=False,
    )
    assert set(res.episodes) == {"plain", "mine"}


def test_eval_cli_without_trust_says_why_and_how(sb3_save, capsys):
    from navgym.cli import main

    zip_path, pkl = sb3_save
    rc = main(["eval", "--env", FADING, "--policies", f"ppo:{zip_path}", "--vecnormalize", str(pkl)])
    err = capsys.readouterr().err
    assert rc == 2 and "--trust" in err and "arbitrary code" in err and "navgym import" in err


def test_import_then_export_round_trips_through_sb3(sb3_save, tmp_path, capsys):
    """SB3 save -> navgym agent (loads without trust) -> SB3 files (PPO.load / VecNormalize.load)."""
    from agents.training.loading import load_agent
    from navgym.cli import main

    zip_path, pkl = sb3_save
    agent_dir = tmp_path / "agent"
    args = ["import", str(zip_path), "--vecnormalize", str(pkl), "--env", FADING, str(agent_dir)]
    assert main(args) == 2
    assert "--trust" in capsys.readouterr().err
    assert main([*args, "--trust"]) == 0
    assert {"model.zip", "vecnormalize.npz", "manifest.json", "config.yml"} <= {
        p.name for p in agent_dir.iterdir()
    }
    assert not (agent_dir / "vecnormalize.pkl").exists()
    obs = _obs()
    want = _sb3_actions(zip_path, pkl, obs)
    agent = load_agent(agent_dir, env=FADING)  # no trust: nothing unpickled
    np.testing.assert_array_equal(agent.predict(obs, deterministic=True)[0], want)

    out = tmp_path / "exported"
    assert main(["export", str(agent_dir), str(out)]) == 0
    np.testing.assert_array_equal(_sb3_actions(out / "model.zip", out / "vecnormalize.pkl", obs), want)
    pols = parse_policies(
        [f"back=ppo:{out / 'model.zip'}"], FADING, KW, vecnormalize=out / "vecnormalize.pkl", trust=True
    )
    np.testing.assert_array_equal(pols["back"].predict(obs, deterministic=True)[0], want)


def test_a_zoo_agent_exports_to_sb3_files(tmp_path):
    from agents.demo import ZOO
    from agents.training.interop import export_agent
    from agents.training.loading import load_agent

    zoo = ZOO / "GpsInsFading-v2"
    out = export_agent(zoo, tmp_path / "x")
    obs = np.stack([gym.make("navgym/GpsInsFading-v2").reset(seed=s)[0] for s in range(3)])
    venv = DummyVecEnv([lambda: gym.make("navgym/GpsInsFading-v2")])
    vn = VecNormalize.load(str(out / "vecnormalize.pkl"), venv)
    got = PPO.load(out / "model.zip", device="cpu").predict(vn.normalize_obs(obs), deterministic=True)[0]
    np.testing.assert_allclose(got, load_agent(zoo).predict(obs, deterministic=True)[0], rtol=1e-6)
