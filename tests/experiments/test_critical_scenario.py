import csv
import json
from pathlib import Path

import numpy as np
import pytest

from agents.seeds import TUNE_START
from experiments.critical_scenario.__main__ import (
    SEED_OFFSET,
    STEPS,
    ExplorationTask,
    main,
    play,
    running_rms,
)

SWITCH_S = 1983  # first second with 2 satellites above the 50 deg mask (default_critical_window)


def test_quick_mode_writes_its_results(tmp_path: Path):
    assert main(["--quick", "--no-progress", "--out", str(tmp_path)]) == 0
    for name in ("table.csv", "report.md", "running_rms.png", "manifest.json"):
        assert (tmp_path / name).stat().st_size > 0
    with open(tmp_path / "table.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["filter"] for r in rows] == (
        ["EKF"] * 3 + ["PF (N = 200)"] * 3 + ["n-conditional PF (N = 200, M = 4)"] * 3
    )
    assert all(np.isfinite(float(r["rms 3600 s median"])) for r in rows)
    assert all(r["episodes"] == "2" for r in rows)
    report = (tmp_path / "report.md").read_text()
    assert "Paired episodes (same truth and satellites used by every filter" in report
    assert "over the episodes both of a pair played): True" in report
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["paired"] == {"ekf-pf": True, "ekf-npf": True}
    assert manifest["filters"] == ["ekf", "pf", "npf"]
    assert manifest["aux_particles (npf)"] == 4 and manifest["section_length (npf)"] == 1


def test_the_filters_option_picks_the_rows(tmp_path: Path):
    argv = ["--filters", "ekf,npf", "--episodes", "2", "--particles", "50", "--aux", "2"]
    assert main([*argv, "--steps", "30", "--no-progress", "--out", str(tmp_path)]) == 0
    with open(tmp_path / "table.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["filter"] for r in rows] == ["EKF"] * 3 + ["n-conditional PF (N = 50, M = 2)"] * 3
    assert json.loads((tmp_path / "manifest.json").read_text())["paired"] == {"ekf-npf": True}
    with pytest.raises(SystemExit):
        main(["--filters", "ukf", "--no-progress", "--out", str(tmp_path)])


@pytest.fixture(scope="module")
def quick_runs():
    seed = TUNE_START + SEED_OFFSET
    runs = {k: play(k, 2, seed, particles=200) for k in ("ekf", "pf")}
    runs["npf"] = play("npf", 2, seed, particles=200, n_aux=4)
    return runs


def test_the_scenario_drops_from_3_to_2_satellites_and_every_filter_sees_it(quick_runs):
    for r in quick_runs.values():
        assert r["used"].shape == (2, STEPS)
        assert (r["used"][:, : SWITCH_S - 60] == 3).all()
        assert (r["used"][:, SWITCH_S + 60 :] == 2).all()
    # the comparison is paired: same truth, same satellites
    for k in ("pf", "npf"):
        np.testing.assert_array_equal(quick_runs["ekf"]["truth"], quick_runs[k]["truth"])
        np.testing.assert_array_equal(quick_runs["ekf"]["used"], quick_runs[k]["used"])


def test_running_rms_is_carvalho_1997s_formula():
    err = np.array([[3.0, 4.0, 0.0]])
    np.testing.assert_allclose(running_rms(err)[0], [3.0, np.sqrt(12.5), np.sqrt(25.0 / 3.0)])


def test_the_ekf_tracks_the_drifts_through_the_two_satellite_phase(quick_runs):
    """Measured (2 episodes): EKF running rms at 3600 s 3.5-3.9 m east, 6.8-7.5 m north, 0.9 m
    clock. A truth/estimate mix-up (a wrong state index, unpaired episodes) breaks these bounds.
    The PFs' errors are only checked to be finite: that they are worse than the EKF here (README)
    is a measured shortfall against Carvalho et al. 1997, not a property to keep.
    """
    ekf = running_rms(quick_runs["ekf"]["err"])[:, -1]  # (B, 3) at 3600 s
    assert (ekf[:, :2] < 15.0).all() and (ekf[:, 2] < 3.0).all(), ekf
    for k in ("pf", "npf"):
        assert np.isfinite(quick_runs[k]["err"]).all(), k
    for r in quick_runs.values():
        assert (r["diverged_at"] < 0).all() and (r["terminated_at"] < 0).all()
    assert (quick_runs["npf"]["resamples"] > 0).all()  # the redistribution rule drives it too


def test_the_exploration_task_keeps_the_resample_tasks_options():
    from navgym.envs.tasks import ResampleTask

    base = ResampleTask(
        n_particles=300,
        resample_cost=0.2,
        method="multinomial",
        roughening=0.1,
        log_ess_feature=True,
        particle_dtype="float64",
    )
    t = ExplorationTask.like(base, 7)
    assert t.n_aux == 7 and t.options == base.options  # every option, not a hand-kept list
    assert (t.n_particles, t.method, t.particle_dtype) == (300, "multinomial", np.float64)
    assert ResampleTask(**base.options).options == base.options
    assert [f.name for f in t.features()] == [f.name for f in base.features()]
    with pytest.raises(ValueError, match="n_aux"):
        ExplorationTask(0)
