"""``navgym demo``: the headline v2 id, the verdict sentence, the knob trace and the outputs."""

import json
import re
from pathlib import Path

from agents.demo import DEFAULT_ENV
from navgym.cli import main

README = Path(__file__).resolve().parents[2] / "README.md"


def test_demo_quick_writes_its_outputs(tmp_path: Path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "learned" in printed and "|" in printed  # the table is printed
    for name in ("report.md", "table.csv", "manifest.json", "knob_trace.png"):
        assert (out / name).is_file(), name
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["env_id"] == DEFAULT_ENV
    # one sentence says whether the agent beats the best tuned baseline, with its paired CI
    sentence = re.search(
        r"On navgym/\S+ \(6 held-out episodes\) the learned agent .*?CI; RMSE [^)]*\)\.", printed
    )
    assert sentence, printed
    assert "the best tuned classical baseline `chi_square`" in sentence.group(0)
    assert re.search(r"ΔRMSE [+-]\d+\.\d % \[[+-]\d+\.\d, [+-]\d+\.\d\]", sentence.group(0))
    report = (out / "report.md").read_text()
    assert sentence.group(0) in report and "![knob over one episode](knob_trace.png)" in report
    assert report.startswith(f"# Evaluation: {DEFAULT_ENV}\n")


def test_the_headline_id_is_the_study_row_where_learning_comes_closest():
    """The demo's default is the learned_v2 table's id with the smallest ΔRMSE % (README block)."""
    block = README.read_text().split("<!-- learned-v2:begin -->")[1].split("<!-- learned-v2:end -->")[0]
    rows = re.findall(r"^\| `(navgym/\S+)` \|[^|]*\|[^|]*\| ([+-]\d+\.\d) \[", block, flags=re.M)
    assert len(rows) >= 4, block
    assert DEFAULT_ENV == min(rows, key=lambda r: float(r[1]))[0]
