"""``navgym demo --quick`` runs end to end and writes the report, table, plots and manifest."""

import json
from pathlib import Path

from navgym.cli import main


def test_demo_quick_writes_its_outputs(tmp_path: Path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "learned" in printed and "|" in printed  # the table is printed
    for name in ("report.md", "table.csv", "manifest.json"):
        assert (out / name).is_file(), name
    assert list(out.glob("*.png")), "no plots written"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest
