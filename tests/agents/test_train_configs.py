"""A training configuration for every trainable id: per-task / per-platform defaults, per-id entries."""

from __future__ import annotations

import warnings

import gymnasium as gym
import pytest

pytest.importorskip("stable_baselines3")

from agents.training.config import (
    CONFIG_DIR,
    UnknownEnvError,
    build_hyperparameters,
    check_algo_entry,
    default_entry,
    load_config,
    read_config_file,
    split_entry,
    trainable_ids,
)

TRAINABLE = trainable_ids()
#: One id per way of resolving (defaults: all / task / platform; an entry of its own).
REPRESENTATIVE = [
    "navgym/Robot2dFading-v2",  # defaults: all
    "navgym/GpsInsResample-v2",  # defaults: task resample, platform GpsIns
    "navgym/JpaRobust-v2",  # defaults: all (another platform and task)
    "navgym/Robot2dResample-v2",  # an entry of its own
    "navgym/Robot2dRowScale-v3",  # defaults: all; a v3 id that passed G1 (navgym list: "train")
]


def test_trainable_ids_are_the_newest_versions():
    assert "navgym/Robot2dFading-v2" in TRAINABLE and "navgym/Robot2dFading-v1" not in TRAINABLE
    assert len(TRAINABLE) == len({i.rpartition("-v")[0] for i in TRAINABLE})
    assert "navgym/ReplayRowScale-v3" not in TRAINABLE  # real data: evaluation only


@pytest.mark.parametrize("env_id", TRAINABLE)
def test_every_trainable_id_has_a_configuration_for_each_algorithm_that_fits(env_id):
    env = gym.make(env_id)
    discrete = isinstance(env.action_space, gym.spaces.Discrete)
    env.close()
    for algo in ("ppo", "ppo_lstm", "dqn" if discrete else "sac"):
        entry = load_config(env_id, algo)
        run, hyper = split_entry(entry)
        check_algo_entry(algo, run, hyper)
        build_hyperparameters(hyper)
        assert run["n_timesteps"] > 0 and run["env_kwargs"]["eval_info"] is False
    wrong = "sac" if discrete else "dqn"
    with pytest.raises(UnknownEnvError, match="defaults cover tasks"):
        load_config(env_id, wrong)


def test_an_entry_of_its_own_wins_over_the_defaults():
    ppo = read_config_file(CONFIG_DIR / "ppo.yml")
    assert load_config("navgym/Robot2dMixture-v2") == ppo["navgym/Robot2dMixture-v2"]
    assert "residual" not in default_entry("navgym/Robot2dMixture-v2")
    assert load_config("navgym/GpsInsMixture-v2")["gamma"] == 0.98  # platform GpsIns
    assert load_config("navgym/GpsInsResample-v2")["ent_coef"] == 0.01  # task resample
    assert load_config("navgym/PedestrianFading-v2")["gamma"] == 0.97  # all


def test_a_mistyped_id_is_unknown_with_a_suggestion(capsys):
    from navgym.cli import main

    with pytest.raises(UnknownEnvError, match="unknown env id .*did you mean 'navgym/Robot2dFading-v2'"):
        load_config("navgym/Robot2dFadin-v2")
    assert main(["train", "navgym/Robot2dFadin-v2", "--n-timesteps", "512"]) == 2
    err = capsys.readouterr().err
    assert "unknown env id" in err and "Robot2dFading-v2" in err and "no ppo configuration" not in err


def _train_starts(env_id, tmp_path):
    from navgym.cli import main

    out = tmp_path / env_id.split("/")[-1]
    args = ["train", env_id, "--n-timesteps", "512", "--n-envs", "2", "--out", str(out), "--no-progress"]
    with warnings.catch_warnings():  # SB3: the mini-batch exceeds the short rollout buffer
        warnings.simplefilter("ignore", UserWarning)
        assert main(args) == 0
    assert (out / "model.zip").is_file() and (out / "manifest.json").is_file()


@pytest.mark.parametrize("env_id", REPRESENTATIVE)
def test_navgym_train_starts(env_id, tmp_path):
    _train_starts(env_id, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", [i for i in TRAINABLE if i not in REPRESENTATIVE])
def test_navgym_train_starts_for_every_trainable_id(env_id, tmp_path):
    _train_starts(env_id, tmp_path)
