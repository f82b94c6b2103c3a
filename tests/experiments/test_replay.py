"""experiments.replay: the outage-end scoring, the placements, the quick study's outputs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from experiments.replay.__main__ import DT, main, outage_end_errors, placements


def test_outage_end_error_is_the_last_truth_epoch_inside_the_outage():
    steps = 40
    err = np.tile(np.arange(1, steps + 1, dtype=float), (2, 1))  # column i: epoch (i + 1) dt, error i + 1
    exact = np.ones((2, steps), dtype=bool)
    exact[1, 10:12] = False  # row 1: the outage's last epoch (2.75 s, column 10) is no truth epoch
    res = {"err": err, "exact": exact}
    # outage [1, 3) s holds the epochs 1.0, ..., 2.75 s (columns 3..10)
    got = outage_end_errors(res, [1.0, 1.0], 2.0)
    np.testing.assert_array_equal(got, [2.75 / DT, 2.5 / DT])


def test_placements_end_by_the_last_end():
    for L in (5.0, 10.0, 30.0):
        s = placements(L)
        assert s[0] == 10.0 and s[-1] + L <= 80.0 and np.all(np.diff(s) == 5.0)


@pytest.mark.slow
def test_quick_study_writes_its_outputs(tmp_path):
    assert main(["--quick", "--out", str(tmp_path)]) == 0
    for name in ("table.csv", "report.md", "walk.png", "manifest.json"):
        assert (tmp_path / name).is_file()
    man = json.loads((tmp_path / "manifest.json").read_text())
    assert man["no_outage"]["rms_m"] < 0.5
