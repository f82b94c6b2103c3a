"""experiments.learned_v2: the shifts, the tables and a tiny end-to-end run.

The numbers (ΔRMSE %, capture, verdict): tests/agents/test_comparison.py.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from experiments.learned_v2.__main__ import (
    BEGIN,
    END,
    HELD_OUT,
    ROOT,
    STUDY_README,
    best_tuned,
    full_table,
    main,
    plain_baseline,
    replace_block,
    summary_table,
    verdict,
)
from experiments.learned_v2.shifts import (
    PLATFORMS,
    SHIFT_KWARGS,
    SHIFTS,
    Shift,
    apply_shift,
    platform_of,
)

ENV = "navgym/Robot2dNoiseScale-v2"


# ----------------------------------------------------------------------------------- shifts
@pytest.mark.parametrize("platform", sorted(PLATFORMS))
def test_shifts_are_the_documented_rules_on_the_platform_defaults(platform: str):
    p = PLATFORMS[platform]
    ev, kw = p.events, SHIFT_KWARGS[platform]
    T = p.spec.episode_steps * p.spec.dt
    cap = T - min(p.spec.start_margin_s, 0.1 * T)
    durations = [k for k in ev if k.endswith("_duration")]
    counts = [k for k in ev if k.endswith("_count")]
    assert {"burst_duration", "multipath_duration", "jamming_duration"} <= set(durations)
    assert kw["longer events"] == {k: (min(2 * ev[k][0], cap), min(2 * ev[k][1], cap)) for k in durations}
    stronger = {"burst_velocity_sigma": 2, "multipath_bias": 2, "jamming_sigma": 2, "canyon_noise_scale": 1.5}
    assert kw["stronger events"] == {k: (f * ev[k][0], f * ev[k][1]) for k, f in stronger.items()}
    limit = p.count_caps
    assert kw["more events"] == {
        k: (min(ev[k][0] + 2, limit.get(k, 99)), min(ev[k][1] + 2, limit.get(k, 99))) for k in counts
    }
    assert all(isinstance(v, int) for k in counts for v in kw["more events"][k])
    untouched = {"jamming_ramp", "canyon_satellites", "burst_yaw_rate_sigma", "multipath_rows", "canyon_loss"}
    assert not untouched & {k for s in kw.values() for k in s}


def test_shift_ranges_of_robot2d_by_hand():
    kw = SHIFT_KWARGS["Robot2d"]  # defaults: bursts 2-15 s, 0.5-3 m/s; canyons x2-5; outages 1-3
    assert kw["longer events"]["burst_duration"] == (4.0, 30.0)
    assert kw["longer events"]["multipath_duration"] == (16.0, 50.0)
    assert kw["stronger events"]["burst_velocity_sigma"] == (1.0, 6.0)
    assert kw["stronger events"]["canyon_noise_scale"] == (3.0, 7.5)
    assert kw["more events"]["outage_count"] == (3, 5) and kw["more events"]["burst_count"] == (4, 6)
    assert platform_of(ENV) == "Robot2d" and platform_of("navgym/GpsInsMixture-v2") == "GpsIns"


def test_apply_shift_caps_durations_and_counts():
    rule = Shift("x", factors={"*_duration": 2.0}, cap_durations=True)
    assert apply_shift(rule, {"a_duration": (10.0, 40.0), "a_sigma": (1.0, 2.0)}, 50.0) == {
        "a_duration": (20.0, 50.0)
    }
    more = SHIFTS["more events"]
    assert apply_shift(more, {"multipath_count": (5, 7)}, count_caps={"multipath_count": 8}) == {
        "multipath_count": (7, 8)
    }
    with pytest.raises(ValueError, match="range"):
        apply_shift(more, {"outage_count": 3})


# --------------------------------------------------------------------------- ids and tables
def test_reference_is_the_best_tuning_score(tmp_path: Path):
    assert best_tuned(ENV)[0] == "sage_husa"  # the committed tuned file
    f = tmp_path / "t.json"
    f.write_text(
        json.dumps({"baselines": {"a": {"score": -2.0}, "b": {"score": -1.0}, "c": {"score": -1.0}}})
    )
    assert best_tuned(ENV, f) == ("b", -1.0)  # ties: the first in the file
    with pytest.raises(FileNotFoundError, match="navgym tune"):
        best_tuned(ENV, tmp_path / "missing.json")
    assert plain_baseline(ENV) == "plain" and plain_baseline("navgym/Robot2dMixture-v2") == "zero"
    assert plain_baseline("navgym/Robot2dResample-v2") is None


def _row(env: str, set_name: str, capture: dict | None, delta: float = -12.5) -> dict:
    pol = {
        "agent": {"rmse_m": 2.0, "p95_err_m": 3.0, "outage_end_err_m": 4.0},
        "ref": {"rmse_m": 2.5, "p95_err_m": 3.5, "outage_end_err_m": 4.5},
    }
    for m in pol.values():
        m.update({"nees_median": 3.0, "diverged_pct": 0.0, "return": -10.0})
    if capture is not None:
        pol["clairvoyant"] = {**pol["ref"], "rmse_m": 1.0}
    return {
        "env": env,
        "set": set_name,
        "seeds": {"n": 4},
        "reference": "ref",
        "plain": None,
        "agent": "agent",
        "policies": pol,
        "delta_rmse": {"delta_pct": delta, "low_pct": delta - 1, "high_pct": delta + 1},
        "capture": capture,
        "verdict": verdict(delta, delta - 1, delta + 1),
        "error": None,
    }


def test_tables_and_the_readme_block(tmp_path: Path):
    rows = [
        _row("navgym/X-v2", HELD_OUT, {"capture": 0.25, "low": 0.1, "high": 0.4}),
        _row("navgym/X-v2", "more events", {"capture": 0.2, "low": 0.1, "high": 0.3}),
        _row("navgym/XResample-v2", HELD_OUT, None, delta=3.0),
        {
            "env": "navgym/Y-v2",
            "set": "longer events",
            "reference": "ref",
            "error": "no kwarg",
            "verdict": "not run",
        },
    ]
    summary = summary_table(rows)
    assert summary.count("\n| `navgym/") == 2  # the held-out rows only
    held = "| `navgym/X-v2` | `ref` | 2.00 / 2.50 / 1.00 | -12.5 [-13.5, -11.5] | 25.0 [10.0, 40.0] |"
    assert held + " target met |" in summary
    assert "| 2.00 / 2.50 / n/a | +3.0 [2.0, 4.0] | n/a | worse | - / - / - |" in summary
    assert "ΔRMSE % on shifts: longer / stronger / more |" in summary
    more = rows[1]["delta_rmse"]["delta_pct"]
    assert f"target met | - / - / {more:+.1f} |" in summary
    full = full_table(rows)
    assert full.count("\n| `navgym/") == 4 and "| no kwarg |" in full and full.rstrip().endswith("not run |")
    readme = tmp_path / "README.md"
    readme.write_text(f"# t\n\n{BEGIN}\nold\n{END}\n\nafter\n")
    replace_block(readme, "new table")
    assert readme.read_text() == f"# t\n\n{BEGIN}\nnew table\n{END}\n\nafter\n"
    (tmp_path / "bare.md").write_text("no markers")
    with pytest.raises(ValueError, match="block"):
        replace_block(tmp_path / "bare.md", "x")


# ------------------------------------------------------------------------------- end to end
@pytest.fixture
def robot2d_events_but_burst_duration(monkeypatch: pytest.MonkeyPatch) -> None:
    """Robot2d v2 takes every event range as an env kwarg except ``burst_duration``."""
    from navgym.robot2d import env_v2
    from navgym.robot2d.env import V2_EVENTS

    spec = env_v2.ROBOT2D_V2
    names = tuple(k for k in dict.fromkeys((*spec.scenario_arguments, *V2_EVENTS)) if k != "burst_duration")
    patched = replace(spec, scenario_arguments=names)
    for cls in (env_v2.Robot2dEnv, env_v2.Robot2dVectorEnv):
        monkeypatch.setattr(cls, "platform_spec", patched)


@pytest.fixture
def dev_agent(tmp_path: Path) -> Path:
    """A residual PPO agent of a few hundred steps (about 4 s), trained here."""
    import yaml

    from agents.training import train

    entry = {
        "n_envs": 2,
        "n_timesteps": 256,
        "policy": "MlpPolicy",
        "normalize": {"norm_obs": True, "norm_reward": True},
        "residual": {"baseline": "sage_husa", "params": "tuned", "scale": 0.5, "observe_base": True},
        "n_steps": 128,
        "batch_size": 128,
        "n_epochs": 1,
        "policy_kwargs": {"net_arch": [16, 16]},
    }
    config = tmp_path / "ppo.yml"
    config.write_text(yaml.safe_dump({ENV: entry}))
    agents = tmp_path / "agents"
    train(
        ENV,
        algo="ppo",
        config=config,
        total_timesteps=256,
        out_dir=agents / ENV.split("/")[-1],
        progress=False,
    )
    return agents


def test_tiny_run_end_to_end(tmp_path: Path, dev_agent: Path, robot2d_events_but_burst_duration: None):
    readmes = {p: p.read_text() for p in (ROOT / "README.md", STUDY_README)}
    out = tmp_path / "out"
    argv = ["--agents-dir", str(dev_agent), "--episodes", "4", "--shift-episodes", "2", "--steps", "60"]
    assert main([*argv, "--n-boot", "100", "--out", str(out), "--quiet"]) == 0
    assert {p: p.read_text() for p in readmes} == readmes  # a dev run rewrites no README
    res = json.loads((out / "results.json").read_text())
    assert res["episodes"] == 4 and res["shift_episodes"] == 2 and res["git"]["commit"]
    assert res["command"].startswith("python -m experiments.learned_v2 --agents-dir")
    e = res["envs"][ENV]
    assert e["reference"] == "sage_husa" and e["plain"] == "plain" and e["clairvoyant"]
    assert e["agent"]["residual"]["baseline"] == "sage_husa" and e["agent"]["label"] == "learned (PPO)"
    rows = {r["set"]: r for r in e["rows"]}
    assert list(rows) == [HELD_OUT, *SHIFTS]
    # the shift whose kwarg the env lacks says so and does not stop the others
    longer = rows["longer events"]
    assert longer["verdict"] == "not run" and "'burst_duration'" in longer["error"]
    assert "UnknownKeywordError" in longer["error"]
    held = rows[HELD_OUT]
    assert set(held["policies"]) == {
        "plain",
        "constant",
        "iae",
        "sage_husa",
        "iae_q",
        "learned (PPO)",
        "clairvoyant",
    }
    assert held["seeds"]["n"] == 4 and held["seeds"]["first"] == 2_000_000_000
    for name in (HELD_OUT, "stronger events", "more events"):
        r = rows[name]
        assert r["error"] is None and r["paired_clairvoyant"] is True
        assert r["verdict"] in ("target met", "beats", "ties", "worse")
        if name != HELD_OUT:
            assert set(r["policies"]) == {"sage_husa", "plain", "learned (PPO)", "clairvoyant"}
            assert r["seeds"]["n"] == 2
            steps = {"episode_steps": 60, "max_episode_steps": 60}
            assert r["env_kwargs"] == {**steps, **json.loads(json.dumps(SHIFT_KWARGS["Robot2d"][name]))}
        rmse = {k: np.asarray(v) for k, v in r["rmse_per_episode"].items()}
        p, a, c, ref = (rmse[k].mean() for k in ("plain", "learned (PPO)", "clairvoyant", "sage_husa"))
        assert r["capture"]["capture"] == pytest.approx((p - a) / (p - c))
        assert r["delta_rmse"]["delta_pct"] == pytest.approx(100.0 * (a - ref) / ref)
        assert r["policies"]["sage_husa"]["rmse_m"] == pytest.approx(ref)
    table = (out / "table.md").read_text()
    assert "Quick mode" not in table and "does not accept" in table and table.count(f"| `{ENV}` |") == 4
    assert (out / "Robot2dNoiseScale-v2" / "held-out" / "summary.csv").is_file()
