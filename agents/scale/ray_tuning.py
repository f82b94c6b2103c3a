"""``navgym tune --ray``: the baselines' grid search as Ray Tune trials (Optuna where the grid is large).

:func:`ray_tune` scores grid points of one baseline in Ray Tune trials, each trial one point
through the local search itself (:func:`agents.tuning.search.tune` with a one-point grid: the
same tuning episodes, the same score), and returns what :func:`agents.tuning.search.tune`
returns: the best point (highest mean return on the tuning seeds; ties to the first in grid
order) and the scored points in grid order. :class:`RayTuneStrategy` is it as the
:class:`agents.tuning.search.TuneStrategy` that :func:`agents.tuning.search.tune_env` takes
(this module depends on the search, never the other way).

Every point (``samples`` None) is a grid search and gives the local grid's results; with
``samples`` smaller than the grid, Optuna's TPE sampler (``ray.tune.search.optuna.OptunaSearch``,
seeded) picks that many points among the grid's values, and only those are scored.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from agents.baselines.registry import baseline_specs
from agents.evaluation.runner import make_vector_env
from agents.scale.ray_runtime import init_ray, require_ray
from agents.tuning.search import grid_points
from agents.tuning.search import tune as local_tune

__all__ = ["RayTuneStrategy", "ray_tune", "score_point"]

METRIC = "mean_return"


def score_point(config: Mapping[str, Any], spec: Mapping[str, Any]) -> dict[str, Any]:
    """The Tune trainable: score one grid point (``config``: index or parameter values); report it."""
    from ray import tune

    from filters.core.threads import set_num_threads

    set_num_threads(1)  # a trial holds one CPU of Ray's ({"cpu": 1}): its particle passes stay on it
    if "index" in config:
        point = spec["points"][int(config["index"])]
    else:
        point = {k: float(config[k]) for k in spec["keys"]}
    res = local_tune(
        spec["env_id"],
        spec["baseline"],
        grid={k: [v] for k, v in point.items()},
        episodes=spec["episodes"],
        seed_offset=spec["seed_offset"],
        env_kwargs=spec["env_kwargs"],
        max_batch=spec["max_batch"],
        progress=False,
    )
    row = res["grid"][0]
    metrics = {
        "point": point,
        METRIC: row["mean_return"],
        "rmse_m": row["rmse_m"],
        "diverged": row["diverged"],
    }
    tune.report(metrics)
    return metrics


def ray_tune(
    env_id: str,
    baseline: str,
    grid: Mapping[str, Sequence[float]] | None = None,
    *,
    episodes: int = 64,
    seed_offset: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    max_batch: int | None = None,
    samples: int | None = None,
    search_seed: int = 0,
    max_concurrent: int | None = None,
    address: str | None = None,
    num_cpus: int | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """:func:`agents.tuning.search.tune` with the grid points scored as Ray Tune trials.

    Args:
        env_id: registered env id.
        baseline: baseline name of the env's task.
        grid: ``{param: values}``; default the registry's grid (empty: the fixed baseline,
            scored locally).
        episodes: tuning episodes per point.
        seed_offset: offset into the tuning seed range.
        env_kwargs: env keyword arguments.
        max_batch: sub-envs per batched rollout within a trial.
        samples: score only this many points, chosen by Optuna's TPE sampler among the grid's
            values (None, or >= the grid's size: every point, a grid search).
        search_seed: seed of the Optuna sampler.
        max_concurrent: trials at once (default: one per CPU).
        address: Ray cluster address; ``None``: local Ray.
        num_cpus: CPUs of a local Ray (default: all cores).
        progress: Tune's status table.

    Returns:
        The dict of :func:`agents.tuning.search.tune` (``grid``: the scored points in grid order),
        with ``search``: ``"ray grid"`` or ``"ray optuna, k of n points"``.
    """
    require_ray("navgym tune --ray")
    from ray import tune

    t0 = time.perf_counter()
    probe = make_vector_env(env_id, 1, env_kwargs)
    specs = baseline_specs(probe)
    probe.close()
    if baseline not in specs:
        raise ValueError(f"no baseline {baseline!r} for {env_id}; have {sorted(specs)}")
    spec = specs[baseline]
    grid = dict(spec.grid if grid is None else grid)
    points = grid_points(grid)
    if not points:  # nothing to search: the fixed baseline, scored as the local search does
        return {
            **local_tune(
                env_id,
                baseline,
                grid,
                episodes=episodes,
                seed_offset=seed_offset,
                env_kwargs=env_kwargs,
                max_batch=max_batch,
                progress=False,
            ),
            "search": "local",
        }
    if samples is not None and samples < 1:
        raise ValueError(f"samples must be >= 1; got {samples}")
    optuna = samples is not None and samples < len(points)
    trial_spec = {
        "env_id": env_id,
        "baseline": baseline,
        "points": points,
        "keys": list(grid),
        "episodes": int(episodes),
        "seed_offset": int(seed_offset),
        "env_kwargs": dict(env_kwargs or {}),
        "max_batch": max_batch,
    }
    if optuna:
        from ray.tune.search.optuna import OptunaSearch

        space = {k: tune.choice([float(v) for v in vals]) for k, vals in grid.items()}
        search = OptunaSearch(metric=METRIC, mode="max", seed=search_seed)
        tune_config = tune.TuneConfig(
            search_alg=search, num_samples=int(samples), max_concurrent_trials=max_concurrent
        )
    else:
        space = {"index": tune.grid_search(list(range(len(points))))}
        tune_config = tune.TuneConfig(max_concurrent_trials=max_concurrent)
    init_ray(address, num_cpus)
    trainable = tune.with_resources(tune.with_parameters(score_point, spec=trial_spec), {"cpu": 1})
    with tempfile.TemporaryDirectory(prefix="navgym-tune-") as storage:
        tuner = tune.Tuner(
            trainable,
            param_space=space,
            tune_config=tune_config,
            run_config=tune.RunConfig(name=f"tune-{baseline}", storage_path=storage, verbose=int(progress)),
        )
        results = tuner.fit()
        errors = [str(r.error) for r in results if r.error is not None]
        if errors:
            raise RuntimeError(f"{len(errors)} tuning trials failed; first: {errors[0]}")
        scored = {tuple(sorted(r.metrics["point"].items())): r.metrics for r in results}
    rows = []
    for p in points:  # grid order, each scored point once
        m = scored.get(tuple(sorted(p.items())))
        if m is not None:
            rows.append(
                {
                    "params": {**dict(spec.fixed), **p},
                    "mean_return": m[METRIC],
                    "rmse_m": m["rmse_m"],
                    "diverged": m["diverged"],
                }
            )
    best = max(range(len(rows)), key=lambda i: (rows[i]["mean_return"], -i))
    b = rows[best]
    return {
        "params": b["params"],
        "score": b["mean_return"],
        "rmse_m": b["rmse_m"],
        "diverged": b["diverged"],
        "tuned": True,
        "grid": rows,
        "seconds": round(time.perf_counter() - t0, 1),
        "search": f"ray optuna, {len(rows)} of {len(points)} points" if optuna else "ray grid",
    }


@dataclass(frozen=True)
class RayTuneStrategy:
    """:func:`ray_tune` as a :class:`agents.tuning.search.TuneStrategy` (``navgym tune --ray``).

    Attributes:
        samples: Optuna picks this many points (``None``: every point, a grid search).
        address: Ray cluster address; ``None``: local Ray.
        search_seed: seed of the Optuna sampler.
        max_concurrent: trials at once (default: one per CPU).
        num_cpus: CPUs of a local Ray (default: all cores).
    """

    samples: int | None = None
    address: str | None = None
    search_seed: int = 0
    max_concurrent: int | None = None
    num_cpus: int | None = None

    def __call__(
        self,
        env_id: str,
        baseline: str,
        grid: Mapping[str, Sequence[float]] | None = None,
        *,
        episodes: int = 64,
        seed_offset: int = 0,
        env_kwargs: Mapping[str, Any] | None = None,
        max_batch: int | None = None,
        progress: bool = True,
    ) -> dict[str, Any]:
        return ray_tune(
            env_id,
            baseline,
            grid,
            episodes=episodes,
            seed_offset=seed_offset,
            env_kwargs=env_kwargs,
            max_batch=max_batch,
            samples=self.samples,
            search_seed=self.search_seed,
            max_concurrent=self.max_concurrent,
            address=self.address,
            num_cpus=self.num_cpus,
            progress=progress,
        )
