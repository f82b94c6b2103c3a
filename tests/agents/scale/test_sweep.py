"""navgym sweep: trial specs, the summary over seeds, the missing extra, and (slow) sweeps on local Ray."""

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from agents.scale.specs import apply_overrides, grid_configs, make_trials, parse_grid, parse_seeds
from agents.scale.summary import seed_ci, summarize_trials, summary_table

ENV = "navgym/Robot2dFading-v1"
ROOT = Path(__file__).resolve().parents[3]
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def test_parse_seeds():
    assert parse_seeds("0..3") == [0, 1, 2, 3]
    assert parse_seeds("5,2,9") == [5, 2, 9]
    assert parse_seeds("0..1,7") == [0, 1, 7]
    assert parse_seeds([3, 4]) == [3, 4]
    for bad in ("3..1", "a", "1,1", "-1", ""):
        with pytest.raises(ValueError, match="seeds"):
            parse_seeds(bad)


def test_parse_grid_and_trials():
    grid = parse_grid(["learning_rate=1e-4,3e-4", "policy_kwargs.net_arch=[32, 32],[64]"])
    assert grid == {"learning_rate": [1e-4, 3e-4], "policy_kwargs.net_arch": [[32, 32], [64]]}
    configs = grid_configs(grid)
    assert len(configs) == 4 and configs[1] == {"learning_rate": 1e-4, "policy_kwargs.net_arch": [64]}
    entry = {"n_envs": 2, "learning_rate": 3e-4, "policy_kwargs": {"net_arch": [8], "activation_fn": "tanh"}}
    e = apply_overrides(entry, configs[1])
    assert e["policy_kwargs"] == {"net_arch": [64], "activation_fn": "tanh"} and e["learning_rate"] == 1e-4
    assert entry["policy_kwargs"]["net_arch"] == [8]  # not changed in place
    trials = make_trials(entry, grid, [0, 1])
    assert [(t.config, t.seed) for t in trials] == [(c, s) for c in range(4) for s in (0, 1)]
    assert trials[3].name == "c01_seed1" and trials[3].entry == e
    assert grid_configs({}) == [{}]
    for bad in (["lr"], ["=1"], ["a=1", "a=2"]):
        with pytest.raises(ValueError, match="grid"):
            parse_grid(bad)


def test_seed_ci_is_the_t_interval():
    mean, lo, hi, n = seed_ci([1.0, 2.0, 3.0, 4.0])
    # t(0.975, 3) = 3.1824; sd = 1.29099; half-width = 3.1824 * 1.29099 / 2
    assert (mean, n) == (2.5, 4) and hi - mean == pytest.approx(3.182446 * 1.290994 / 2, rel=1e-5)
    assert lo == pytest.approx(2 * mean - hi)
    m1, lo1, hi1, n1 = seed_ci([7.0, float("nan")])
    assert (m1, n1) == (7.0, 1) and math.isnan(lo1) and math.isnan(hi1)


def test_summary_per_config():
    rows = [
        {
            "config_id": c,
            "seed": s,
            "return": 10.0 * c + s,
            "rmse_m": 1.0,
            "diverged": 0.0,
            "train_wall_s": 2.0,
        }
        for c in (0, 1)
        for s in (0, 1, 2)
    ]
    summary = summarize_trials(rows, ["a", "b"])
    assert [r["seeds"] for r in summary] == [3, 3]
    assert (
        summary[1]["return"] == pytest.approx(11.0)
        and summary[0]["return_lo"] < 1.0 < summary[0]["return_hi"]
    )
    table = summary_table(summary)
    assert table.count("\n") == 4 and table.endswith(" |\n") and "| b | 3 | 11.0 [" in table
    assert table.splitlines()[1] == "|---|---:|---:|---:|---:|---:|"


def test_without_ray_the_command_says_how_to_get_it(monkeypatch, capsys):
    from navgym.cli import main

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ModuleNotFoundError
    assert main(["sweep", ENV, "--seeds", "0..1"]) == 2
    err = capsys.readouterr().err
    assert "navgym sweep: needs the 'scale' extra (missing module 'ray')" in err
    assert "pip install -e '.[scale]'" in err


