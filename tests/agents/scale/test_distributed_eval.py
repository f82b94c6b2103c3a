"""navgym eval --workers N --ray: the episodes split over Ray workers equal one process bit for bit."""

import sys

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.evaluation.runner import Rollout, run_policies
from agents.scale.distributed_eval import ALIGN, merge_rollouts, split_seeds

ENV = "navgym/Robot2dMixture-v2"  # baselines and a zoo agent (residual PPO, torch MLP)
AGENT = "ppo:agents/zoo/Robot2dMixture-v2"
SHORT = {"episode_steps": 15, "max_episode_steps": 15}


def test_split_seeds():
    seeds = list(range(1000, 1200))
    assert split_seeds(seeds, 2) == [seeds[:64], seeds[64:]]  # cut at a multiple of 64 from the start
    assert split_seeds(seeds, 3) == [seeds[:64], seeds[64:128], seeds[128:]]
    assert split_seeds(seeds, 8) == split_seeds(seeds, 3)  # parts of >= 64 only
    assert split_seeds(seeds[:127], 4) == [seeds[:127]]
    assert split_seeds(seeds[:20], 3, align=4) == [seeds[:4], seeds[4:8], seeds[8:20]]
    with pytest.raises(ValueError, match="workers"):
        split_seeds(seeds, 0)


def test_merge_rollouts_concatenates_rows():
    def roll(b, v):
        return Rollout(
            {"reward": np.full((b, 3), v)}, np.ones((b, 3), bool), np.full(b, 3), np.zeros(b, bool), 0.1
        )

    m = merge_rollouts([roll(2, 1.0), roll(1, 2.0)])
    assert m.steps["reward"][:, 0].tolist() == [1.0, 1.0, 2.0] and m.length.shape == (3,)


def _policies():
    from agents.baselines import load_tuned
    from agents.evaluation.cli import parse_policies

    return parse_policies(["chi_square", AGENT], ENV, SHORT, load_tuned(ENV))


def test_parts_of_the_seeds_give_the_same_episodes():
    """The premise of the split, without Ray: aligned parts, concatenated, equal one batch."""
    from agents.seeds import seeds as seed_range

    seeds = seed_range("eval", 2 * ALIGN + 11)  # parts of 64 and 75
    policies = _policies()
    _, full, rolls, _ = run_policies(ENV, policies, seeds, SHORT, progress=False)
    parts = [run_policies(ENV, policies, p, SHORT, progress=False) for p in split_seeds(seeds, 2)]
    assert len(parts) == 2
    for name, metrics in full.items():
        for m, x in metrics.items():
            np.testing.assert_array_equal(
                x, np.concatenate([p[1][name][m] for p in parts]), err_msg=f"{name} {m}"
            )
        merged = merge_rollouts([p[2][name] for p in parts])
        for k, x in rolls[name].steps.items():
            np.testing.assert_array_equal(x, merged.steps[k], err_msg=f"{name} {k}")


def test_without_ray_eval_workers_says_how_to_get_it(monkeypatch, capsys):
    from navgym.cli import main

    monkeypatch.setitem(sys.modules, "ray", None)
    assert (
        main(["eval", "--env", ENV, "--episodes", "4", "--workers", "2", "--ray", "--quiet", "--no-plots"])
        == 2
    )
    err = capsys.readouterr().err
    assert "needs the 'scale' extra (missing module 'ray')" in err and "pip install -e '.[scale]'" in err


@pytest.mark.slow
def test_distributed_eval_equals_local_eval_bit_for_bit(tmp_path):
    pytest.importorskip("ray")
    from agents.evaluation.cli import run_eval
    from agents.scale.ray_runtime import init_ray
    from tests.agents.evaluation.same_results import assert_same_results

    init_ray(num_cpus=2)
    kw = {"env_kwargs": SHORT, "n_boot": 500, "plots": False, "progress": False}
    local = run_eval(ENV, ["baselines", AGENT], 2 * ALIGN + 5, tmp_path / "local", **kw)
    dist = run_eval(ENV, ["baselines", AGENT], 2 * ALIGN + 5, tmp_path / "dist", workers=2, ray=True, **kw)
    assert_same_results(dist, local, tmp_path / "dist", tmp_path / "local", parts=2)
