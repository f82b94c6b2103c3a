"""Training logs RMSE, divergence and knob statistics, and keeps the best model on tuning seeds."""

from __future__ import annotations

import json
import warnings

import pytest

pytest.importorskip("stable_baselines3")

from agents.seeds import check_seeds
from agents.training import train
from agents.training.config import load_config
from agents.training.loading import load_agent

ENV = "navgym/Robot2dFading-v2"


def _scalars(tb_dir):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    tags = {}
    for f in tb_dir.rglob("events.out.tfevents.*"):
        acc = EventAccumulator(str(f.parent))
        acc.Reload()
        for tag in acc.Tags()["scalars"]:
            tags[tag] = [e.value for e in acc.Scalars(tag)]
    return tags


def test_training_logs_nav_metrics_and_keeps_the_best_model_on_tuning_seeds(tmp_path, monkeypatch):
    pytest.importorskip("tensorboard")
    import sys

    train_mod = sys.modules["agents.training.train"]  # the name agents.training.train is the function

    seeds_used = []
    make = train_mod.make_vec_env

    def spy(env_id, n_envs, seed, *a, **k):
        seeds_used.append((n_envs, seed, k.get("training", True)))
        return make(env_id, n_envs, seed, *a, **k)

    monkeypatch.setattr(train_mod, "make_vec_env", spy)
    entry = load_config(ENV)
    entry.update(n_steps=64, batch_size=64, env_kwargs={**entry["env_kwargs"], "max_episode_steps": 40})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        out = train(
            ENV,
            config=entry,
            total_timesteps=512,
            n_envs=2,
            out_dir=tmp_path / "run",
            progress=False,
            eval_freq=256,
            eval_episodes=3,
        )
    evals = [(n, s) for n, s, training in seeds_used if not training]
    assert evals and all(n == 3 for n, _ in evals)
    for n, s in evals:
        check_seeds("tune", range(s, s + n))  # tuning seeds, never held-out ones
    tags = _scalars(out / "tb")
    for tag in ("nav/ep_rmse_m", "nav/divergence_rate", "nav/knob_mean", "nav/knob_std", "eval/tune_rmse_m"):
        assert tag in tags, (tag, sorted(tags))
    assert all(v > 0 for v in tags["nav/ep_rmse_m"])
    assert len(tags["eval/tune_return"]) == 3  # at 0 (the initial policy), 256 and 512 steps
    best = json.loads((out / "best" / "best.json").read_text())
    assert best["episodes"] == 3 and best["return"] == pytest.approx(max(tags["eval/tune_return"]), rel=1e-6)
    folders = list((out / "best").glob("step_*"))
    assert [f.name for f in folders] == [best["folder"]]
    agent = load_agent(folders[0], env=ENV)
    assert agent.model.num_timesteps == best["num_timesteps"]


def test_eval_freq_is_checked():
    with pytest.raises(ValueError, match="eval_episodes"):
        train(ENV, total_timesteps=64, eval_freq=32, eval_episodes=0, progress=False)
