"""``navgym benchmark``: one quick run of two ids (a supervised, an SB3 and a two-seed agent)."""

import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401
from agents.baselines.registry import baseline_specs, best_tuned
from agents.benchmark.protocol import _boot_seed
from agents.benchmark.references import CLAIRVOYANT, REGIME_ORACLE
from agents.evaluation.comparison import delta_rmse
from agents.seeds import seeds as seed_range
from navgym.cli import main

ZOO = Path(__file__).resolve().parents[3] / "agents" / "zoo"
ROW = "navgym/Robot2dRowScale-v3"
MIX = "navgym/Robot2dMixture-v2"
SUPERVISED = ZOO / "Robot2dRowScale-v3-supervised"
PPO = ZOO / "Robot2dMixture-v2"
EPISODES, STEPS, N_BOOT = 4, 60, 200


def two_seeds(root: Path) -> Path:
    """A folder of two 'training seeds': the zoo agent and the same weights in mode 'expected'."""
    for seed, mode in (("seed_0", None), ("seed_1", "expected")):
        shutil.copytree(SUPERVISED, root / seed)
        if mode:
            man = json.loads((root / seed / "manifest.json").read_text())
            man["mode"] = mode
            (root / seed / "manifest.json").write_text(json.dumps(man))
    return root


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("benchmark")
    out = tmp / "out"
    agents = [f"zoo={SUPERVISED}", f"zoo={PPO}", f"mine={two_seeds(tmp / 'mine')}"]
    readme = tmp / "README.md"
    readme.write_text("# x\n\n<!-- leaderboard:begin -->\nold\n<!-- leaderboard:end -->\n\nafter\n")
    argv = ["benchmark", *agents, "--quick", "--episodes", str(EPISODES), "--quiet", "--out", str(out)]
    argv += ["--env-kwargs", f"episode_steps={STEPS},max_episode_steps={STEPS}", "--readme", str(readme)]
    import io
    from contextlib import redirect_stdout

    buf = io.StringIO()
    with redirect_stdout(buf):
        assert main(argv) == 0
    board = json.loads((out / "leaderboard.json").read_text())
    return {"out": out, "printed": buf.getvalue(), "board": board, "rows": board["rows"], "readme": readme}


def rows_of(run, env_id):
    return {r["policy"]: r for r in run["rows"] if r["id"] == env_id}


def test_it_writes_and_prints_the_leaderboard(run):
    out = run["out"]
    for name in ("leaderboard.md", "leaderboard.json", "leaderboard.csv", "manifest.json"):
        assert (out / name).is_file(), name
    md = (out / "leaderboard.md").read_text()
    assert md in run["printed"]
    assert "| id | policy | role | RMSE [m] |" in md and "across seeds: mean / IQM" in md
    assert md.count("\n| `Robot2dRowScale-v3` |") == len(rows_of(run, ROW))
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["ids"] == [ROW, MIX]  # the agents' ids, in order
    assert manifest["seeds"][ROW] == {"n": EPISODES, "first": 2_000_000_000, "last": 2_000_000_003}
    assert manifest["protocol"]["env_kwargs"] == {"episode_steps": STEPS, "max_episode_steps": STEPS}
    assert manifest["protocol"]["n_boot"] == N_BOOT and manifest["protocol"]["quick"] is True
    assert {a["label"]: a["kind"] for a in manifest["agents"]} == {"zoo": "sb3", "mine": "supervised"}
    assert manifest["tuned_files"][ROW]["sha256"]
    assert "Non-standard env kwargs" in md  # the episodes were shortened: said so


def test_the_readme_block_keeps_plain_the_bar_agents_seed_means_and_references(run):
    text = run["readme"].read_text()
    assert text.startswith("# x\n\n<!-- leaderboard:begin -->\n") and text.endswith(
        "<!-- leaderboard:end -->\n\nafter\n"
    )
    assert "old" not in text and "navgym benchmark zoo=" in text
    block = text.split("<!-- leaderboard:begin -->")[1]
    kept = {r["policy"] for r in run["rows"] if r["id"] == ROW and r["policy"] in block}
    roles = {r["policy"]: r["role"] for r in run["rows"] if r["id"] == ROW}
    assert {p for p, role in roles.items() if role in ("plain", "bar", "agent", "reference")} <= kept
    assert "mine" in kept and "mine/seed_0" not in block  # a multi-seed agent: its mean row only
    others = [p for p, role in roles.items() if role == "baseline"]
    assert others and not any(f"| {p} |" in block for p in others)


@pytest.mark.parametrize("env_id", [ROW, MIX])
def test_the_bar_is_the_tuned_best_and_every_baseline_runs(run, env_id):
    rows = rows_of(run, env_id)
    bar = [r for r in rows.values() if r["role"] == "bar"]
    assert [r["policy"] for r in bar] == [best_tuned(env_id)[0]]
    assert run["board"]["ids"][env_id]["bar"] == bar[0]["policy"]
    assert bar[0]["delta_pct"] == 0.0
    specs = set(baseline_specs(gym.make(env_id)))
    classical = {p for p, r in rows.items() if r["role"] in ("plain", "baseline", "bar")}
    assert classical == specs | {"plain"}
    assert rows["plain"]["role"] == "plain"


