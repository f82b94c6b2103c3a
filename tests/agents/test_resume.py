"""Checkpoints as atomic units, resume from the newest valid one, and resume of a finished run."""

from __future__ import annotations

import hashlib
import importlib
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

from agents.training import AgentLoadError, latest_checkpoint, load_agent, train, train_cli
from agents.training.loading import read_normalization, verify_manifest

#: The module (``agents.training.train`` the attribute is the function of the same name).
train_module = importlib.import_module("agents.training.train")

ENV = "navgym/GpsInsFading-v0"
SHORT = {"episode_steps": 50, "max_episode_steps": 50}
#: 4 sub-envs x 64 steps = 256 steps per rollout; a checkpoint every 512 steps.
TINY = {
    "n_envs": 4,
    "n_timesteps": 1024,
    "policy": "MlpPolicy",
    "normalize": {"norm_obs": True, "norm_reward": True},
    "env_kwargs": {"eval_info": False, **SHORT},
    "n_steps": 64,
    "batch_size": 128,
    "n_epochs": 2,
    "learning_rate": 1.0e-3,
    "policy_kwargs": {"net_arch": [16, 16]},
    "checkpoint_freq": 512,
}


class _Killed(BaseException):
    """Stands for the process being killed (not an Exception: nothing may catch it)."""


def _train(out: Path, **kw):
    kw.setdefault("config", TINY)
    return train(ENV, "ppo", seed=1, out_dir=out, progress=False, tensorboard=False, **kw)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _steps(out: Path) -> list[int]:
    return sorted(int(p.name.split("_")[1]) for p in (out / "checkpoints").glob("step_*"))


def test_kill_between_model_and_statistics_leaves_no_half_checkpoint(tmp_path, monkeypatch):
    """A kill after SB3 saved the model but before the statistics were written: the checkpoint
    does not exist (not a model without statistics); resume continues the older one's statistics."""
    out = tmp_path / "run"
    real = train_module.save_normalization

    def killed_at_1024(vec_normalize, path):
        if "step_1024" in str(path):
            assert (Path(path).parent / "model.zip").is_file()  # SB3's model save has happened
            raise _Killed
        return real(vec_normalize, path)

    monkeypatch.setattr(train_module, "save_normalization", killed_at_1024)
    with pytest.raises(_Killed):
        _train(out)
    monkeypatch.undo()
    assert _steps(out) == [512]
    assert not (out / "model.zip").exists()
    model, stats, n = latest_checkpoint(out)
    assert n == 512 and stats is not None
    count_at_512 = float(read_normalization(stats)["count"])

    _train(out, config=None, resume=True)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["resumed_from_timesteps"] == 512 and meta["total_timesteps"] == 1024
    # The statistics continued from the checkpoint's (not restarted): more observations than at 512.
    assert float(read_normalization(out / "vecnormalize.npz")["count"]) > count_at_512
    assert not list((out / "checkpoints").glob(".*"))  # the interrupted save's temporary is gone
    assert _steps(out) == [512, 1024]
    for step in _steps(out):
        verify_manifest(out / "checkpoints" / f"step_{step}")


def test_resume_falls_back_from_a_truncated_checkpoint(tmp_path):
    out = tmp_path / "run"
    _train(out)
    assert _steps(out) == [512, 1024]
    (out / "manifest.json").unlink()  # interrupted before the final agent was complete
    newest = out / "checkpoints" / "step_1024" / "model.zip"
    newest.write_bytes(newest.read_bytes()[: newest.stat().st_size // 2])  # truncated
    with pytest.warns(UserWarning, match=r"skipping checkpoint .*step_1024"):
        assert latest_checkpoint(out)[2] == 512
    with pytest.warns(UserWarning, match=r"skipping checkpoint .*step_1024"):
        _train(out, config=None, resume=True)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["resumed_from_timesteps"] == 512 and meta["total_timesteps"] == 1024
    assert load_agent(out).model.num_timesteps == 1024
    verify_manifest(out / "checkpoints" / "step_1024")  # written again, whole

    # No valid checkpoint and no final agent: an error, not a silent fresh start.
    (out / "manifest.json").unlink()
    for step in _steps(out):
        (out / "checkpoints" / f"step_{step}" / "vecnormalize.npz").write_bytes(b"")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(AgentLoadError, match="cannot resume from checkpoint"):
            _train(out, config=None, resume=True)


def test_resume_of_a_finished_run_does_nothing(tmp_path, capsys):
    out = tmp_path / "run"
    _train(out)
    before = {p.name: _sha(p) for p in out.iterdir() if p.is_file()}
    checkpoints = _steps(out)
    argv = [ENV, "--seed", "1", "--out", str(out), "--resume", "--no-progress"]
    assert train_cli(argv) == 0
    printed = capsys.readouterr().out
    assert "already finished 1,024 timesteps" in printed and "nothing to do" in printed
    assert train_cli([*argv, "--timesteps", "1024"]) == 0  # the same total, given explicitly
    assert "already finished" in capsys.readouterr().out
    assert _train(out, config=None, resume=True) == out  # the library call too
    assert "already finished" in capsys.readouterr().out
    assert {p.name: _sha(p) for p in out.iterdir() if p.is_file()} == before
    assert _steps(out) == checkpoints
    # More timesteps: it continues from where it finished.
    assert train_cli([*argv, "--timesteps", "1280"]) == 0
    meta = json.loads((out / "meta.json").read_text())
    assert meta["resumed_from_timesteps"] == 1024 and meta["total_timesteps"] == 1280


def test_sac_checkpoint_keeps_its_replay_buffer(tmp_path):
    """Off-policy: the checkpoint unit holds the replay buffer as plain arrays, and resume refills
    the buffer from it (nothing unpickled)."""
    cfg = {
        "n_envs": 4,
        "n_timesteps": 512,
        "policy": "MlpPolicy",
        "normalize": True,
        "env_kwargs": {"eval_info": False, **SHORT},
        "buffer_size": 2000,
        "learning_starts": 128,
        "batch_size": 32,
        "train_freq": 1,
        "gradient_steps": 1,
        "learning_rate": "lin_1e-3",
        "policy_kwargs": {"net_arch": [16, 16]},
        "checkpoint_freq": 256,
        "save_replay_buffer": True,
    }
    out = tmp_path / "sac"
    train(ENV, "sac", config=cfg, seed=2, out_dir=out, progress=False, tensorboard=False)
    ck = out / "checkpoints" / "step_512"
    assert "replay_buffer.npz" in verify_manifest(ck)["files"]
    (out / "manifest.json").unlink()
    seen = {}
    real = train_module.load_replay_buffer

    def spy(buffer, path):
        ok = real(buffer, path)
        seen["pos"], seen["ok"] = buffer.pos, ok
        return ok

    train_module.load_replay_buffer = spy
    try:
        train(
            ENV,
            "sac",
            seed=2,
            total_timesteps=640,
            out_dir=out,
            resume=True,
            progress=False,
            tensorboard=False,
        )
    finally:
        train_module.load_replay_buffer = real
    with np.load(ck / "replay_buffer.npz") as saved:  # the transitions stored by step 512
        assert seen == {"pos": int(saved["pos"]), "ok": True} and seen["pos"] >= 512 // 4 - 1
    assert load_agent(out).model.num_timesteps == 640
