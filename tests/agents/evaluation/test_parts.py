"""navgym eval --workers: the episodes split over forked processes give the one-process result bit for bit."""

import sys

import pytest

pytest.importorskip("stable_baselines3")

from agents.evaluation.cli import run_eval
from agents.evaluation.parts import ALIGN, forked_evaluate, split_seeds
from agents.seeds import seeds as seed_range
from agents.workers import can_fork
from tests.agents.evaluation.same_results import assert_same_results

ENV = "navgym/Robot2dMixture-v2"  # baselines and a zoo agent (residual PPO, torch MLP)
AGENT = "ppo:agents/zoo/Robot2dMixture-v2"
SHORT = {"episode_steps": 15, "max_episode_steps": 15}


@pytest.mark.skipif(not can_fork(), reason="no fork start method here")
def test_forked_eval_equals_one_process_bit_for_bit(tmp_path):
    kw = {"env_kwargs": SHORT, "n_boot": 300, "plots": False, "progress": False}
    n = 2 * ALIGN + 5  # parts of 64 and 69 episodes
    one = run_eval(ENV, ["baselines", AGENT], n, tmp_path / "one", **kw)
    two = run_eval(ENV, ["baselines", AGENT], n, tmp_path / "two", workers=2, **kw)
    assert_same_results(two, one, tmp_path / "two", tmp_path / "one", parts=2)


def test_forked_eval_runs_the_parts_of_split_seeds_and_reports_them():
    from agents.baselines import make_baselines
    from agents.evaluation.runner import make_vector_env

    pols = make_baselines(make_vector_env(ENV, 1, SHORT), {}, names=["zero", "chi_square"])
    seeds = seed_range("eval", 3)
    done = []
    res = forked_evaluate(ENV, pols, seeds, SHORT, workers=4, n_boot=20, on_done=done.append)
    assert len(split_seeds(seeds, 4)) == 1 and done == [0] and res.config["workers"] == 1
    assert res.episodes["zero"]["return"].shape == (3,)
    with pytest.raises(ValueError, match="workers must be at least 1; got 0"):
        forked_evaluate(ENV, pols, seeds, SHORT, workers=0)
    with pytest.raises(ValueError, match="eval"):
        forked_evaluate(ENV, pols, seed_range("tune", 2), SHORT)


def test_eval_workers_need_no_ray(monkeypatch, capsys, tmp_path):
    from navgym.cli import main

    monkeypatch.setitem(sys.modules, "ray", None)
    args = ["eval", "--env", ENV, "--episodes", "4", "--workers", "2", "--quiet", "--no-plots"]
    assert main([*args, "--policies", "zero", "--env-kwargs", "episode_steps=15,max_episode_steps=15",
                 "--out", str(tmp_path)]) == 0  # fmt: skip
    assert (tmp_path / "summary.csv").exists()
    assert main(["eval", "--env", ENV, "--episodes", "4", "--workers", "0", "--quiet", "--no-plots"]) == 2
    assert "workers must be at least 1; got 0" in capsys.readouterr().err