@pytest.mark.parametrize("env_id", [ROW, MIX])
def test_every_row_is_paired_with_the_bar_on_the_same_seeds(run, env_id):
    info = run["board"]["ids"][env_id]
    assert info["seeds"] == seed_range("eval", EPISODES)
    eps = info["episodes"]
    bar = np.asarray(eps[info["bar"]]["rmse_m"])
    checked = 0
    for label, row in rows_of(run, env_id).items():
        assert row["n"] == EPISODES
        if row["role"] == "bar" or label not in eps:
            continue
        a = np.asarray(eps[label]["rmse_m"])
        assert a.shape == bar.shape == (EPISODES,)
        assert row["delta_pct"] == pytest.approx(100 * (a.mean() - bar.mean()) / bar.mean())
        d = delta_rmse(a, bar, N_BOOT, seed=_boot_seed(0, env_id, label) + 1)
        assert (row["delta_low"], row["delta_high"]) == pytest.approx((d["low_pct"], d["high_pct"]))
        assert row["rmse_m"] == pytest.approx(a.mean())
        assert row["diverged"] == pytest.approx(np.mean(eps[label]["diverged"]))
        checked += 1
    assert checked >= 5


def test_the_references_run_where_the_id_has_them(run):
    row, mix = run["board"]["ids"][ROW], run["board"]["ids"][MIX]
    assert set(row["references"]) == {CLAIRVOYANT, REGIME_ORACLE}
    table = json.loads((SUPERVISED / "manifest.json").read_text())["table"]
    assert row["references"][REGIME_ORACLE]["table"] == table  # from the supervised zoo manifest
    assert row["references"][REGIME_ORACLE]["env_kwargs"]["regime_oracle"] == table
    assert set(mix["references"]) == {CLAIRVOYANT} and REGIME_ORACLE in mix["skipped_references"]
    md = (run["out"] / "leaderboard.md").read_text()
    assert f"`Robot2dMixture-v2` {REGIME_ORACLE} skipped: the regime oracle belongs to the RowScale ids" in md
    refs = rows_of(run, ROW)
    assert refs[CLAIRVOYANT]["role"] == refs[REGIME_ORACLE]["role"] == "reference"
    # the clairvoyant filter (told the true noise) is far better than the plain one on any episodes
    assert refs[CLAIRVOYANT]["rmse_m"] < refs["plain"]["rmse_m"]


def test_a_multi_seed_agent_gets_its_seeds_and_their_aggregate(run):
    rows = rows_of(run, ROW)
    s0, s1, agg = rows["mine/seed_0"], rows["mine/seed_1"], rows["mine"]
    assert (s0["role"], s1["role"], agg["role"]) == ("seed", "seed", "mean of 2 seeds")
    assert s0["rmse_m"] != s1["rmse_m"]  # two different policies
    assert agg["seeds"] == ["seed_0", "seed_1"]
    assert agg["rmse_m"] == pytest.approx((s0["rmse_m"] + s1["rmse_m"]) / 2)
    assert agg["delta_pct"] == pytest.approx((s0["delta_pct"] + s1["delta_pct"]) / 2)
    seeds = agg["across_seeds"]["delta_pct"]
    assert seeds["n_runs"] == 2
    assert seeds["mean"] == pytest.approx(agg["delta_pct"]) and seeds["iqm"] == pytest.approx(seeds["mean"])
    lo, hi = sorted((s0["delta_pct"], s1["delta_pct"]))
    assert seeds["mean_low"] == pytest.approx(lo) and seeds["mean_high"] == pytest.approx(hi)
    order = [r["policy"] for r in run["rows"] if r["id"] == ROW]
    assert order.index("mine") == order.index("mine/seed_1") + 1  # the aggregate follows its seeds
    # the supervised zoo agent's single row is exactly the first seed's (same weights, same mode)
    assert rows["zoo"]["rmse_m"] == pytest.approx(s0["rmse_m"]) and rows["zoo"]["role"] == "agent"


def test_a_label_on_two_ids_is_aggregated_across_them(run):
    (agg,) = run["board"]["across_ids"]
    assert agg["agent"] == "zoo" and agg["ids"] == [ROW, MIX] and agg["runs"] == {ROW: 1, MIX: 1}
    deltas = [rows_of(run, i)["zoo"]["delta_pct"] for i in (ROW, MIX)]
    assert agg["mean"] == pytest.approx(np.mean(deltas))
    assert agg["mean_low"] == agg["mean_high"] == pytest.approx(agg["mean"])  # one seed per id
    assert "## Across ids" in (run["out"] / "leaderboard.md").read_text()
