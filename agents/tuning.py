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

With ``--ray`` (the ``scale`` extra) the grid points are scored as Ray Tune trials, on local
Ray or a cluster (``--address``), with the same results
(:func:`agents.scale.ray_tuning.ray_tune`); ``--samples K`` scores only K points chosen by
Optuna's TPE sampler, for grids too large to score whole.

Usage::

    python -m agents.tuning --env navgym/GpsInsFading-v0 --episodes 64
    navgym tune --env navgym/GpsInsFading-v0 --episodes 64 --ray [--samples 40] [--address ray://HEAD:10001]
"""

from __future__ import annotations

import argparse
import itertools
import json
import shlex
import sys
import time
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from agents.baselines.registry import TUNED_DIR, baseline_specs, tuned_path
from agents.evaluation.metrics import episode_metrics
from agents.evaluation.report import environment_versions, git_commit
from agents.evaluation.runner import make_vector_env, rollout
from agents.seeds import check_seeds
from agents.seeds import seeds as seed_range
from navgym.envs.base import navigation_env

__all__ = ["add_arguments", "grid_points", "main", "run", "tune", "tune_env"]

#: Default sub-envs per batched rollout (particle tasks: fewer, their state is B x N x n).
MAX_BATCH = {"Resample": 256}
DEFAULT_MAX_BATCH = 1024


def grid_points(grid: Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """Cartesian product of a parameter grid, in order (last parameter fastest)."""
    keys = list(grid)
    return [
        dict(zip(keys, map(float, vals), strict=True)) for vals in itertools.product(*(grid[k] for k in keys))
    ]


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

    Returns:
        ``{"params", "score", "rmse_m", "diverged", "grid": [{"params", "mean_return",
        "rmse_m", "scored_rmse_m", "diverged"}, ...], "seconds"}``.
    """
    t0 = time.perf_counter()
    seeds = seed_range("tune", episodes, seed_offset)
    check_seeds("tune", seeds)
    probe = make_vector_env(env_id, 1, env_kwargs)
    specs = baseline_specs(probe)
    if baseline not in specs:
        raise ValueError(f"no baseline {baseline!r} for {env_id}; have {sorted(specs)}")
    spec = specs[baseline]
    nav = navigation_env(probe)
    T = nav.horizon
    divergence_m = float(nav.platform.divergence_m)
    points = grid_points(spec.grid if grid is None else grid) or [{}]
    mb = max_batch or MAX_BATCH.get(nav.task.name, DEFAULT_MAX_BATCH)
    per_chunk = max(1, mb // episodes)
    chunks = [points[i : i + per_chunk] for i in range(0, len(points), per_chunk)]
    pbar = None
    if progress:
        from tqdm.auto import tqdm

        pbar = tqdm(
            total=len(chunks) * T, desc=f"tune {baseline} ({len(points)} points x {episodes})", leave=False
        )
    rows = []
    try:
        for chunk in chunks:
            G = len(chunk)
            env = make_vector_env(env_id, G * episodes, env_kwargs)
            params = {k: np.repeat([p[k] for p in chunk], episodes) for k in chunk[0]}
            policy = spec.cls(env, **{**spec.fixed, **params})
            roll = rollout(env, policy, seeds * G, pbar=pbar)
            if pbar is not None:
                pbar.update(T - int(roll.length.max()))
            m = episode_metrics(roll, divergence_m)
            for g, p in enumerate(chunk):
                sl = slice(g * episodes, (g + 1) * episodes)
                rows.append(
                    {
                        "params": {**dict(spec.fixed), **p},
                        "mean_return": float(np.mean(m["return"][sl])),
                        "rmse_m": float(np.mean(m["rmse_m"][sl])),
                        "scored_rmse_m": float(np.mean(m["scored_rmse_m"][sl])),
                        "diverged": float(np.mean(m["diverged"][sl])),
                    }
                )
            env.close()
    finally:
        if pbar is not None:
            pbar.close()
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
    ray: bool = False,
    samples: int | None = None,
    address: str | None = None,
) -> dict[str, Any]:
    """Tune every baseline of ``env_id``'s task (or ``baselines``); write the JSON; return its content.

    An existing file is updated: baselines not re-tuned keep their entries. ``ray``: score the
    points as Ray Tune trials (``samples``: Optuna picks that many points; ``address``: a Ray
    cluster), :func:`agents.scale.ray_tuning.ray_tune`.
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
        if ray:
            from agents.scale.ray_tuning import ray_tune

            entries[name] = ray_tune(
                env_id,
                name,
                episodes=episodes,
                seed_offset=seed_offset,
                env_kwargs=env_kwargs,
                max_batch=max_batch,
                samples=samples,
                address=address,
                progress=progress,
            )
            continue
        entries[name] = tune(
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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of the tuning job."""
    parser.add_argument("--env", required=True, nargs="+", help="env id(s)")
    parser.add_argument(
        "--baselines", nargs="+", default=None, help="baselines to tune (default: all of the task)"
    )
    parser.add_argument("--episodes", type=int, default=64, help="tuning episodes per grid point")
    parser.add_argument("--seed-offset", type=int, default=0, help="offset into the tuning seed range")
    parser.add_argument("--env-kwargs", default="{}", help="env keyword arguments as JSON")
    parser.add_argument("--out", default=None, help=f"output directory (default {TUNED_DIR})")
    parser.add_argument("--max-batch", type=int, default=None, help="sub-envs per batched rollout")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument("--ray", action="store_true", help="score the grid points as Ray Tune trials")
    parser.add_argument(
        "--samples", type=int, default=None, help="with --ray: score K points chosen by Optuna (large grids)"
    )
    parser.add_argument("--address", default=None, help="with --ray: Ray cluster address (default: local)")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym tune`` to the ``navgym`` command's sub-parsers (:mod:`navgym.cli`)."""
    parser = subparsers.add_parser("tune", help="grid-search the classical baselines on tuning seeds")
    add_arguments(parser)
    parser.set_defaults(_run=run)


def _command(argv: Sequence[str] | None) -> str:
    """The command line to record: ``python -m agents.tuning ...`` or ``navgym tune ...``."""
    if argv is not None:
        return "python -m agents.tuning " + " ".join(shlex.quote(a) for a in argv)
    prog = Path(sys.argv[0])
    head = "navgym" if "navgym" in (prog.stem, prog.parent.name) else "python -m agents.tuning"
    return head + " " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def run(args: argparse.Namespace, argv: Sequence[str] | None = None) -> int:
    """Tune each ``--env``; print the best parameters (``--ray`` without Ray: says so, status 2)."""
    ray = getattr(args, "ray", False)
    if ray:
        from agents.scale.ray_runtime import MissingExtraError, report_missing, require_ray

        try:
            require_ray("navgym tune --ray")
        except MissingExtraError as exc:
            return report_missing("navgym tune --ray", exc)
    elif getattr(args, "samples", None) is not None or getattr(args, "address", None) is not None:
        raise ValueError("--samples and --address go with --ray")
    command = _command(argv)
    for env_id in args.env:
        data = tune_env(
            env_id,
            args.baselines,
            episodes=args.episodes,
            seed_offset=args.seed_offset,
            env_kwargs=json.loads(args.env_kwargs),
            out_dir=args.out,
            command=command,
            max_batch=args.max_batch,
            progress=not args.quiet,
            ray=ray,
            samples=getattr(args, "samples", None),
            address=getattr(args, "address", None),
        )
        print(f"{env_id} -> {tuned_path(env_id, args.out)}")
        for name, e in data["baselines"].items():
            print(f"  {name:16s} score {e['score']:9.2f}  rmse {e['rmse_m']:8.2f} m  ", end="")
            print(f"{e['params']}  ({e['seconds']} s)")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.tuning --env ID [--episodes N] [--baselines ...]``."""
    p = argparse.ArgumentParser(prog="python -m agents.tuning", description=__doc__.splitlines()[0])
    add_arguments(p)
    argv = list(sys.argv[1:] if argv is None else argv)
    return run(p.parse_args(argv), argv)


if __name__ == "__main__":
    sys.exit(main())
