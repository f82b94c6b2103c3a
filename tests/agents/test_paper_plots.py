"""Per-episode plots of ``navgym eval``: box / violin, forest plot (paired BCa), per-episode CDF."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from agents.evaluation import run_eval
from agents.evaluation.paper_plots import episode_cdf, forest_rows

FADING = "navgym/GpsInsFading-v0"
KW = {"max_episode_steps": 30}
EPISODES = 6


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval")
    res = run_eval(
        FADING,
        ["plain", "suboptimal:rho=0.6,beta=2", "sage_husa"],
        episodes=EPISODES,
        out=out,
        env_kwargs=KW,
        tuned=False,
        reference="plain",
        n_boot=200,
        progress=False,
        trace=2,
    )
    return res, out


def test_the_paper_plots_are_written(evaluated):
    _, out = evaluated
    files = ("rmse_box.png", "forest.png", "forest.csv", "error_cdf.png", "error_time.png", "knob_trace.png")
    for f in files:
        assert (out / f).stat().st_size > 0, f


def test_the_knob_trace_is_written_only_when_asked(tmp_path):
    run_eval(FADING, ["plain"], 2, tmp_path, env_kwargs=KW, tuned=False, n_boot=50, progress=False)
    assert (tmp_path / "error_cdf.png").is_file() and not (tmp_path / "knob_trace.png").exists()


def test_the_cdf_is_over_episodes_not_pooled_steps(evaluated):
    res, _ = evaluated
    cdf = episode_cdf(res)
    assert set(cdf) == set(res.episodes)
    for name, (x, f) in cdf.items():
        assert x.size == EPISODES  # one value per episode, not one per step
        np.testing.assert_allclose(np.sort(res.episodes[name]["rmse_m"]), x)
        assert f[-1] == 1.0 and np.all(np.diff(x) >= 0)


def test_the_forest_rows_are_paired_bca_differences_against_the_reference(evaluated):
    from scipy.stats import bootstrap

    res, out = evaluated
    rows = forest_rows(res)
    assert [r["policy"] for r in rows] == ["suboptimal:rho=0.6,beta=2", "sage_husa"]
    with (out / "forest.csv").open() as f:
        assert len(list(csv.DictReader(f))) == len(rows)
    for r in rows:
        d = res.episodes[r["policy"]]["rmse_m"] - res.episodes["plain"]["rmse_m"]
        assert r["mean_diff"] == pytest.approx(d.mean()) and r["n"] == EPISODES
        assert r["low"] <= r["mean_diff"] <= r["high"]
        # the same as scipy's paired BCa bootstrap of the two samples
        want = bootstrap(
            (res.episodes[r["policy"]]["rmse_m"], res.episodes["plain"]["rmse_m"]),
            lambda a, b, axis: np.mean(a - b, axis=axis),
            paired=True,
            vectorized=True,
            n_resamples=200,
            method="BCa",
            random_state=np.random.default_rng(0),
        ).confidence_interval
        assert (r["low"], r["high"]) == pytest.approx((want.low, want.high), rel=1e-9)
