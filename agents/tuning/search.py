"""Grid search of the parametrised baselines on **tuning seeds only**; results cached as JSON.

For every baseline of the env's task with a grid (:data:`agents.baselines.BASELINES`), every
grid point is run on the same ``episodes`` tuning episodes (``agents.seeds.seeds("tune", n)``,
checked with ``check_seeds``), the whole grid batched into native vector envs (sub-env = grid
point x episode, parameters passed as ``(B,)`` arrays), in chunks of at most ``max_batch``
sub-envs. The **score is the mean episode return** (higher is better): the quantity agents
maximise (accuracy, action costs and the divergence penalty together); the mean horizontal RMSE
and the divergence rate of each point are recorded too. Ties go to the first point in grid order.

Results go to ``agents/baselines/tuned/<EnvName-vK>.json`` with the command that produced them,
the seeds, versions and git commit; :func:`agents.baselines.load_tuned` reads them, so
evaluation never re-tunes. Baselines without a grid are scored on the same episodes and
recorded with their fixed parameters.

How one baseline's points are scored is a :class:`TuneStrategy` passed to :func:`tune_env`:
:func:`tune` (here, the default) or another with the same results, e.g.
:class:`agents.scale.ray_tuning.RayTuneStrategy` (Ray Tune trials, Optuna for large grids),
which builds on this module; this module imports no scale-out code. The command line is
:mod:`agents.tuning.cli`.
"""

from __future__ import annotations

import itertools
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from agents.baselines.registry import baseline_specs, tuned_path
from agents.evaluation.metrics import episode_metrics
from agents.evaluation.runner import make_vector_env, rollout
from agents.reporting import environment_versions, git_commit
from agents.seeds import check_seeds
from agents.seeds import seeds as seed_range
from agents.workers import can_fork, map_chunks
from navgym.envs.base import navigation_env
from navgym.envs.distinct import EpisodeCache

__all__ = [
    "DEFAULT_MAX_BATCH",
    "LocalTuneStrategy",
    "MAX_BATCH",
    "TuneStrategy",
    "grid_points",
    "score_points",
    "tune",
    "tune_env",
]

#: Default sub-envs per batched rollout (particle tasks: fewer, their state is B x N x n).
MAX_BATCH = {"Resample": 256}
DEFAULT_MAX_BATCH = 1024


