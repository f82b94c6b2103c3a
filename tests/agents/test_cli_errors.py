"""``navgym train`` / ``navgym eval``: expected errors give one line on stderr and exit status 2."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

from agents.cli_errors import report_errors
from navgym.cli import main

ENV = "navgym/GpsInsFading-v0"


def _one_line_error(capsys, prog: str) -> str:
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert "Traceback" not in captured.err
    assert len(err.splitlines()) == 1, captured.err
    assert err.startswith(f"{prog}: error: ")
    return err


def test_train_missing_config_file(tmp_path, capsys):
    missing = tmp_path / "missing.yml"
    assert main(["train", ENV, "--config", str(missing), "--out", str(tmp_path / "run")]) == 2
    err = _one_line_error(capsys, "navgym train")
    assert "configuration file not found" in err and str(missing) in err
    assert not (tmp_path / "run").exists()


def test_train_unknown_env_id(tmp_path, capsys):
    assert main(["train", "navgym/NoSuchEnv-v0", "--out", str(tmp_path / "run")]) == 2
    err = _one_line_error(capsys, "navgym train")
    # names it, says it is unknown (not "no ppo configuration") and where the ids are
    assert "unknown env id 'navgym/NoSuchEnv-v0'" in err and "navgym list" in err


def test_train_unknown_env_id_with_own_config(tmp_path, capsys):
    cfg = tmp_path / "c.yml"
    cfg.write_text("navgym/NoSuchEnv-v0: {n_timesteps: 10}\n")
    assert main(["train", "navgym/NoSuchEnv-v0", "--config", str(cfg), "--out", str(tmp_path / "r")]) == 2
    assert "unknown environment id 'navgym/NoSuchEnv-v0'" in _one_line_error(capsys, "navgym train")


def test_train_corrupt_checkpoint_on_resume(tmp_path, capsys):
    ck = tmp_path / "run" / "checkpoints"
    ck.mkdir(parents=True)
    (ck / "model_100_steps.zip").write_text("not a zip")
    argv = ["train", ENV, "--resume", "--out", str(tmp_path / "run"), "--no-progress"]
    assert main(argv) == 2
    assert "cannot resume from checkpoint" in _one_line_error(capsys, "navgym train")


def test_agents_training_module_entry(tmp_path):
    """``python -m agents.training`` reports the same way (stderr, status 2)."""
    proc = subprocess.run(
        [sys.executable, "-m", "agents.training", ENV, "--config", str(tmp_path / "nope.yml")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("navgym train: error: configuration file not found")
    assert "Traceback" not in proc.stderr and proc.stdout == ""


def test_eval_unknown_env_id(tmp_path, capsys):
    assert main(["eval", "--env", "navgym/NoSuchEnv-v0", "--out", str(tmp_path), "--quiet"]) == 2
    assert "NoSuchEnv" in _one_line_error(capsys, "navgym eval")


def test_eval_missing_model_and_bad_spec(tmp_path, capsys):
    missing = tmp_path / "nope.zip"
    argv = ["eval", "--env", ENV, "--policies", f"ppo:{missing}", "--out", str(tmp_path), "--quiet"]
    assert main(argv) == 2
    assert str(missing) in _one_line_error(capsys, "navgym eval")
    assert main(["eval", "--env", ENV, "--policies", "bogus", "--out", str(tmp_path), "--quiet"]) == 2
    assert "unknown policy spec 'bogus'" in _one_line_error(capsys, "navgym eval")
    assert main(["eval", "--env", ENV, "--env-kwargs", "{x", "--out", str(tmp_path), "--quiet"]) == 2
    assert "--env-kwargs" in _one_line_error(capsys, "navgym eval")


def test_unexpected_errors_still_raise(capsys, monkeypatch):
    def boom():
        raise RuntimeError("a bug")

    def bare_key_error():
        return {}["x"]

    with pytest.raises(RuntimeError, match="a bug"):
        report_errors("navgym train", boom)
    with pytest.raises(KeyError):  # only the config lookup's UnknownEnvError is expected
        report_errors("navgym train", bare_key_error)
    from gymnasium.error import ResetNeeded

    def reset_needed():
        raise ResetNeeded("a bug, not an unknown env id")

    with pytest.raises(ResetNeeded):  # gymnasium errors other than unknown/malformed ids raise
        report_errors("navgym train", reset_needed)
    monkeypatch.setenv("NAVGYM_DEBUG", "1")
    with pytest.raises(FileNotFoundError):
        report_errors("navgym train", lambda: open("/no/such/file"))
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(
    ("argv", "prog", "expected"),
    [
        (["bench", "envs", "--envs", "bad/id"], "navgym bench", "Namespace bad not found"),
        (["eval", "--env", "bad/id/x", "--policies", "constant"], "navgym eval", "Malformed environment ID"),
        (
            ["eval", "--env", ENV, "--policies", "constant:badparam=1", "--episodes", "2"],
            "navgym eval",
            "unknown parameters ['badparam']",
        ),
        (
            [
                "eval",
                "--env",
                ENV,
                "--env-kwargs",
                '{"bogus": 1}',
                "--policies",
                "constant",
                "--episodes",
                "2",
            ],
            "navgym eval",
            "unexpected keyword arguments: ['bogus']",
        ),
        (["train", ENV, "--n-envs", "0"], "navgym train", "n_envs must be >= 1"),
        (["demo", "--env", "navgym/Robot2dFading-v0"], "navgym demo", "no trained agent"),
    ],
)
def test_user_errors_of_every_command_give_one_line(argv, prog, expected, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing a failing command might write lands in the checkout
    assert main(argv) == 2
    assert expected in _one_line_error(capsys, prog)
