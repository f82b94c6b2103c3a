"""``navgym bench step_profile``: the stage table of a step, its timers and their removal.

No timing is asserted beyond positive times and shares that add up (benchmarks are commands,
not timed tests).
"""

from __future__ import annotations

import json

import pytest

from benchmarks import step_profile
from benchmarks.step_profile import STAGES, StageTimer, parse_config
from navgym.cli import main


def _check_record(rec: dict) -> None:
    stages = rec["stages"]
    assert list(stages) == list(STAGES)
    assert sum(s["share"] for s in stages.values()) == pytest.approx(1.0, abs=1e-9)
    total_us = sum(s["us_per_step"] for s in stages.values())
    assert total_us == pytest.approx(rec["instrumented_us_per_step"], rel=1e-9)
    for name in ("action", "models", "filter", "features", "observation", "core", "info", "shell"):
        assert stages[name]["us_per_step"] > 0 and stages[name]["calls"] >= rec["steps"], name
    assert stages["nees"]["calls"] == 0  # eval_info off
    assert rec["plain_us_per_step"] > 0 and rec["env_steps_per_s"] > 0
    # the run under cProfile: the step's calls, a few of them into compiled kernels
    assert rec["calls_per_step"] > 10 * rec["kernel_calls_per_step"]
    assert rec["kernel_calls_per_step"] >= 1 and rec["kernel_us_per_step"] > 0
    assert rec["profiled_us_per_step"] > rec["kernel_us_per_step"]


def test_bench_step_profile_prints_one_stage_table_per_config(tmp_path, capsys):
    out = tmp_path / "sp.json"
    configs = ["navgym/GpsInsFading-v2:single:1", "navgym/GpsInsFading-v2:sb3:2"]
    argv = ["bench", "step_profile", "--configs", *configs, "--steps", "4", "--repeats", "1"]
    assert main([*argv, "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| stage " in text and "us / step (plain)" in text
    for name in STAGES:
        assert f"| {name} " in text
    assert "| calls / step " in text and "kernel us / step" in text
    assert "navgym/GpsInsFading-v2, single, B = 1:" in text and "navgym/GpsInsFading-v2, sb3, B = 2:" in text
    recs = json.loads(out.read_text())["results"]
    assert [(r["kind"], r["B"], r["steps"]) for r in recs] == [("single", 1, 4), ("sb3", 2, 4)]
    for rec in recs:
        _check_record(rec)
        assert rec["stages"]["memory"]["calls"] == 4  # the v2 observation's memory features


def test_a_whole_episode_of_the_vector_env_charges_its_autoreset(tmp_path):
    # default --steps: the episode (300 steps) and the step after it, which starts the next one
    rec = step_profile.profile(parse_config("navgym/GpsInsFading-v2:vector:2"), None, False, _perf(), 1)
    assert rec["steps"] == 301
    _check_record(rec)
    assert rec["stages"]["autoreset"]["calls"] >= 3  # reset, snapshot, restore
    assert rec["stages"]["autoreset"]["us_per_step"] > 0
    assert rec["stages"]["action"]["calls"] == 301  # once a step: before the autoreset, not again after


def _perf():
    import time

    return time.perf_counter


def test_the_timers_are_removed_after_the_run():
    import navgym.envs.base as base
    import navgym.envs.core as core_module
    from navgym.envs.step_info import StepInfo

    before = (core_module._nees, base.check_single_shape, StepInfo.row, StepInfo.sb3, StepInfo.vector)
    step_profile.profile(parse_config("navgym/GpsInsFading-v2:single:1"), 2, False, _perf(), 1)
    after = (core_module._nees, base.check_single_shape, StepInfo.row, StepInfo.sb3, StepInfo.vector)
    assert after == before


def test_stage_timer_charges_each_stage_its_own_time():
    # a fake clock that advances 1 s per reading: every timer reading is a known tick
    ticks = iter(range(1000))
    timer = StageTimer(lambda: float(next(ticks)))

    def filter_step():
        return "f"

    def advance():
        # core (open) holds a filter call (closed), which holds a core-level call: untimed there
        return timer.call("filter", lambda: timer.call("features", filter_step))

    assert timer.call("shell", lambda: timer.call("core", advance)) == "f"
    # readings: shell 0, core 1, filter 2, filter 3 (features untimed inside a closed stage),
    # core 4, shell 5: filter 1 s, core 3 - 1 = 2 s, shell 5 - 3 = 2 s
    assert timer.seconds["filter"] == 1 and timer.seconds["core"] == 2 and timer.seconds["shell"] == 2
    assert timer.calls["features"] == 0 and timer.total == 5


@pytest.mark.parametrize(
    "text, message",
    [
        ("navgym/GpsInsFading-v2:vector", "ID:KIND:B"),
        ("navgym/GpsInsFading-v2:batched:4", "kind 'batched'"),
        ("navgym/GpsInsFading-v2:vector:x", "batch 'x'"),
        ("navgym/GpsInsFading-v2:vector:0", ">= 1"),
        ("navgym/GpsInsFading-v2:single:4", "B = 1"),
    ],
)
def test_parse_config_names_the_argument(text, message):
    with pytest.raises(ValueError, match="--configs") as e:
        parse_config(text)
    assert message in str(e.value)
    assert parse_config("navgym/GpsInsFading-v2:sb3:16") == step_profile.Config(
        "navgym/GpsInsFading-v2", "sb3", 16
    )


def test_threads_are_reported_and_refused_with_the_cpu_clock(tmp_path, capsys):
    out = tmp_path / "sp.json"
    argv = ["bench", "step_profile", "--configs", "navgym/Robot2dResample-v2:vector:2", "--steps", "2"]
    assert main([*argv, "--repeats", "1", "--threads", "2", "--json", str(out)]) == 0
    header = "Per-step profile (2 threads for the particle passes, random actions, wall clock"
    assert header in capsys.readouterr().out
    assert json.loads(out.read_text())["threads"] == 2
    assert main([*argv, "--threads", "2", "--clock", "cpu", "--json", str(out)]) == 2
    assert "--threads 2 needs --clock wall" in capsys.readouterr().err
    assert main([*argv, "--threads", "0", "--json", str(out)]) == 2
    assert "--threads must be >= 1; got 0" in capsys.readouterr().err