def test_bad_arguments_exit_2(capsys):
    pytest.importorskip("ray")
    from navgym.cli import main

    assert main(["sweep", ENV, "--seeds", "2..1"]) == 2
    assert "navgym sweep: error: --seeds" in capsys.readouterr().err


# --- on local Ray (2 CPUs) ------------------------------------------------------------------

TINY = ["--timesteps", "1024", "--n-envs", "4", "--eval-episodes", "4", "--num-cpus", "2", "--quiet"]


@pytest.mark.slow
def test_two_trial_sweep_writes_its_summary(tmp_path, capsys):
    pytest.importorskip("ray")
    from agents.scale.sweep import sweep

    res = sweep(
        ENV,
        "ppo",
        "0..1",
        ["gamma=0.9"],
        tmp_path / "sw",
        timesteps=1024,
        n_envs=4,
        eval_episodes=4,
        num_cpus=2,
        verbose=0,
    )
    assert not res.errors and not res.resumed
    assert [(r["config_id"], r["seed"]) for r in res.trials] == [(0, 0), (0, 1)]
    assert all(r["timesteps"] == 1024 and math.isfinite(r["return"]) for r in res.trials)
    assert res.summary[0]["seeds"] == 2 and res.summary[0]["label"] == "gamma=0.9"
    out = tmp_path / "sw"
    assert "| gamma=0.9 | 2 |" in (out / "summary.md").read_text()
    assert (out / "trials.csv").read_text().count("\n") == 3 and (out / "summary.csv").is_file()
    for seed in (0, 1):  # each trial: a navgym run folder (agent, TensorBoard logs) and its evaluation
        run = out / "trials" / f"c00_seed{seed}"
        assert (run / "manifest.json").is_file() and any((run / "tb").iterdir())
        assert (run / "config.yml").read_text().startswith(f"env_id: {ENV}")
        assert json.loads((run / "eval.json").read_text())["seed"] == seed
    import yaml

    assert yaml.safe_load((out / "trials" / "c00_seed1" / "config.yml").read_text())["gamma"] == 0.9
    # the same sweep again: Tune restores the finished experiment, nothing is retrained
    again = sweep(
        ENV, "ppo", "0..1", ["gamma=0.9"], out, timesteps=1024, n_envs=4, eval_episodes=4, verbose=0
    )
    assert again.resumed and [r["return"] for r in again.trials] == [r["return"] for r in res.trials]
    with pytest.raises(ValueError, match="another sweep"):
        sweep(ENV, "ppo", "0..2", ["gamma=0.9"], out, timesteps=1024, n_envs=4, eval_episodes=4, verbose=0)


def _checkpoints(out: Path) -> list[Path]:
    return sorted(out.glob("trials/*/checkpoints/step_*"))


@pytest.mark.slow
def test_killed_sweep_resumes(tmp_path):
    pytest.importorskip("ray")
    out = tmp_path / "sw"
    args = [ENV, "--seeds", "0..1", "--timesteps", "12288", "--n-envs", "4", "--checkpoint-freq", "1024"]
    args += ["--eval-episodes", "4", "--num-cpus", "2", "--quiet", "--out", str(out)]
    cmd = [sys.executable, "-m", "agents.scale.sweep", *args]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.time() + 240
        while not _checkpoints(out) and time.time() < deadline and proc.poll() is None:
            time.sleep(0.5)
        assert _checkpoints(out), "no checkpoint before the deadline"
        assert proc.poll() is None, "the sweep finished before it could be killed"
        os.killpg(proc.pid, signal.SIGKILL)  # the driver, local Ray and its workers: a hard crash
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert not (out / "summary.md").exists()
    time.sleep(1)
    from agents.scale.sweep import main

    assert main(args) == 0
    done = [json.loads(p.read_text()) for p in sorted(out.glob("trials/*/eval.json"))]
    assert [d["seed"] for d in done] == [0, 1] and all(d["timesteps"] == 12288 for d in done)
    assert any(d["resumed_from"] for d in done), "no trial resumed its training from a checkpoint"
    assert "resumed" in (out / "summary.md").read_text()
