"""Evaluation: determinism, metrics, bootstrap coverage, seed ranges, tuning, oracle, report files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agents.baselines import HindsightOracle, make_baseline, make_baselines
from agents.evaluation import (
    bootstrap_mean_ci,
    episode_metrics,
    evaluate,
    paired_difference,
    run_eval,
)
from agents.evaluation.metrics import outage_runs
from agents.evaluation.runner import Rollout, make_vector_env, rollout
from agents.seeds import seeds
from agents.tuning import grid_points, tune
from tests.navgym.envs.simulations import count_simulations

FADING = "navgym/GpsInsFading-v0"
KW = {"max_episode_steps": 40}


def _policies(env):
    return make_baselines(
        env, {"suboptimal": {"rho": 0.6, "beta": 2.0}}, names=["plain", "suboptimal", "sage_husa"]
    )


def test_evaluation_is_deterministic_under_a_seed():
    env = make_vector_env(FADING, 1, KW)
    s = seeds("eval", 4)
    r1 = evaluate(FADING, _policies(env), s, KW, n_boot=200, progress=False)
    r2 = evaluate(FADING, _policies(env), s, KW, n_boot=200, progress=False)
    for name in r1.episodes:
        for m, x in r1.episodes[name].items():
            np.testing.assert_array_equal(x, r2.episodes[name][m], err_msg=f"{name} {m}")
    for rows1, rows2 in ((r1.summary, r2.summary), (r1.paired, r2.paired)):
        assert len(rows1) == len(rows2)
        for a, b in zip(rows1, rows2, strict=True):
            assert a.keys() == b.keys()
            for k in a:
                same = a[k] == b[k] or (isinstance(a[k], float) and np.isnan(a[k]) and np.isnan(b[k]))
                assert same, (k, a[k], b[k])
    assert r1.reference in r1.episodes
    best = max(r1.episodes, key=lambda n: r1.episodes[n]["return"].mean())
    assert r1.reference == best


def test_evaluation_simulates_the_episodes_once_for_all_policies(monkeypatch):
    calls = count_simulations(monkeypatch)
    env = make_vector_env(FADING, 1, KW)
    pols = _policies(env)
    r = evaluate(FADING, pols, seeds("eval", 4), KW, n_boot=20, progress=False)
    assert len(pols) == 3 and calls == [4]
    # each policy's episodes are those of a run of its own (no cache there)
    alone = evaluate(
        FADING, {"sage_husa": pols["sage_husa"]}, seeds("eval", 4), KW, n_boot=20, progress=False
    )
    for m, x in alone.episodes["sage_husa"].items():
        np.testing.assert_array_equal(x, r.episodes["sage_husa"][m], err_msg=m)


def test_seeds_outside_the_eval_range_are_rejected():
    env = make_vector_env(FADING, 1, KW)
    pols = {"plain": make_baseline(env, "plain")}
    with pytest.raises(ValueError, match="eval"):
        evaluate(FADING, pols, seeds("tune", 2), KW, progress=False)
    with pytest.raises(ValueError, match="eval"):
        evaluate(FADING, pols, [5, 6], KW, progress=False)


def test_outage_metrics_on_a_handmade_rollout():
    assert outage_runs(np.array([1, 0, 0, 1, 0, 1], dtype=bool) == 0) == [(1, 3), (4, 5)]
    T = 6
    err = np.array([[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], [1.0, 1.0, np.nan, 0.0, 0.0, 0.0]])
    gnss = np.array([[1, 0, 0, 1, 0, 1], [1, 1, 1, 0, 0, 0]], dtype=bool)
    alive = np.array([[True] * T, [True, True, True, False, False, False]])
    roll = Rollout(
        {"pos_err_m": err, "gnss_available": gnss, "reward": np.ones((2, T)), "nees": np.ones((2, T))},
        alive,
        np.array([6, 3]),
        np.array([False, True]),
        1.0,
    )
    m = episode_metrics(roll, divergence_m=100.0)
    assert m["outage_mean_err_m"][0] == pytest.approx((2 + 3 + 5) / 3)
    assert m["outage_end_err_m"][0] == pytest.approx((3 + 5) / 2)
    assert m["n_outages"][0] == 2
    assert np.isnan(m["outage_mean_err_m"][1])  # no outage within its 3 steps
    assert m["rmse_m"][1] == pytest.approx(np.sqrt((1 + 1 + 100.0**2) / 3))  # NaN error -> divergence_m
    assert m["return"].tolist() == [6.0, 3.0] and m["diverged"].tolist() == [0.0, 1.0]


def test_scored_rmse_adds_the_platforms_extra_error_and_equals_rmse_without_one():
    err = np.array([[3.0, 4.0, 0.0], [1.0, np.nan, 2.0]])
    extra = np.array([[1.0, 0.0, 2.0], [0.5, 7.0, np.nan]])  # NaN extra: nothing added
    alive = np.array([[True, True, True], [True, True, False]])
    args = (alive, np.array([3, 2]), np.array([False, True]), 1.0)
    with_extra = episode_metrics(
        Rollout({"pos_err_m": err, "extra_err": extra, "reward": np.ones((2, 3))}, *args), 50.0
    )
    assert with_extra["scored_rmse_m"][0] == pytest.approx(np.sqrt((16 + 16 + 4) / 3))
    assert with_extra["scored_rmse_m"][1] == pytest.approx(np.sqrt((1.5**2 + 57.0**2) / 2))  # NaN err -> 50
    assert with_extra["rmse_m"][0] == pytest.approx(np.sqrt(25 / 3))
    plain = episode_metrics(Rollout({"pos_err_m": err, "reward": np.ones((2, 3))}, *args), 50.0)
    np.testing.assert_array_equal(plain["scored_rmse_m"], plain["rmse_m"])


def test_bootstrap_ci_covers_the_true_mean_difference():
    rng = np.random.default_rng(0)
    true_diff, n, reps = 0.7, 40, 300
    hits = 0
    for r in range(reps):
        base = rng.normal(10.0, 5.0, n)  # episode effect shared by both policies
        a = base + true_diff + rng.exponential(1.0, n) - 1.0
        d = paired_difference(a, base, n_boot=400, seed=r)
        hits += d["low"] <= true_diff <= d["high"]
    coverage = hits / reps
    assert 0.88 <= coverage <= 0.99, coverage
    mean, lo, hi, k = bootstrap_mean_ci(np.array([1.0, np.nan, 3.0]), n_boot=100)
    assert (mean, k) == (2.0, 2) and lo <= mean <= hi


def test_paired_statistic_ci_resamples_episodes_jointly():
    from agents.evaluation.bootstrap import paired_statistic_ci

    def ratio(m):
        return m[..., 1] / m[..., 0]

    a, b = np.array([2.0, 4.0, np.nan]), np.array([1.0, 1.0, 5.0])
    value, lo, hi, n = paired_statistic_ci((a, b), ratio, n_boot=500)
    # the nan episode is dropped with its pair; the resamples of two pairs give 1/2, 1/3 or 1/4
    assert (value, n) == (2.0 / 6.0, 2)
    assert 0.25 <= lo <= value <= hi <= 0.5
    # equal pairs: every resample gives the same ratio, the CI collapses onto it
    assert paired_statistic_ci((a[:2], a[:2]), ratio, n_boot=50)[:3] == (1.0, 1.0, 1.0)
    # a statistic that is not finite on the full sample gives NaNs
    assert np.isnan(paired_statistic_ci((np.zeros(3), np.ones(3)), ratio, n_boot=50)[0])
    with pytest.raises(ValueError, match="equal lengths"):
        paired_statistic_ci((np.ones(2), np.ones(3)), ratio)
    with pytest.raises(ValueError, match="level"):
        paired_statistic_ci((np.ones(2), np.ones(2)), ratio, level=1.0)


def test_tuning_grid_scores_equal_individual_rollouts():
    grid = {"rho": (0.5, 0.9), "beta": (1.0, 3.0)}
    assert len(grid_points(grid)) == 4
    res = tune(FADING, "suboptimal", grid, episodes=3, env_kwargs=KW, progress=False)
    assert len(res["grid"]) == 4
    best = max(res["grid"], key=lambda r: r["mean_return"])
    assert res["params"] == best["params"] and res["score"] == best["mean_return"]
    env = make_vector_env(FADING, 1, KW)
    p = res["grid"][2]["params"]
    r = evaluate(
        FADING,
        {"x": make_baseline(env, "suboptimal", **p)},
        seeds("tune", 3),
        KW,
        seed_kind="tune",
        progress=False,
    )
    assert r.episodes["x"]["return"].mean() == pytest.approx(res["grid"][2]["mean_return"], rel=1e-12)


@pytest.mark.parametrize("given, used", [({}, False), ({"eval_info": True}, True)])
def test_tuning_envs_skip_the_nees_unless_asked(monkeypatch, given, used):
    """No score reads the NEES: the scored envs are made with eval_info=False, an explicit one kept."""
    import agents.tuning.search as search

    made = []

    def spy(env_id, num_envs, env_kwargs=None):
        made.append((num_envs, dict(env_kwargs or {})))
        return make_vector_env(env_id, num_envs, env_kwargs)

    monkeypatch.setattr(search, "make_vector_env", spy)
    res = tune(
        FADING,
        "suboptimal",
        {"rho": (0.5,), "beta": (1.0,)},
        episodes=2,
        env_kwargs={**KW, **given},
        progress=False,
    )
    scored = [kw for n, kw in made if n == 2]
    assert scored and all(kw["eval_info"] is used for kw in scored)
    assert len(res["grid"]) == 1


def test_tuning_chunks_simulate_their_episodes_once(monkeypatch):
    """Four chunks reset the same episodes: simulated once, the rows those of uncached chunks."""
    import agents.tuning.search as search
    from navgym.envs import distinct

    grid = {"rho": (0.5, 0.9), "beta": (1.0, 3.0)}
    kw = {"episodes": 3, "env_kwargs": KW, "progress": False, "max_batch": 3, "workers": 1}
    calls = count_simulations(monkeypatch)
    cached = tune(FADING, "suboptimal", grid, **kw)
    assert calls == [3]  # 4 chunks of 3 episodes (max_batch 3): one simulation

    class NoCache(distinct.EpisodeCache):
        def key(self, *args, **kwargs):
            return None

    monkeypatch.setattr(search, "EpisodeCache", NoCache)
    calls.clear()
    plain = tune(FADING, "suboptimal", grid, **kw)
    assert calls == [3] * 4
    assert cached["grid"] == plain["grid"]
    assert len({r["mean_return"] for r in plain["grid"]}) == 4


def test_hindsight_oracle_bounds_its_candidates_episode_by_episode():
    env = make_vector_env(FADING, 1, KW)
    cands = _policies(env)
    pols = dict(cands)
    pols["oracle"] = lambda e: HindsightOracle(
        e, {k: make_baseline(e, k, **v.describe()["params"]) for k, v in cands.items()}
    )
    r = evaluate(FADING, pols, seeds("eval", 3), KW, n_boot=100, progress=False)
    best = np.max([r.episodes[k]["return"] for k in cands], axis=0)
    np.testing.assert_allclose(r.episodes["oracle"]["return"], best, rtol=1e-12)
    assert r.row("oracle")["kind"] == "oracle" and r.reference != "oracle"


def test_run_eval_writes_the_report(tmp_path):
    res = run_eval(
        FADING,
        ["plain", "suboptimal:rho=0.6,beta=2", "x=sage_husa"],
        episodes=3,
        out=tmp_path,
        env_kwargs=KW,
        tuned=False,
        n_boot=100,
        progress=False,
    )
    assert set(res.episodes) == {"plain", "suboptimal:rho=0.6,beta=2", "x"}
    for f in (
        "episodes.csv",
        "summary.csv",
        "paired.csv",
        "report.md",
        "manifest.json",
        "error_time.png",
        "error_cdf.png",
    ):
        assert (tmp_path / f).stat().st_size > 0, f
    man = json.loads((tmp_path / "manifest.json").read_text())
    assert man["seeds"]["first"] == seeds("eval", 1)[0] and man["versions"]["numpy"]
    assert "commit" in man["git"] and man["policies"]["plain"]["params"] == {"lam": 1.0}
    assert "| policy |" in (tmp_path / "report.md").read_text()
    assert len((tmp_path / "episodes.csv").read_text().splitlines()) == 1 + 3 * 3


def test_rollout_without_autoreset_equals_env_step():
    env = make_vector_env(FADING, 3, KW)
    s = seeds("eval", 3)
    pol = make_baseline(env, "suboptimal", rho=0.6)
    a = rollout(env, pol, s)
    b = rollout(env, pol, s, autoreset=True)
    for k in a.steps:
        np.testing.assert_array_equal(a.steps[k], b.steps[k], err_msg=k)
    np.testing.assert_array_equal(a.length, b.length)


def test_terminated_episodes_do_not_disturb_the_others():
    kw = {**KW, "divergence_m": 15.0}  # small bound: some episodes terminate early
    s = seeds("eval", 6)
    env = make_vector_env(FADING, 6, kw)
    pol = make_baseline(env, "constant", lam=3.0)
    batch = rollout(env, pol, s)
    assert batch.terminated.any() and not batch.terminated.all()
    one = make_vector_env(FADING, 1, kw)
    for i, seed in enumerate(s):
        r = rollout(one, make_baseline(one, "constant", lam=3.0), [seed])
        n = int(batch.length[i])
        assert r.length[0] == n and r.terminated[0] == batch.terminated[i]
        np.testing.assert_array_equal(r.steps["pos_err_m"][0, :n], batch.steps["pos_err_m"][i, :n])


def test_sb3_policy_spec_loads_with_its_normalization():
    """``ppo:PATH`` loads through load_agent: the zoo's VecNormalize statistics are applied."""
    pytest.importorskip("stable_baselines3")
    from agents.demo import ZOO
    from agents.evaluation.cli import parse_policies
    from agents.training.loading import TrainedAgent

    zoo = ZOO / "GpsInsFading-v0"
    pols = parse_policies([f"a=ppo:{zoo}/model.zip", f"b=ppo:{zoo}/model", f"c=ppo:{zoo}"], FADING, KW)
    assert set(pols) == {"a", "b", "c"}
    for agent in pols.values():
        assert isinstance(agent, TrainedAgent) and agent.normalizer is not None


def test_policy_specs_of_a_per_row_mixture_id_are_its_row_baselines():
    """navgym/Robot2dMixture-v2 (per_row=True) takes the RowMixture baselines by name and as 'baselines'."""
    from agents.baselines import baseline_specs
    from agents.evaluation.cli import parse_policies

    policies = parse_policies(["baselines", "chi_square:alpha=0.01"], "navgym/Robot2dMixture-v2")
    assert set(baseline_specs("RowMixture")) <= set(policies)
    assert "chi_square:alpha=0.01" in policies
