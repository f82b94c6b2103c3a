"""experiments.zoo_results: the verdict sentence under each table, and the quick run."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

pytest.importorskip("stable_baselines3")

from experiments.zoo_results.__main__ import LEARNED, main, summary_row, verdict


def _results(low: float, high: float) -> SimpleNamespace:
    rows = {"best": {"return": -10.0, "rmse_m": 1.0}, LEARNED: {"return": -9.5, "rmse_m": 0.9}}
    return SimpleNamespace(
        reference="best",
        paired=[
            {"policy": LEARNED, "metric": "return", "mean_diff": (low + high) / 2, "low": low, "high": high},
            {"policy": LEARNED, "metric": "rmse_m", "mean_diff": -0.1, "low": -0.2, "high": 0.0},
        ],
        row=rows.__getitem__,
    )


def test_verdict_reads_the_paired_ci():
    assert "**beats** the best tuned baseline `best`" in verdict(_results(0.1, 0.9))
    assert "is **worse than**" in verdict(_results(-0.9, -0.1))
    tie = verdict(_results(-0.4, 1.4))
    assert "does **not** beat (ties)" in tie
    assert "-9.5 vs -10.0" in tie and "[-0.40, 1.40]" in tie and "RMSE 0.90 vs 1.00 m" in tie


def test_summary_row_quotes_both_rmses_the_cis_and_the_word():
    row = summary_row("navgym/X-v1", _results(0.1, 0.9))
    assert row.startswith("| `navgym/X-v1` | `best` | 0.90 / 1.00 |")
    assert "-0.10 [-0.20, 0.00]" in row and "+0.50 [0.10, 0.90]" in row and row.endswith("| beats |")
    assert summary_row("navgym/X-v1", _results(-0.9, -0.1)).endswith("| worse |")
    assert summary_row("navgym/X-v1", _results(-0.4, 1.4)).endswith("| ties |")


def test_quick_mode_writes_a_verdict_per_env(tmp_path: Path):
    assert main(["--quick", "--out", str(tmp_path)]) == 0
    report = (tmp_path / "report.md").read_text()
    n_envs = report.count("### `navgym/")
    assert n_envs >= 1 and report.count("the best tuned baseline") == n_envs
