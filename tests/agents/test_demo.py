"""``navgym demo``: the headline v3 id, the verdict sentence, the knob trace and the outputs."""

import json
import re
from pathlib import Path

from agents.baselines.registry import best_tuned
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
    bar = best_tuned(DEFAULT_ENV)[0]
    assert f"the best tuned classical baseline `{bar}`" in sentence.group(0)
    assert "supervised (zoo)" in printed  # the warm start is in the table too
    assert re.search(r"ΔRMSE [+-]\d+\.\d % \[[+-]\d+\.\d, [+-]\d+\.\d\]", sentence.group(0))
    report = (out / "report.md").read_text()
    assert sentence.group(0) in report and "![knob over one episode](knob_trace.png)" in report
    assert report.startswith(f"# Evaluation: {DEFAULT_ENV}\n")


def test_the_headline_id_is_the_study_row_where_the_agent_wins_most_clearly():
    """The demo's default is the learned_v3 table's id with the most negative CI end (README block)."""
    block = README.read_text().split("<!-- learned-v3:begin -->")[1].split("<!-- learned-v3:end -->")[0]
    rows = re.findall(
        r"^\| `(\w+-v3)` \|[^|]*\| ([+-]\d+\.\d) \[([+-]\d+\.\d), ([+-]\d+\.\d)\]", block, flags=re.M
    )
    assert len(rows) >= 4, block
    assert DEFAULT_ENV == "navgym/" + min(rows, key=lambda r: float(r[3]))[0]
