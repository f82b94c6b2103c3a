"""The AGENT arguments of ``navgym benchmark`` and its input errors (each names what is wrong)."""

import json
import shutil
from pathlib import Path

import pytest

from agents.benchmark.agent_specs import parse_agent
from agents.benchmark.protocol import run_protocol
from navgym.cli import main

ZOO = Path(__file__).resolve().parents[3] / "agents" / "zoo"
SUPERVISED = ZOO / "Robot2dRowScale-v3-supervised"
PPO = ZOO / "Robot2dMixture-v2"


def test_a_supervised_folder():
    spec = parse_agent(str(SUPERVISED))
    assert (spec.kind, spec.env_id, spec.label) == (
        "supervised",
        "navgym/Robot2dRowScale-v3",
        SUPERVISED.name,
    )
    assert spec.seeds == [("", SUPERVISED)] and not spec.multi_seed
    assert spec.record["agent"]["table"] == json.loads((SUPERVISED / "manifest.json").read_text())["table"]


def test_an_sb3_folder_with_a_label():
    spec = parse_agent(f"ppo={PPO}")
    assert (spec.kind, spec.env_id, spec.label) == ("sb3", "navgym/Robot2dMixture-v2", "ppo")
    assert spec.record["agent"]["algo"] == "ppo"
    assert spec.train_env_kwargs == {}  # eval_info only: changes no episode
    assert spec.loaded[PPO].env_id == "navgym/Robot2dMixture-v2"


def test_a_run_with_a_model_kept_on_tuning_seeds_is_evaluated_with_that_model(tmp_path):
    run = tmp_path / "run"
    shutil.copytree(PPO, run)
    shutil.copytree(PPO, run / "best" / "step_64")
    (run / "best" / "best.json").write_text(json.dumps({"folder": "step_64", "return": -1.0}))
    spec = parse_agent(str(run))
    assert spec.record["agent"]["model"] == str(run / "best" / "step_64")
    assert spec.loaded[run].env_id == "navgym/Robot2dMixture-v2"
    (run / "best" / "best.json").write_text(json.dumps({"folder": "step_99"}))  # gone: the final model
    assert parse_agent(str(run)).record["agent"]["model"] == str(run)


def test_seed_folders_in_numeric_order(tmp_path):
    for name in ("seed_10", "seed_2", "seed_0"):
        shutil.copytree(SUPERVISED, tmp_path / "agent" / name)
    spec = parse_agent(str(tmp_path / "agent"))
    assert spec.multi_seed and [n for n, _ in spec.seeds] == ["seed_0", "seed_2", "seed_10"]
    assert spec.label == "agent" and spec.policy_label("seed_2") == "agent/seed_2"


def test_a_missing_path_is_named(tmp_path, capsys):
    bad = tmp_path / "no_such_agent"
    assert main(["benchmark", f"mine={bad}", "--quiet", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "navgym benchmark: error:" in err and str(bad) in err and "does not exist" in err
    assert not (tmp_path / "o").exists()


def test_a_folder_that_is_no_agent_is_named(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=r"empty is neither a supervised agent folder"):
        parse_agent(str(tmp_path / "empty"))
    (tmp_path / "file.zip").write_text("x")
    with pytest.raises(ValueError, match=r"file.zip is not a folder"):
        parse_agent(str(tmp_path / "file.zip"))


def test_a_changed_agent_file_is_refused(tmp_path):
    shutil.copytree(SUPERVISED, tmp_path / "sup")
    (tmp_path / "sup" / "weights.pt").write_bytes(b"not the weights")
    with pytest.raises(ValueError, match=r"agent .*sup.*weights.pt changed since it was saved"):
        parse_agent(str(tmp_path / "sup"))


def test_seed_folders_of_different_ids_are_refused(tmp_path):
    shutil.copytree(SUPERVISED, tmp_path / "a" / "seed_0")
    shutil.copytree(ZOO / "GpsInsRowScale-v3-supervised", tmp_path / "a" / "seed_1")
    with pytest.raises(ValueError, match=r"one kind and env id.*Robot2dRowScale-v3.*GpsInsRowScale-v3"):
        parse_agent(str(tmp_path / "a"))


def test_two_agents_of_one_id_need_two_labels():
    with pytest.raises(ValueError, match=r"label 'Robot2dRowScale-v3-supervised'.*LABEL=PATH"):
        run_protocol([str(SUPERVISED), str(SUPERVISED)], progress=False)


def test_nothing_to_run_and_an_id_without_a_bar(monkeypatch, tmp_path, capsys):
    with pytest.raises(ValueError, match="give at least one AGENT or --ids"):
        run_protocol([], progress=False)
    assert (
        main(["benchmark", "--ids", "Robot2dMixture-v2", "--episodes", "0", "--out", str(tmp_path / "o")])
        == 2
    )
    assert "episodes must be >= 1; got 0" in capsys.readouterr().err
    assert main(["benchmark", "--ids", "navgym/NoSuchThing-v9", "--out", str(tmp_path / "o")]) == 2
    assert "NoSuchThing" in capsys.readouterr().err
    monkeypatch.setattr("agents.baselines.registry.TUNED_DIR", tmp_path)
    with pytest.raises(FileNotFoundError, match=r"no tuned baselines for navgym/Robot2dMixture-v2"):
        run_protocol([], ["Robot2dMixture-v2"], progress=False)  # the namespace may be left out


def test_ids_restrict_and_extend_the_agents_ids():
    board = run_protocol(
        [str(SUPERVISED)],
        ["navgym/Robot2dMixture-v2"],
        2,
        env_kwargs={"episode_steps": 20, "max_episode_steps": 20},
        n_boot=50,
        seed_reps=50,
        references=False,
        progress=False,
    )
    assert list(board.results) == ["navgym/Robot2dMixture-v2"]
    assert {r["role"] for r in board.rows} == {"plain", "baseline", "bar"}  # no agent of that id
    assert any("'Robot2dRowScale-v3-supervised'" in n and "not run" in n for n in board.notes)


def test_the_readme_command_folds_one_label_in_shell_brace_form():
    from agents.benchmark.cli import braced

    got = braced(
        ["ppo=runs/Robot2dRowScale-v3", "ppo=runs/GpsInsRowScale-v3", "x=a/b", "a/c", "q=z/1", "q=z/1"]
    )
    assert got == ["ppo=runs/{Robot2d,GpsIns}RowScale-v3", "x=a/b", "a/c", "q=z/1", "q=z/1"]
