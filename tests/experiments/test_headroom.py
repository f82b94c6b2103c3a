"""experiments.headroom: the headroom arithmetic, the seeds, the constant-action grid, the quick run."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from agents.baselines import ConstantAction
from agents.seeds import RANGES
from experiments.headroom.__main__ import main, study_env, study_seeds
from experiments.headroom.candidates import action_grid
from experiments.headroom.clairvoyant import v2_ids
from experiments.headroom.gate import GATE, headroom, passes

QUICK_KW = {"episode_steps": 30, "max_episode_steps": 30}


def test_headroom_of_a_hand_example():
    # mean baseline RMSE 3, mean clairvoyant RMSE 1: headroom (3 - 1) / 3
    h = headroom(np.array([2.0, 4.0]), np.array([1.0, 1.0]), n_boot=500)
    assert h["headroom"] == pytest.approx(2.0 / 3.0)
    assert h["baseline_rmse"] == 3.0 and h["clairvoyant_rmse"] == 1.0 and h["n"] == 2
    # the resamples of two pairs: (2, 2) -> 1/2, (4, 4) -> 3/4, mixed -> 2/3
    assert 0.5 <= h["low"] <= 2.0 / 3.0 <= h["high"] <= 0.75
    assert h["significant"] and passes(h)


def test_headroom_pairs_drop_nonfinite_values_and_equal_filters_have_none():
    h = headroom(np.array([1.0, 2.0, np.nan, 3.0]), np.array([1.0, 2.0, 0.5, 3.0]))
    assert h["n"] == 3 and h["headroom"] == 0.0 and h["low"] == h["high"] == 0.0
    assert not h["significant"] and not passes(h)
    with pytest.raises(ValueError, match="equal lengths"):
        headroom(np.ones(3), np.ones(2))


def test_headroom_ci_is_a_paired_bootstrap():
    rng = np.random.default_rng(1)
    base = rng.uniform(1.0, 10.0, 300)  # large spread between episodes
    clair = 0.7 * base  # but every episode gains exactly 30 %
    h = headroom(base, clair)
    assert h["headroom"] == pytest.approx(0.3)
    assert h["low"] == pytest.approx(0.3) and h["high"] == pytest.approx(0.3)  # pairing cancels the spread


def test_gate_needs_20_percent_and_a_ci_above_zero():
    assert passes({"headroom": GATE, "low": 0.01})
    assert not passes({"headroom": 0.19, "low": 0.1})
    assert not passes({"headroom": 0.5, "low": -0.01})
    assert not passes({"headroom": float("nan"), "low": float("nan")})


def test_tuning_and_evaluation_seeds_are_disjoint():
    tune, held = study_seeds(300, 300)
    assert len(tune) == len(held) == 300 and not set(tune) & set(held)
    assert all(RANGES["tune"][0] <= s < RANGES["tune"][1] for s in tune)
    assert all(s >= RANGES["eval"][0] for s in held)
    assert max(tune) < min(held)


def test_constant_action_grid_holds_the_neutral_action():
    box2 = spaces.Box(-1.0, 1.0, (2,), np.float32)  # NoiseScale: neutral -1/3 is off the 9 levels
    g = action_grid(box2, np.array([-1 / 3, -1 / 3], np.float32))
    assert g.shape == (82, 2) and np.allclose(g[0], -1 / 3)
    box6 = spaces.Box(-1.0, 1.0, (6,), np.float32)  # per-row Mixture: the same value on every row
    g = action_grid(box6, -np.ones(6, np.float32), levels=5)
    assert g.shape == (5, 6) and (g == g[:, :1]).all() and (g[0] == -1).all()
    assert action_grid(spaces.Discrete(2), np.array(0)).tolist() == [0, 1]
    a, _ = ConstantAction(box2, g[:1, :2]).predict(np.zeros((4, 3)))
    assert a.shape == (4, 2) and a.dtype == np.float32


@pytest.mark.filterwarnings("ignore:.*Robot2dFading-v1 is out of date:DeprecationWarning")
def test_stand_in_headroom_matches_the_table():
    # a v1 id whose "clairvoyant" is the plain filter itself: the gate's numbers must be the
    # table's, and the headroom is (best - plain) / best
    tune, held = study_seeds(4, 4)
    r = study_env(
        "navgym/Robot2dFading-v1",
        tune_seeds=tune,
        eval_seeds=held,
        env_kwargs=QUICK_KW,
        clairvoyant_kwargs={},
        quick=True,
        n_boot=100,
    )
    rows = {row["policy"]: row for row in r["rows"]}
    g = r["gate"]
    assert rows["clairvoyant"]["rmse_m"] == pytest.approx(rows["plain"]["rmse_m"])
    assert rows[g["best_tuned_baseline"]]["best_tuned"]
    b, c = g["baseline_rmse_m"], g["clairvoyant_rmse_m"]
    assert b == pytest.approx(rows[g["best_tuned_baseline"]]["rmse_m"]) and c == pytest.approx(
        rows["plain"]["rmse_m"]
    )
    assert g["headroom_pct"] == pytest.approx(100.0 * (b - c) / b)
    assert {"constant", "suboptimal", "strong_tracking", "sage_husa"} <= set(rows)
    best = min(
        (row for row in r["rows"] if row["role"] in ("constant", "adaptive")), key=lambda x: x["tune_rmse_m"]
    )
    assert best["policy"] == g["best_tuned_baseline"]  # chosen on the tuning episodes


def _v2_id() -> str:
    ids = v2_ids()
    if not ids:
        pytest.skip("no -v2 id is registered yet")
    return next((i for i in ids if "Robot2dFading" in i), ids[0])


def test_quick_mode_runs_end_to_end_on_a_v2_id(tmp_path: Path):
    env_id = _v2_id()
    assert main(["--quick", "--env", env_id, "--out", str(tmp_path)]) == 0
    for name in ("table.csv", "gate.csv", "report.md", "manifest.json"):
        assert (tmp_path / name).stat().st_size > 0
    with (tmp_path / "table.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert {r["policy"] for r in rows} >= {"plain", "constant", "clairvoyant"}
    with (tmp_path / "gate.csv").open() as f:
        (gate,) = list(csv.DictReader(f))
    assert gate["env"] == env_id and gate["verdict"] in ("PASS", "FAIL") and gate["paired"] == "True"
    report = (tmp_path / "report.md").read_text()
    assert env_id in report and "Quick mode" in report
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    s = manifest["config"]["seeds"]
    assert s["tune"]["last"] < s["eval"]["first"]  # tuning seeds below the held-out ones
    assert manifest["git"]["commit"] and manifest["versions"]["numpy"]
    assert env_id in manifest["tuned"]


@pytest.fixture
def toy_ids():
    """Stand-ins of NoiseScale and per-row Mixture v2 ids: the linear toy of the v2 task tests."""
    from tests.navgym.envs.toy_v2 import ToyEnv, ToyVectorEnv

    kw = {"truth_r_scale": 4.0, "bias": (3.0, -3.0), "memory_features": True}
    ids = {
        "navgym-test/ToyNoiseScale-v2": {"task": "noisescale", **kw},
        "navgym-test/ToyMixture-v2": {"task": "mixture", "per_row": True, **kw},
    }
    for env_id, kwargs in ids.items():
        gym.register(env_id, entry_point=ToyEnv, vector_entry_point=ToyVectorEnv, kwargs=kwargs)
    yield list(ids)
    for env_id in ids:
        del gym.registry[env_id]


def _study(env_id: str) -> dict:
    tune, held = study_seeds(4, 4)
    return study_env(env_id, tune_seeds=tune, eval_seeds=held, quick=True, action_levels=3, n_boot=50)


def test_noise_scale_and_per_row_mixture_stand_ins(toy_ids):
    noise, mixture = (_study(i) for i in toy_ids)
    assert {r["policy"] for r in noise["rows"]} == {
        "plain",
        "constant",
        "iae",
        "sage_husa",
        "iae_q",
        "clairvoyant",
    }
    assert {r["policy"] for r in mixture["rows"]} == {
        "plain",
        "constant",
        "chi_square",
        "innovation_avg",
        "huber",
        "clairvoyant",
    }  # the per-row Mixture baselines (baseline_task "RowMixture"), not the v1 ones
    for r in (noise, mixture):
        assert not any("does not run" in n for n in r["notes"])
        assert r["tuned"]["constant"]["source"] == "agents.baselines"
        # the toy's truth (R x 4, biased fixes) leaves room
        assert r["gate"]["clairvoyant_rmse_m"] < r["gate"]["baseline_rmse_m"] and r["gate"]["paired"]


def test_a_task_without_baselines_gets_a_constant_action_grid(toy_ids, monkeypatch):
    from agents.baselines import registry

    monkeypatch.setitem(registry.BASELINES, "NoiseScale", {})
    r = _study(toy_ids[0])
    assert {row["policy"] for row in r["rows"]} == {"plain", "constant", "clairvoyant"}
    assert r["gate"]["adaptive_baselines"] == "none" and r["gate"]["best_tuned_baseline"] == "constant"
    assert r["tuned"]["constant"]["grid_points"] == 10  # 3 x 3 levels and the neutral (-1/3, -1/3)
    assert any("no classical adaptive baseline" in n for n in r["notes"])


def test_the_gated_error_must_be_known():
    with pytest.raises(ValueError, match="error must be one of"):
        study_env("navgym/Robot2dFading-v2", tune_seeds=[0], eval_seeds=[0], error="doppler")
