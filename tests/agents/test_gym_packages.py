"""Ids registered outside navgym in every command: ``--gym-packages`` and the platform entry points.

A throwaway module in ``tmp_path`` registers ``mymod.../ShortRobot2dFading-v0`` (navgym's
Robot2d Fading entry with a 20-step horizon) with ``gym.register``; ``navgym eval / train / tune``
find it with ``--gym-packages MODULE`` and say how without. A platform of the
``navgym.platforms`` entry-point group (the toy platform) is found by the commands of a fresh
process, as ``import navgym`` loads it.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import uuid
from pathlib import Path

import gymnasium as gym
import pytest

from agents.cli_args import LOADED_PACKAGES, PACKAGES_VAR, PATHS_VAR, ray_runtime_env, setup_ray_worker
from navgym.cli import main

ROOT = Path(__file__).resolve().parents[2]

MODULE = """
import gymnasium as gym

import navgym  # noqa: F401

_base = gym.spec("navgym/Robot2dFading-v2")
gym.register(
    "{namespace}/ShortRobot2dFading-v0",
    entry_point=_base.entry_point,
    vector_entry_point=_base.vector_entry_point,
    max_episode_steps=20,
    kwargs=dict(_base.kwargs),
)
"""


@pytest.fixture
def mymod(tmp_path, monkeypatch):
    """``(module name, env id)`` of a fresh module in ``tmp_path`` (the current folder) registering the id."""
    name = f"mymod_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{name}.py").write_text(MODULE.format(namespace=name))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(tmp_path))])
    env_id = f"{name}/ShortRobot2dFading-v0"
    yield name, env_id
    gym.registry.pop(env_id, None)
    sys.modules.pop(name, None)
    if name in LOADED_PACKAGES:  # Ray started by a later test would import it in its workers
        LOADED_PACKAGES.remove(name)


def test_eval_finds_an_external_id_with_gym_packages(mymod, tmp_path, capsys):
    name, env_id = mymod
    args = ["eval", "--env", env_id, "--episodes", "2", "--no-plots", "--quiet", "--out", str(tmp_path / "o")]
    assert main(args) == 2  # not imported: Gymnasium's "not found", pointing to the option
    err = capsys.readouterr().err
    assert "not found" in err and "--gym-packages MODULE" in err
    assert main([*args, "--gym-packages", name]) == 0
    assert "| plain " in capsys.readouterr().out
    assert (tmp_path / "o" / "report.md").is_file()


def test_train_and_tune_find_an_external_id(mymod, tmp_path, capsys):
    name, env_id = mymod
    train = ["train", env_id, "--n-timesteps", "64", "--no-progress", "--out", str(tmp_path / "run")]
    assert main(train) == 2
    assert "--gym-packages MODULE" in capsys.readouterr().err
    assert main([*train, "--gym-packages", name]) == 0
    assert (tmp_path / "run" / "model.zip").is_file()
    tune = ["tune", "--gym-packages", name, "--env", env_id, "--baselines", "suboptimal", "--episodes", "2"]
    assert main([*tune, "--quiet", "--out", str(tmp_path / "tuned")]) == 0
    assert (tmp_path / "tuned" / "ShortRobot2dFading-v0.json").is_file()


def test_an_unknown_module_is_a_usage_error_naming_it(capsys):
    for command in (
        ["eval", "--env", "x/Y-v0"],
        ["train", "x/Y-v0"],
        ["tune", "--env", "x/Y-v0"],
        ["demo"],
        ["import", "m.zip", "out", "--env", "x/Y-v0"],
        ["export", "agent", "out"],
    ):
        with pytest.raises(SystemExit) as exit_:
            main([*command, "--gym-packages", "no_such_module_xyz"])
        assert exit_.value.code == 2
        err = capsys.readouterr().err
        assert f"navgym {command[0]}: error: argument --gym-packages" in err
        assert "cannot import module 'no_such_module_xyz' (ModuleNotFoundError" in err


def test_sweep_records_the_packages_for_its_trials(mymod, tmp_path):
    pytest.importorskip("ray")
    from agents.scale import sweep as sweep_mod

    name, env_id = mymod
    spec = sweep_mod._spec(
        env_id, "ppo", [0], {}, tmp_path / "s", 64, None, None, 2, None, None, gym_packages=[name]
    )
    assert spec["gym_packages"] == [name] and spec["gym_paths"] == [str(tmp_path.resolve())]
    plain = sweep_mod._spec(
        "navgym/Robot2dFading-v2", "ppo", [0], {}, tmp_path, 64, None, None, 2, None, None
    )
    assert "gym_packages" not in plain  # sweeps recorded before the option resume unchanged


def test_ray_workers_import_the_packages(mymod, tmp_path, monkeypatch):
    """The runtime env of ``init_ray`` has a worker import the modules from their folder."""
    name, env_id = mymod
    assert ray_runtime_env() == {}  # nothing imported: Ray starts as before
    from agents.cli_args import import_gym_packages

    import_gym_packages([name])
    env = ray_runtime_env()
    assert env["worker_process_setup_hook"] == "agents.cli_args.setup_ray_worker"
    assert env["env_vars"] == {PACKAGES_VAR: name, PATHS_VAR: str(tmp_path.resolve())}
    # a worker: another folder, neither the module nor the id
    gym.registry.pop(env_id)
    sys.modules.pop(name)
    monkeypatch.chdir("/")
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(tmp_path.resolve()))])
    for k, v in env["env_vars"].items():
        monkeypatch.setenv(k, v)
    setup_ray_worker()
    assert gym.spec(env_id).max_episode_steps == 20


@pytest.mark.slow
def test_eval_workers_find_an_external_id(mymod, tmp_path, capsys):
    pytest.importorskip("ray")
    name, env_id = mymod
    out = str(tmp_path / "o")
    args = ["eval", "--gym-packages", name, "--env", env_id, "--episodes", "4", "--workers", "2"]
    assert main([*args, "--no-plots", "--quiet", "--out", out]) == 0
    assert (tmp_path / "o" / "report.md").is_file()


#: A fresh process whose metadata has a ``navgym.platforms`` entry point naming the toy platform.
FRESH = """
import sys
from importlib import metadata

real = metadata.entry_points


def entry_points(**params):
    if params.get("group") == "navgym.platforms":
        return [metadata.EntryPoint("toy", "tests.navgym.envs.toy_platform:ENTRIES", "navgym.platforms")]
    return real(**params)


metadata.entry_points = entry_points
from navgym.cli import main

out = sys.argv[1]
env_id = "navgym-test/ToyPluginFading-v0"
codes = [
    main(["eval", "--env", env_id, "--episodes", "2", "--no-plots", "--quiet", "--out", out + "/eval"]),
    main(["tune", "--env", env_id, "--baselines", "suboptimal", "--episodes", "2", "--quiet", "--out", out]),
    main(["train", env_id, "--n-timesteps", "64", "--no-progress", "--out", out + "/run"]),
]
print("codes", codes)
"""


def test_platform_entry_point_ids_are_found_by_every_command(tmp_path):
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(FRESH), str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert "codes [0, 0, 0]" in done.stdout, done.stdout[-2000:] + done.stderr[-3000:]
    assert (tmp_path / "eval" / "report.md").is_file()
    assert (tmp_path / "ToyPluginFading-v0.json").is_file()
    assert (tmp_path / "run" / "model.zip").is_file()
