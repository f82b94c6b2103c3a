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


def test_nav_metrics_are_the_per_episode_rmse_divergence_and_knob_statistics():
    """The callback's rollout figures against a direct computation over the steps' infos."""
    from types import SimpleNamespace

    import numpy as np

    from agents.training.callbacks import NavMetricsCallback

    class Logger:
        def __init__(self):
            self.values = {}

        def record(self, key, value):
            self.values[key] = value

    rng = np.random.default_rng(0)
    B, T = 3, 7
    err = rng.random((T, B)) * 10
    err[2, 1] = np.nan  # a step without a finite error does not count
    knob = rng.random((T, B, 2))
    dones = np.zeros((T, B), dtype=bool)
    dones[3, 0] = dones[6, 0] = dones[5, 2] = True
    cb = NavMetricsCallback()
    logger = Logger()
    cb.model = SimpleNamespace(logger=logger)  # BaseCallback.logger is the model's
    for t in range(T):
        infos = [{"pos_err_m": err[t, i], "knob": knob[t, i], "diverged": i == 2} for i in range(B)]
        infos[1].pop("knob") if t == 4 else None  # a step without a knob
        cb.locals = {"infos": infos, "dones": dones[t]}
        assert cb._on_step()
    cb._on_rollout_end()
    rmse = [
        np.sqrt(np.mean(err[0:4, 0] ** 2)),
        np.sqrt(np.mean(err[0:6, 2] ** 2)),
        np.sqrt(np.mean(err[4:7, 0] ** 2)),
    ]
    k = np.concatenate([knob[t, i] for t in range(T) for i in range(B) if not (t == 4 and i == 1)])
    got = logger.values
    assert got["nav/episodes"] == 3
    np.testing.assert_allclose(got["nav/ep_rmse_m"], np.mean(rmse), rtol=1e-12)
    assert got["nav/divergence_rate"] == pytest.approx(1 / 3)
    for name, value in (("mean", k.mean()), ("std", k.std()), ("min", k.min()), ("max", k.max())):
        assert got[f"nav/knob_{name}"] == pytest.approx(value, rel=1e-12)
    # sub-env 1 never ended: its running sums (one NaN step skipped) are kept for the next rollout
    np.testing.assert_allclose(cb._sq[1], np.nansum(err[:, 1] ** 2), rtol=1e-12)
    assert cb._n[1] == T - 1