def grid_points(grid: Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """Cartesian product of a parameter grid, in order (last parameter fastest)."""
    keys = list(grid)
    return [
        dict(zip(keys, map(float, vals), strict=True)) for vals in itertools.product(*(grid[k] for k in keys))
    ]


def score_points(
    env_id: str,
    points: Sequence[Any],
    make_policy: Callable[[Any, Sequence[Any], int], Any],
    seeds: Sequence[int],
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    max_batch: int | None = None,
    desc: str | None = None,
    workers: int = 1,
) -> list[dict[str, float]]:
    """Mean episode metrics of each grid point's policy, every point on the same episodes.

    The points run batched: a chunk of ``G`` points is one native vector env of ``G * n``
    sub-envs (``n = len(seeds)``, point-major: point ``g`` has rows ``g * n .. (g + 1) * n``),
    reset with ``seeds`` repeated ``G`` times, chunks of at most ``max_batch`` sub-envs (default
    :data:`MAX_BATCH` of the env's task, else :data:`DEFAULT_MAX_BATCH`). Seeds are not checked
    here. The envs are made with ``eval_info=False`` unless ``env_kwargs`` says otherwise: no
    score reads the NEES, whose Cholesky per filter is some 5 % of a 15-state filter's step.
    The chunks' episodes are simulated once per process (:class:`navgym.envs.distinct.EpisodeCache`).

    Args:
        env_id: registered env id.
        points: the grid points (anything ``make_policy`` takes).
        make_policy: ``(env, chunk, n) -> policy`` for a chunk of points.
        seeds: the episodes of every point.
        env_kwargs: env keyword arguments.
        max_batch: sub-envs per batched rollout.
        desc: a tqdm bar over the rollout steps with this label (``None``: no bar).
        workers: chunks scored at a time, in forked processes
            (:func:`agents.workers.map_chunks`); the rows do not depend on it.

    Returns:
        One row per point, in order: ``{"mean_return", "rmse_m", "scored_rmse_m", "diverged"}``
        (means over the point's episodes of :func:`agents.evaluation.metrics.episode_metrics`).
    """
    if int(workers) < 1:
        raise ValueError(f"workers must be at least 1; got {workers}")
    n = len(seeds)
    probe = make_vector_env(env_id, 1, env_kwargs)
    nav = navigation_env(probe)
    T = nav.horizon
    divergence_m = float(nav.platform.divergence_m)
    task = str(nav.task.name)
    probe.close()
    # the scores read returns, errors and divergence, not the NEES (an explicit eval_info stays)
    scoring_kwargs = {"eval_info": False, **dict(env_kwargs or {})}
    per_chunk = max(1, (max_batch or MAX_BATCH.get(task, DEFAULT_MAX_BATCH)) // n)
    chunks = [points[i : i + per_chunk] for i in range(0, len(points), per_chunk)]
    pbar = None
    if desc is not None:
        from tqdm.auto import tqdm

        # disable=None: no bar where stderr is not a terminal (a log file, a pipe)
        pbar = tqdm(total=len(chunks) * T, desc=desc, leave=False, disable=None)
    serial = int(workers) == 1 or len(chunks) == 1 or not can_fork()
    # every chunk resets the same episodes: each process simulates them once (its own copy)
    cache = EpisodeCache()

    def job(i: int) -> list[dict[str, float]]:
        chunk = chunks[i]
        G = len(chunk)
        env = make_vector_env(env_id, G * n, scoring_kwargs)
        # the bar advances per step here, per chunk from a worker (on_done)
        with cache.active():
            roll = rollout(env, make_policy(env, chunk, n), list(seeds) * G, pbar=pbar if serial else None)
        if pbar is not None and serial:
            pbar.update(T - int(roll.length.max()))
        m = episode_metrics(roll, divergence_m)
        env.close()
        return [
            {
                "mean_return": float(np.mean(m["return"][sl])),
                "rmse_m": float(np.mean(m["rmse_m"][sl])),
                "scored_rmse_m": float(np.mean(m["scored_rmse_m"][sl])),
                "diverged": float(np.mean(m["diverged"][sl])),
            }
            for sl in (slice(g * n, (g + 1) * n) for g in range(G))
        ]

    def done(i: int) -> None:
        if pbar is not None and not serial:
            pbar.update(T)

    try:
        per_chunk_rows = map_chunks(job, len(chunks), 1 if serial else int(workers), on_done=done)
    finally:
        if pbar is not None:
            pbar.close()
    return [row for rows in per_chunk_rows for row in rows]


class TuneStrategy(Protocol):
    """How the grid points of one baseline are scored: :func:`tune`'s signature and result.

    Called as ``strategy(env_id, baseline, grid, episodes=, seed_offset=, env_kwargs=,
    max_batch=, progress=)``; ``grid`` ``None`` is the registry's grid. Returns
    :func:`tune`'s dict (``params``, ``score``, ``rmse_m``, ``diverged``, ``tuned``, ``grid``,
    ``seconds``; a strategy may add keys, e.g. ``search``).
    """

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
    ) -> dict[str, Any]: ...


@dataclass(frozen=True)
class LocalTuneStrategy:
    """:func:`tune` on ``workers`` processes: the :class:`TuneStrategy` of ``navgym tune --workers``."""

    workers: int = 1

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
        return tune(
            env_id,
            baseline,
            grid,
            episodes=episodes,
            seed_offset=seed_offset,
            env_kwargs=env_kwargs,
            max_batch=max_batch,
            progress=progress,
            workers=self.workers,
        )


def tune(
    env_id: str,
    baseline: str,
    grid: Mapping[str, Sequence[float]] | None = None,
    *,
    episodes: int = 64,
    seed_offset: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    max_batch: int | None = None,
    progress: bool = True,
    workers: int = 1,
) -> dict[str, Any]:
    """Grid search of one baseline; returns the best parameters and the scored grid.

    Args:
        env_id: registered env id.
        baseline: baseline name of the env's task (e.g. ``"suboptimal"``).
        grid: ``{param: values}``; default the registry's grid (empty: score the fixed baseline).
        episodes: tuning episodes per grid point (the same episodes for every point).
        seed_offset: offset into the tuning seed range.
        env_kwargs: env keyword arguments.
        max_batch: sub-envs per batched rollout (default 1024; 256 for particle tasks).
        progress: tqdm bar over the rollout steps.
        workers: chunks of grid points scored at a time in forked processes (:func:`score_points`;
            the results do not depend on it). ``navgym tune`` uses every core (``--workers``).

    Returns:
        ``{"params", "score", "rmse_m", "diverged", "grid": [{"params", "mean_return",
        "rmse_m", "scored_rmse_m", "diverged"}, ...], "seconds"}``.
    """
    t0 = time.perf_counter()
    seeds = seed_range("tune", episodes, seed_offset)
    check_seeds("tune", seeds)
    probe = make_vector_env(env_id, 1, env_kwargs)
    specs = baseline_specs(probe)
    probe.close()
    if baseline not in specs:
        raise ValueError(f"no baseline {baseline!r} for {env_id}; have {sorted(specs)}")
    spec = specs[baseline]
    points = grid_points(spec.grid if grid is None else grid) or [{}]

    def make_policy(env: Any, chunk: Sequence[Mapping[str, float]], n: int) -> Any:
        params = {k: np.repeat([p[k] for p in chunk], n) for k in chunk[0]}
        return spec.cls(env, **{**spec.fixed, **params})

    scores = score_points(
        env_id,
        points,
        make_policy,
        seeds,
        env_kwargs=env_kwargs,
        max_batch=max_batch,
        desc=f"tune {baseline} ({len(points)} points x {episodes})" if progress else None,
        workers=workers,
    )
    rows = [{"params": {**dict(spec.fixed), **p}, **r} for p, r in zip(points, scores, strict=True)]
    best = max(range(len(rows)), key=lambda i: (rows[i]["mean_return"], -i))
    b = rows[best]
    return {
        "params": b["params"],
        "score": b["mean_return"],
        "rmse_m": b["rmse_m"],
        "diverged": b["diverged"],
        "tuned": bool(spec.grid) if grid is None else bool(grid),
        "grid": rows,
        "seconds": round(time.perf_counter() - t0, 1),
    }


def tune_env(
    env_id: str,
    baselines: Sequence[str] | None = None,
    *,
    episodes: int = 64,
    seed_offset: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    out_dir: str | Path | None = None,
    write: bool = True,
    command: str | None = None,
    max_batch: int | None = None,
    progress: bool = True,
    strategy: TuneStrategy = tune,
) -> dict[str, Any]:
    """Tune every baseline of ``env_id``'s task (or ``baselines``); write the JSON; return its content.

    An existing file is updated: baselines not re-tuned keep their entries. ``strategy`` scores
    each baseline's points (default :func:`tune`, the batched local search).
    """
    names = list(baselines or baseline_specs(make_vector_env(env_id, 1, env_kwargs)))
    path = tuned_path(env_id, out_dir)
    data: dict[str, Any] = {}
    if path.exists():
        old = json.loads(path.read_text())
        if old.get("env_id") == env_id and old.get("env_kwargs", {}) == dict(env_kwargs or {}):
            data = old
    entries = dict(data.get("baselines", {}))
    for name in names:
        entries[name] = strategy(
            env_id,
            name,
            episodes=episodes,
            seed_offset=seed_offset,
            env_kwargs=env_kwargs,
            max_batch=max_batch,
            progress=progress,
        )
    seeds = seed_range("tune", episodes, seed_offset)
    data = {
        "env_id": env_id,
        "env_kwargs": dict(env_kwargs or {}),
        "command": command or f"python -m agents.tuning --env {env_id} --episodes {episodes}",
        "score": "mean episode return on the tuning seeds (higher is better)",
        "seeds": {"kind": "tune", "n": episodes, "offset": seed_offset, "first": seeds[0], "last": seeds[-1]},
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "git": git_commit(),
        "versions": environment_versions(),
        "baselines": entries,
    }
    if write:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=1) + "\n")
    return data
