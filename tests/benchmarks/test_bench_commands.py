"""The benchmark commands run end to end on tiny sizes, print their tables and write JSON.

Smoke tests only: no timing is asserted (benchmarks are commands, not timed tests).
"""

import json

import pytest

from navgym.cli import main


@pytest.mark.parametrize(
    "argv, header",
    [
        ("sim --batch 2 --platforms vehicle robot --steps 2 --repeats 1".split(), "sim < filter"),
        ("particles --batch 2 --particles 16 --steps 1 --repeats 1".split(), "particle-steps/s"),
        (["filters", "--batch", "2", "--filters", "ekf", "--repeats", "1", "--no-filterpy"], "B=2"),
    ],
)
def test_bench_command_prints_a_table_and_writes_json(argv, header, tmp_path, capsys):
    out = tmp_path / "bench.json"
    assert main(["bench", *argv, "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert header in text and "|" in text
    data = json.loads(out.read_text())
    assert data


def test_bench_sim_times_each_consuming_envs_own_simulation(tmp_path, capsys):
    out = tmp_path / "sim.json"
    argv = ["bench", "sim", "--batch", "2", "--platforms", "robot", "--steps", "2", "--repeats", "1"]
    assert main([*argv, "--json", str(out)]) == 0
    assert "env sim < filter" in capsys.readouterr().out
    (rec,) = json.loads(out.read_text())["results"]
    costs = rec["consumer_env_sim_ms"]
    assert set(costs) == {"navgym/Robot2dFading-v0", "navgym/Robot2dMixture-v0", "navgym/Robot2dResample-v1"}
    for c in costs.values():
        assert c["reset_ms"] > 0 and c["step_models_ms"] > 0 and c["filter_ms"] > 0
        assert c["env_sim_ms"] == pytest.approx(c["reset_ms"] + c["step_models_ms"])


def test_bench_envs_reports_steps_resets_and_whole_episodes(tmp_path, capsys):
    out = tmp_path / "envs.json"
    argv = ["bench", "envs", "--envs", "navgym/Robot2dFading-v0", "--batch", "2", "--seconds", "0.02"]
    assert main([*argv, "--json", str(out)]) == 0
    assert "env-steps/s (with resets)" in capsys.readouterr().out
    recs = json.loads(out.read_text())["results"]
    assert {r["kind"] for r in recs} == {"single (gym.make)", "native vector", "SyncVectorEnv"}
    for r in recs:
        assert 0 < r["steps_per_s_with_reset"] <= r["steps_per_s"] and r["reset_s"] > 0
    # the native / sync ratio needs the native env at B = 256, which this run did not time
    (sync,) = (r for r in recs if r["kind"] == "SyncVectorEnv")
    assert sync["native_speedup"] is None


def test_amortized_rate_adds_one_reset_per_episode():
    from benchmarks.envs import amortized_rate

    # 4096 x 300 env-steps at 100k/s take 12.288 s; a 4 s reset makes it 16.288 s
    assert amortized_rate(100_000.0, 4.0, 4096, 300) == pytest.approx(4096 * 300 / 16.288)
    assert amortized_rate(100_000.0, 0.0, 4096, 300) == pytest.approx(100_000.0)


@pytest.mark.parametrize("platform", ["vehicle", "robot", "quadrotor"])
def test_sim_truth_window_returns_the_truth_of_each_step(platform):
    # bench sim evaluates the truth for a window of steps at once; every step must see exactly
    # the trajectory at its own query times, across window boundaries
    import numpy as np

    from benchmarks.sim import _TruthWindow
    from navgym.gps_ins.vehicle import sample_vehicle_plans, vehicle_trajectory
    from navgym.quadrotor.flight import quadrotor_trajectory, sample_quadrotor_plans
    from navgym.robot2d.robot import robot_trajectory, sample_robot_plans

    seeds = [0, 1, 2]
    if platform == "vehicle":
        plan, offsets = sample_vehicle_plans(seeds), [0.0]

        def evaluate(t):
            return vehicle_trajectory(plan, t, imu=False)
    elif platform == "robot":
        plan, offsets = sample_robot_plans(seeds), [0.0, 0.02, 0.04]

        def evaluate(t):
            return robot_trajectory(plan, t)
    else:
        plan, offsets = sample_quadrotor_plans(seeds), [0.0, 0.0025]

        def evaluate(t):
            return quadrotor_trajectory(plan, t)

    dt = 0.1
    window = _TruthWindow(evaluate, dt, np.array(offsets), 4)
    for k in (0, 3, 4, 9, 5, 13):
        got = window.at(k)
        ref = evaluate(k * dt + np.array(offsets))
        for name, a, b in zip(got._fields, got, ref, strict=True):
            if a is None:
                assert b is None, name
            else:
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-9, err_msg=name)


def test_bench_commands_tune_the_allocator_first(monkeypatch, tmp_path, capsys):
    import navgym

    calls = []
    monkeypatch.setattr(navgym, "tune_malloc", lambda: calls.append("tuned") or True)
    argv = ["bench", "filters", "--batch", "2", "--filters", "kf", "--repeats", "1", "--no-filterpy"]
    assert main([*argv, "--json", str(tmp_path / "f.json")]) == 0
    assert calls == ["tuned"]
