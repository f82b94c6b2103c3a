"""experiments.learned_v3: train a tiny residual agent, evaluate it paired with the bar, export it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")

from experiments.learned_v3.__main__ import (
    compare,
    evaluate_all,
    export_zoo,
    median_seed,
    met,
    seed_dirs,
    train_all,
)
from tests.agents.training.tiny import ENV, tiny_row_scale_entry

TINY = {ENV: tiny_row_scale_entry(eval_freq=64, eval_episodes=2)}


def test_compare_pairs_each_seed_and_the_mean_of_seeds_with_the_bar():
    rng = np.random.default_rng(0)
    bar = rng.uniform(2.0, 3.0, 200)
    rm = {"bar": bar, "supervised": 0.8 * bar, "ppo seed_0": 0.7 * bar, "ppo seed_1": 0.9 * bar}
    r = compare(rm, "bar", ["ppo seed_0", "ppo seed_1"], n_boot=300)
    assert r["mean_vs_bar"]["delta_pct"] == pytest.approx(-20.0)
    assert r["seed_range_pct"] == pytest.approx([-30.0, -10.0])
    assert r["mean_vs_supervised"]["delta_pct"] == pytest.approx(0.0, abs=1e-9)
    assert met(r["mean_vs_bar"]) and not met(r["per_seed"]["ppo seed_1"])


def test_train_evaluate_and_export_the_median_seed(tmp_path: Path, monkeypatch):
    import experiments.learned_v3.__main__ as v3

    cfg = tmp_path / "tiny.yml"
    cfg.write_text(yaml.safe_dump(TINY))
    runs = tmp_path / "runs"
    done = train_all([ENV], [0, 1], runs, None, jobs=1, config=str(cfg))
    assert [d["seed"] for d in done] == [0, 1]
    dirs = seed_dirs(runs, ENV)
    assert [d.name for d in dirs] == ["seed_0", "seed_1"]
    assert all((d / "best" / "best.json").is_file() for d in dirs)
    cache = tmp_path / "sets"
    (r,) = evaluate_all([ENV], runs, episodes=3, shift_episodes=0, jobs=1, n_boot=100, cache=cache)
    assert len(list(cache.glob("*.json"))) == 1

    def fail(job):
        raise AssertionError("a cached set is evaluated again")

    monkeypatch.setattr(v3, "_evaluate_set", fail)
    (again,) = evaluate_all([ENV], runs, episodes=3, shift_episodes=0, jobs=1, n_boot=100, cache=cache)
    assert again == json.loads(json.dumps(r))
    assert r["set"] == "held-out" and r["bar"] == "row_iae"
    assert set(r["per_episode_rmse_m"]) == {"plain", "row_iae", "supervised", "ppo seed_0", "ppo seed_1"}
    assert all(len(v) == 3 for v in r["per_episode_rmse_m"].values())
    chosen = median_seed(dirs)
    dest = export_zoo(ENV, runs, zoo=tmp_path / "zoo")
    assert dest.name == "Robot2dRowScale-v3" and (dest / "model.zip").is_file()
    assert f"({chosen.name})" in (dest / "README.md").read_text()
    assert json.loads((dest / "meta.json").read_text())["seed"] == int(chosen.name.split("_")[1])


def test_summary_rows_give_held_out_and_shifts_per_id():
    from experiments.learned_v3.__main__ import summary_rows

    rng = np.random.default_rng(1)
    bar = rng.uniform(2.0, 3.0, 100)
    rm = {"row_iae": bar, "supervised": 0.8 * bar, "ppo seed_0": 0.75 * bar, "ppo seed_1": 0.8 * bar}
    held = {"env_id": ENV, "set": "held-out", **compare(rm, "row_iae", ["ppo seed_0", "ppo seed_1"], 200)}
    shifted = {**held, "set": "longer events"}
    (row,) = summary_rows([held, shifted])
    assert row["id"] == "`Robot2dRowScale-v3`" and row["target"] == "met"
    assert row["PPO vs bar % [95% CI]"].startswith("-22.5 [")
    assert row["vs bar % on shifts"] == "-22.5"


def test_an_id_without_a_supervised_agent_is_compared_with_the_bar_only():
    from experiments.learned_v3.__main__ import summary_rows, table_rows

    rng = np.random.default_rng(2)
    bar = rng.uniform(8.0, 10.0, 100)
    rm = {"constant": bar, "ppo seed_0": 0.7 * bar, "ppo seed_1": 0.9 * bar}
    r = compare(rm, "constant", ["ppo seed_0", "ppo seed_1"], n_boot=200)
    assert "mean_vs_supervised" not in r and "supervised_vs_bar" not in r
    assert r["mean_vs_bar"]["delta_pct"] == pytest.approx(-20.0)
    res = {"env_id": "navgym/PedestrianNoiseScale-v3", "set": "held-out", "episodes": 100, **r}
    (row,) = table_rows([res])
    assert row["supervised m"] == "n/a" and row["PPO vs supervised %"] == "n/a"
    (short,) = summary_rows([res])
    assert "/ n/a /" in short["RMSE m: bar / supervised / PPO"] and short["target"] == "met"


def test_replay_rows_give_each_policy_against_plain_and_the_bar():
    from agents.evaluation.comparison import delta_rmse
    from experiments.learned_v3.replay import replay_rows

    rng = np.random.default_rng(3)
    plain = rng.uniform(1.0, 2.0, 50)
    rm = {"plain": plain, "row_iae": 0.9 * plain, "PPO (QuadrotorRowScale-v3)": 1.2 * plain}
    res = {
        "bar": "row_iae",
        "rmse_m": {k: float(v.mean()) for k, v in rm.items()},
        "vs_plain": {k: delta_rmse(v, plain, 200) for k, v in rm.items() if k != "plain"},
        "vs_bar": {
            "PPO (QuadrotorRowScale-v3)": delta_rmse(rm["PPO (QuadrotorRowScale-v3)"], rm["row_iae"], 200)
        },
    }
    rows = {r["policy"]: r for r in replay_rows(res)}
    assert rows["`plain`"]["vs plain % [95% CI]"] == "" and rows["`row_iae`"]["role"].startswith("bar")
    assert rows["`row_iae`"]["vs plain % [95% CI]"].startswith("-10.0 [")
    assert rows["`PPO (QuadrotorRowScale-v3)`"]["vs bar % [95% CI]"].startswith("+33.3 [")


def test_readme_rows_of_ids_not_evaluated_are_kept(tmp_path: Path):
    from experiments.learned_v3.__main__ import BEGIN, END, merged_table

    head = "| id | set |\n|---|---|\n"
    old = head + "| `Robot2dRowScale-v3` | held-out |\n| `PedestrianNoiseScale-v3` | old |\n"
    readme = tmp_path / "README.md"
    readme.write_text(f"text\n{BEGIN}\n{old}\nfoot\n{END}\nmore\n")
    new = head + "| `PedestrianNoiseScale-v3` | held-out |\n| `QuadrotorRowScale-v3` | held-out |\n"
    out = merged_table(readme, new, ["navgym/PedestrianNoiseScale-v3", "navgym/QuadrotorRowScale-v3"])
    assert out.splitlines()[2:] == [
        "| `Robot2dRowScale-v3` | held-out |",
        "| `QuadrotorRowScale-v3` | held-out |",
        "| `PedestrianNoiseScale-v3` | held-out |",
    ]
    other = "| id | other |\n|---|---|\n| `Robot2dRowScale-v3` | x |\n"
    assert merged_table(readme, other, ["navgym/Robot2dRowScale-v3"]) == other  # other columns: no merge


def test_replay_quick_scores_the_quadrotor_agents_on_the_walk(tmp_path: Path):
    from experiments.learned_v3.__main__ import main

    assert main(["replay", "--quick", "--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "replay.json").read_text())
    assert res["env_id"] == "navgym/ReplayRowScale-v3" and res["episodes"] == 8
    names = set(res["per_episode_rmse_m"])
    assert {"plain", res["bar"], "PPO (QuadrotorRowScale-v3)", "supervised (QuadrotorRowScale-v3)"} <= names
    assert all(len(v) == 8 and np.isfinite(v).all() for v in res["per_episode_rmse_m"].values())
