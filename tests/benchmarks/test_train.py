"""``navgym bench train``: the PPO throughput table against the Pendulum-v1 reference.

Run with ``--quick`` (one rollout and one update per env); no timing is asserted beyond
positive rates, the ratio's definition and shares that add up.
"""

from __future__ import annotations

import json

import pytest

from benchmarks import train as bench_train
from navgym.cli import main


def test_bench_train_quick_table_json_and_markdown(tmp_path, capsys):
    ids = ["navgym/GpsInsFading-v2", "navgym/Robot2dRowScale-v3"]  # plain MLP; residual + RowSharedPolicy
    assert main(["bench", "train", "--quick", "--ids", *ids, "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    header = text[text.index("| environment") :].splitlines()[0]
    assert [h.strip() for h in header.strip("|").split("|")] == bench_train.HEADERS
    data = json.loads((tmp_path / "train.json").read_text())
    recs = data["results"]
    assert [r["env"] for r in recs] == ["Pendulum-v1 (like navgym/GpsInsFading-v2)", *ids]
    ref, fading, rowscale = recs
    # the reference has the entry's rollout shape; one rollout each (--quick)
    assert ref["vec_env"] == "DummyVecEnv" and fading["vec_env"] == "NavSB3VecEnv"
    assert rowscale["vec_env"] == "NavSB3VecEnv + residual" and rowscale["policy"] == "RowSharedPolicy"
    for key in ("n_envs", "n_steps", "batch_size", "n_epochs"):
        assert ref[key] == fading[key], key
    for r in recs:
        assert r["timesteps"] == r["n_envs"] * r["n_steps"]
        assert r["steps_per_s"] > 0
        assert r["ratio"] == pytest.approx(r["steps_per_s"] / ref["steps_per_s"], rel=1e-12)
        s = r["shares"]
        assert s["env"] + s["update"] + s["rollout_other"] == pytest.approx(1.0, abs=1e-9)
        assert 0 < s["base_env"] <= s["env"] < 1 and 0 < s["update"] < 1 and s["rollout_other"] > 0
        # the table's row shows the same figures
        assert f"| {r['env']} " in text and f"{r['ratio']:.2f}" in text
    assert fading["meta_steps_per_s"] > 0
    md = (tmp_path / "train.md").read_text()
    assert "| environment" in md and "Pendulum-v1 (like navgym/GpsInsFading-v2)" in md


def test_timed_ppo_puts_ppo_back():
    from stable_baselines3 import PPO

    learn, train = PPO.__dict__["learn"], PPO.__dict__["train"]
    with bench_train.timed_ppo():
        assert PPO.__dict__["learn"] is not learn and PPO.__dict__["train"] is not train
    assert PPO.__dict__["learn"] is learn and PPO.__dict__["train"] is train


def test_reference_needs_an_mlp_entry():
    with pytest.raises(ValueError, match="--reference-like"):
        bench_train.reference_run("navgym/Robot2dRowScale-v3", 1)


def test_timesteps_must_be_positive(tmp_path, capsys):
    import argparse

    parser = argparse.ArgumentParser()
    bench_train.add_arguments(parser)
    with pytest.raises(ValueError, match="--timesteps"):
        bench_train.run(parser.parse_args(["--timesteps", "0", "--out", str(tmp_path)]))
    # the navgym command reports it as a usage error
    assert main(["bench", "train", "--timesteps", "0", "--out", str(tmp_path)]) != 0
    assert "--timesteps must be >= 1" in capsys.readouterr().err


def test_n_envs_keeps_the_rollout_size():
    entry = {"n_envs": 16, "n_steps": 128, "batch_size": 512}
    assert bench_train.with_n_envs(entry, None) is entry
    assert bench_train.with_n_envs(entry, 64) == {"n_envs": 64, "n_steps": 32, "batch_size": 512}
    assert bench_train.with_n_envs(entry, 4096)["n_steps"] == 1
    with pytest.raises(ValueError, match="--n-envs"):
        bench_train.with_n_envs(entry, 0)
