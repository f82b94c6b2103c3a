"""navgym tune --ray: the grid points as Ray Tune trials give the local grid's results."""

import sys

import pytest

pytest.importorskip("stable_baselines3")

ENV = "navgym/Robot2dFading-v2"
SHORT = {"episode_steps": 20, "max_episode_steps": 20}
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def test_without_ray_tune_ray_says_how_to_get_it(monkeypatch, capsys):
    from navgym.cli import main

    monkeypatch.setitem(sys.modules, "ray", None)
    assert main(["tune", "--env", ENV, "--ray", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "navgym tune --ray: needs the 'scale' extra (missing module 'ray')" in err


def test_samples_without_ray_is_an_error(capsys):
    from navgym.cli import main

    assert main(["tune", "--env", ENV, "--samples", "3", "--quiet"]) == 2
    assert "--samples and --address go with --ray" in capsys.readouterr().err


@pytest.mark.slow
def test_ray_grid_equals_local_grid_and_optuna_scores_grid_points():
    pytest.importorskip("ray")
    pytest.importorskip("optuna")
    from agents.scale.ray_runtime import init_ray
    from agents.scale.ray_tuning import ray_tune
    from agents.tuning import tune

    init_ray(num_cpus=2)
    grid = {"rho": [0.9, 0.95, 0.99], "beta": [1.0, 2.0]}
    kw = {"episodes": 6, "env_kwargs": SHORT, "progress": False}
    local = tune(ENV, "suboptimal", grid, **kw)
    remote = ray_tune(ENV, "suboptimal", grid, **kw)
    assert remote["search"] == "ray grid"
    assert remote["grid"] == local["grid"]  # every point, same episodes: the same floats
    for k in ("params", "score", "rmse_m", "diverged", "tuned"):
        assert remote[k] == local[k], k
    picked = ray_tune(ENV, "suboptimal", grid, samples=3, search_seed=1, **kw)
    assert picked["search"].startswith("ray optuna") and 1 <= len(picked["grid"]) <= 3
    by_point = {tuple(sorted(r["params"].items())): r for r in local["grid"]}
    for r in picked["grid"]:  # each sampled point scored as the local grid scores it
        assert r == by_point[tuple(sorted(r["params"].items()))]
    assert picked["score"] == max(r["mean_return"] for r in picked["grid"])
