from pathlib import Path

from experiments.divergence_penalty.__main__ import main, play


def test_quick_mode_writes_its_results(tmp_path: Path):
    assert main(["--quick", "--out", str(tmp_path)]) == 0
    for name in ("table.csv", "report.md", "returns.png", "manifest.json"):
        assert (tmp_path / name).stat().st_size > 0
    assert "GpsInsFading-v1" in (tmp_path / "report.md").read_text()


def test_v1_charges_the_steps_a_diverged_episode_does_not_play():
    kw = {"episode_steps": 30, "max_episode_steps": 30, "divergence_m": 1.0}  # every episode diverges
    v0 = play("navgym/GpsInsFading-v0", 3, None, 1_000_000, **kw)
    v1 = play("navgym/GpsInsFading-v1", 3, None, 1_000_000, **kw)
    assert v0["terminated"].all() and v1["terminated"].all()
    assert (v1["return"] < v0["return"] - 10.0 * 20).all()  # at least 20 unplayed steps at -10
