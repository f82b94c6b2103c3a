"""Small papercuts of the command line: tune's output folder and kwargs, sweep's grid check,
``navgym list --json`` and its filter, progress bars off a terminal, ``navgym eval --help``."""

from __future__ import annotations

import json

import pytest

from agents.baselines.registry import TUNED_DIR
from navgym.cli import main

FADING = "navgym/GpsInsFading-v0"


def test_tune_writes_to_a_user_folder_and_takes_key_value_kwargs(tmp_path, monkeypatch, capsys):
    shipped = TUNED_DIR / "GpsInsFading-v0.json"
    before = shipped.read_bytes()
    monkeypatch.chdir(tmp_path)
    args = ["tune", "--env", FADING, "--baselines", "suboptimal", "--episodes", "2", "--quiet"]
    assert main([*args, "--env-kwargs", "max_episode_steps=10"]) == 0
    assert "./tuned/" in capsys.readouterr().err
    written = json.loads((tmp_path / "tuned" / "GpsInsFading-v0.json").read_text())
    assert set(written["baselines"]) == {"suboptimal"}
    assert shipped.read_bytes() == before  # the shipped values are left alone
    assert main([*args, "--env-kwargs", "max_episode_steps"]) == 2  # neither JSON nor key=value
    assert "--env-kwargs" in capsys.readouterr().err


def test_sweep_checks_grid_keys_before_ray_starts(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    import agents.scale.sweep as sweep_mod

    def no_ray(*a, **k):
        raise AssertionError("Ray started before the grid was checked")

    monkeypatch.setattr(sweep_mod, "init_ray", no_ray)
    with pytest.raises(ValueError, match="'learning_rat'.*did you mean 'learning_rate'"):
        sweep_mod.sweep("navgym/Robot2dFading-v2", grid=["learning_rat=1e-4,3e-4"], out=tmp_path / "s")
    with pytest.raises(ValueError, match="env_kwargs"):
        sweep_mod.sweep("navgym/Robot2dFading-v2", grid=["env_kwargs.filtr=ekf"], out=tmp_path / "s")
    assert not (tmp_path / "s").exists()


def test_ray_session_files_go_under_out(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    import os

    import agents.scale.sweep as sweep_mod
    from agents.scale.ray_runtime import MAX_RAY_TEMP_PATH, ray_temp_dir

    deep = tmp_path / ("x" * MAX_RAY_TEMP_PATH) / "ray"
    link = ray_temp_dir(deep)
    assert len(link) <= MAX_RAY_TEMP_PATH + 10 and os.path.realpath(link) == str(deep.resolve())
    assert ray_temp_dir(deep) == link  # the same link again

    class Started(Exception):
        pass

    def fake_init(address, num_cpus, temp_dir=None):
        raise Started(temp_dir)

    monkeypatch.setattr(sweep_mod, "init_ray", fake_init)
    with pytest.raises(Started) as e:
        sweep_mod.sweep("navgym/Robot2dFading-v2", out=tmp_path / "s")
    assert str(e.value.args[0]) == str((tmp_path / "s" / "ray").resolve())


def test_list_json_and_filter(capsys):
    assert main(["list", "--json", "resample-v2"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows and all("Resample-v2" in r["id"] for r in rows)
    assert {"id", "task", "action_space", "observation", "on_divergence"} <= set(rows[0])
    assert main(["list", "*NoiseScale-v2"]) == 0
    table = capsys.readouterr().out
    assert "navgym/Robot2dNoiseScale-v2" in table and "Fading" not in table


def test_progress_bars_are_off_when_stderr_is_not_a_terminal(capsys):
    from agents.baselines import make_baseline
    from agents.evaluation import evaluate
    from agents.evaluation.runner import make_vector_env
    from agents.seeds import seeds

    env = make_vector_env(FADING, 1, {"max_episode_steps": 10})
    evaluate(FADING, {"plain": make_baseline(env, "plain")}, seeds("eval", 2), {"max_episode_steps": 10})
    assert "it/s" not in capsys.readouterr().err  # progress=True by default; capsys is no terminal


def test_eval_help_documents_the_policy_spec_format(capsys):
    with pytest.raises(SystemExit):
        main(["eval", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for part in ("baselines", "NAME:key=value", "oracle", "[LABEL=]ALGO:PATH", "--trust", "--vecnormalize"):
        assert part in text, part
