"""Where the regime oracle's table comes from, and which references an id has."""

import json
from pathlib import Path

from agents.benchmark.references import CLAIRVOYANT, REGIME_ORACLE, reference_policies, regime_table

ZOO = Path(__file__).resolve().parents[3] / "agents" / "zoo"
ROW = "navgym/Robot2dRowScale-v3"

README = """# knob_reach
<!-- knob-reach-v3:begin -->
| id | episodes | plain m | bar m | oracle m | reach | G1 | the table | time |
|---|---|---|---|---|---|---|---|---|
| `Robot2dRowScale-v3` | 256 / 256 | 6.2 | 2.1 | 1.4 | 30.6 | pass | (0.3, 3, 100; 1, 1e4) | 233 s |
<!-- knob-reach-v3:end -->
"""


def test_the_table_of_the_supervised_zoo_agent_comes_first():
    table, source = regime_table(ROW)
    assert (
        list(table)
        == json.loads((ZOO / "Robot2dRowScale-v3-supervised" / "manifest.json").read_text())["table"]
    )
    assert source.endswith("Robot2dRowScale-v3-supervised/manifest.json")


def test_else_a_knob_reach_result_then_its_readme(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(README)
    nothing = tmp_path / "none.json"
    assert regime_table(ROW, zoo=tmp_path, results=nothing, readme=readme)[0] == (0.3, 3.0, 100.0, 1.0, 1e4)
    results = tmp_path / "results.json"
    entries = ("s_nominal", "s_noisy", "s_biased", "s_q_nominal", "s_q_event")
    results.write_text(
        json.dumps([{"env_id": ROW, "table": dict(zip(entries, [1, 2, 3, 4, 5], strict=True))}])
    )
    assert regime_table(ROW, zoo=tmp_path, results=results, readme=readme) == (
        (1.0, 2.0, 3.0, 4.0, 5.0),
        str(results),
    )
    table, why = regime_table("navgym/GpsInsRowScale-v3", zoo=tmp_path, results=results, readme=readme)
    assert table is None and "no regime-oracle table for navgym/GpsInsRowScale-v3" in why


def test_an_id_without_references_says_why():
    have, skipped = reference_policies("navgym/Robot2dResample-v2")
    assert have == {}
    assert "clairvoyant" in skipped[CLAIRVOYANT] and "Resample" in skipped[CLAIRVOYANT]
    assert "RowScale" in skipped[REGIME_ORACLE]
    have, skipped = reference_policies("navgym/GpsInsFading-v0")  # its platform gives no true noise
    assert CLAIRVOYANT in skipped and "v2" in skipped[CLAIRVOYANT]


def test_a_rowscale_id_has_both(tmp_path):
    have, skipped = reference_policies(ROW, {"episode_steps": 20})
    assert skipped == {} and set(have) == {CLAIRVOYANT, REGIME_ORACLE}
    assert have[CLAIRVOYANT]["env_kwargs"] == {"episode_steps": 20, "clairvoyant": True}
    assert have[REGIME_ORACLE]["env_kwargs"]["episode_steps"] == 20
    have, skipped = reference_policies(ROW, zoo=tmp_path)  # no zoo manifest: the committed knob_reach table
    assert REGIME_ORACLE in have and "knob_reach" in have[REGIME_ORACLE]["source"]
