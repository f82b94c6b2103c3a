"""``python -m benchmarks.report`` (docs/benchmarks.md): every benchmark, its command, its tables."""

from __future__ import annotations

import io

from benchmarks import report
from benchmarks.cli import bench_targets


def test_the_report_runs_every_benchmark():
    assert len({e.title or e.target for e in report.ENTRIES}) == len(report.ENTRIES)  # one heading each
    assert {e.target for e in report.ENTRIES} == set(bench_targets()) - {"report"}
    for e in report.ENTRIES:
        assert report.command(e).startswith(f"navgym bench {e.target}")


def test_tables_of_keeps_the_tables_and_drops_progress_and_the_json_note():
    out = "  kf B=2  1.0 us\n\nCaption\n| a |\n|---|\n| 1 |\n\nStages:\n| b |\n\nJSON written to x.json\n"
    assert report.tables_of(out) == "Caption\n| a |\n|---|\n| 1 |\n\nStages:\n| b |"


def test_a_section_holds_what_it_measures_the_command_and_the_table(tmp_path):
    argv = ("--batch", "2", "--filters", "kf", "--no-filterpy", "--repeats", "1")
    entry = report.Entry("filters", (*argv, "--json", str(tmp_path / "f.json")), "What it measures.")
    tables = report.run_entry(entry, echo=io.StringIO())
    assert tables.startswith("Filter throughput") and "| kf " in tables and "JSON" not in tables
    page = report.render(report.machine_lines(), [(entry, tables)])
    assert page.startswith("# Benchmarks\n") and "## Machine" in page and "- CPU: " in page
    assert "## filters\n\nWhat it measures.\n\n```\nnavgym bench filters --batch 2 --filters kf" in page
    assert "Numba" in page and "BLAS" in page
