"""``navgym sweep``: training sweeps (grid x seeds) as Ray Tune trials, with a per-config summary.

``navgym sweep ENV_ID --algo ppo --seeds 0..9 [--grid KEY=V1,V2 ...] [--timesteps N]
[--out DIR] [--max-concurrent K] [--address ray://HEAD:10001]``

Each trial (one grid point, one seed) runs :func:`agents.training.train` into
``DIR/trials/c<config>_seed<seed>/`` (the run folder of ``navgym train``: checkpoints every
``checkpoint_freq`` steps, TensorBoard logs in ``tb/``, the saved agent) and then evaluates
the agent on held-out episodes (:func:`agents.evaluation.evaluate`, evaluation seeds, the env's
default kwargs unless ``--eval-env-kwargs``): mean return, RMSE, divergence rate, reported to
Tune. Local Ray by default, one CPU per trial, as many trials at once as cores (or
``--max-concurrent``); ``--address`` joins an existing cluster (its nodes need navgym and
``DIR`` on a shared file system). A local Ray keeps its session files (logs, sockets, spilled
objects) in ``DIR/ray``, not in the system temp folder. Every grid point is checked (SB3
argument names, ``env_kwargs``) before Ray starts.

Interrupted sweeps resume: running the same command again finds Tune's experiment in
``DIR/tune`` and continues it with ``tune.Tuner.restore`` (finished trials kept, unfinished
and failed ones rerun); a rerun trial resumes its training from its newest checkpoint
(``train(..., resume=True)``). ``DIR/sweep.json`` records the sweep; a different sweep into the
same ``DIR`` is refused.

Outputs: ``DIR/trials.csv`` (one row per trial), ``DIR/summary.csv`` and ``DIR/summary.md``
(per config: mean and 95 % Student-t interval over seeds, :mod:`agents.scale.summary`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.cli_args import add_gym_packages, import_gym_packages, module_roots
from agents.reporting import write_csv
from agents.scale.ray_runtime import MissingExtraError, init_ray, report_missing, require_ray
from agents.scale.specs import (
    check_trials,
    config_label,
    grid_configs,
    make_trials,
    parse_grid,
    parse_seeds,
)
from agents.scale.summary import summarize_trials, summary_table

__all__ = ["SweepResult", "add_arguments", "register", "run_trial", "sweep"]

PROG = "navgym sweep"
SPEC_FILE = "sweep.json"
#: Columns of ``trials.csv``: the metrics a trial reports.
TRIAL_COLUMNS = (
    "config_id",
    "seed",
    "return",
    "rmse_m",
    "diverged",
    "train_wall_s",
    "timesteps",
    "resumed_from",
    "run_dir",
)
#: Held-out episodes per trial when not told.
DEFAULT_EVAL_EPISODES = 64


@dataclass
class SweepResult:
    """What :func:`sweep` returns: the folder, one row per trial, one per config, the table."""

    out: Path
    trials: list[dict[str, Any]]
    summary: list[dict[str, Any]]
    table: str
    errors: list[str]
    resumed: bool
    wall_s: float


def run_trial(config: Mapping[str, Any], spec: Mapping[str, Any]) -> dict[str, Any]:
    """The Tune trainable: train trial ``config["index"]`` of ``spec``, evaluate it, report.

    Returns (and reports) the trial's metrics: ``return``, ``rmse_m``, ``diverged`` (held-out
    means), ``train_wall_s``, ``timesteps``, with ``config``, ``seed`` and ``run_dir``.
    """
    import numpy as np
    from ray import tune

    from agents.evaluation.runner import evaluate
    from agents.seeds import seeds as seed_range
    from agents.training.loading import load_agent
    from agents.training.train import train

    import_gym_packages(spec.get("gym_packages", ()), spec.get("gym_paths", ()))  # --gym-packages' ids
    t = spec["trials"][int(config["index"])]
    run_dir = Path(spec["out"]) / "trials" / t["name"]
    t0 = time.time()
    train(
        spec["env_id"],
        algo=spec["algo"],
        config=t["entry"],
        seed=t["seed"],
        total_timesteps=spec["timesteps"],
        out_dir=run_dir,
        resume=True,
        progress=False,
        n_envs=spec["n_envs"],
        torch_threads=1,
    )
    train_s = time.time() - t0
    meta = json.loads((run_dir / "meta.json").read_text())
    agent = load_agent(run_dir)
    seeds = seed_range("eval", spec["eval_episodes"])
    res = evaluate(
        spec["env_id"], {"agent": agent}, seeds, spec["eval_env_kwargs"], n_boot=200, progress=False
    )
    ep = res.episodes["agent"]
    metrics = {
        "config_id": t["config"],
        "seed": t["seed"],
        "return": float(np.mean(ep["return"])),
        "rmse_m": float(np.nanmean(ep["rmse_m"])),
        "diverged": float(np.mean(ep["diverged"])),
        "train_wall_s": float(meta.get("wall_time_s", train_s)),
        "timesteps": int(meta["total_timesteps"]),
        "resumed_from": meta.get("resumed_from_timesteps"),
        "run_dir": str(run_dir),
    }
    (run_dir / "eval.json").write_text(json.dumps(metrics, indent=1) + "\n")
    tune.report(metrics)
    return metrics


def _spec(
    env_id: str,
    algo: str,
    seeds: Sequence[int],
    grid: Mapping[str, Sequence[Any]],
    out: Path,
    timesteps: int | None,
    n_envs: int | None,
    config: Any,
    eval_episodes: int,
    eval_env_kwargs: Mapping[str, Any] | None,
    checkpoint_freq: int | None,
    gym_packages: Sequence[str] = (),
) -> dict[str, Any]:
    """The sweep's description (``sweep.json``): everything the trials need, JSON only.

    ``gym_packages`` (the modules registering ``env_id``, imported by each trial) is recorded
    only when given, so that sweeps recorded before it resume.
    """
    from agents.training.config import check_algo
    from agents.training.train import _check_env_id, resolve_config

    algo = check_algo(algo)
    import_gym_packages(gym_packages)
    _check_env_id(env_id)
    entry = resolve_config(env_id, algo, config)
    if checkpoint_freq is not None:
        entry["checkpoint_freq"] = int(checkpoint_freq)
    if eval_episodes < 1:
        raise ValueError(f"--eval-episodes must be >= 1; got {eval_episodes}")
    trials = make_trials(entry, grid, seeds)
    check_trials(env_id, algo, trials)  # before Ray starts: a wrong key fails here, not in a trial
    packages = (
        {"gym_packages": [str(p) for p in gym_packages], "gym_paths": module_roots(gym_packages)}
        if gym_packages
        else {}
    )
    return json.loads(
        json.dumps(
            {
                **packages,
                "env_id": env_id,
                "algo": algo,
                "seeds": list(seeds),
                "grid": {k: list(v) for k, v in grid.items()},
                "labels": [config_label(c) for c in grid_configs(grid)],
                "timesteps": None if timesteps is None else int(timesteps),
                "n_envs": n_envs,
                "config": None if config is None or isinstance(config, dict) else str(config),
                "eval_episodes": int(eval_episodes),
                "eval_env_kwargs": dict(eval_env_kwargs or {}),
                "out": str(out),
                "trials": [
                    {"index": t.index, "config": t.config, "seed": t.seed, "name": t.name, "entry": t.entry}
                    for t in trials
                ],
            }
        )
    )


def _check_same_sweep(path: Path, spec: Mapping[str, Any]) -> None:
    """``ValueError`` when ``path`` records a different sweep than ``spec``."""
    if not path.is_file():
        return
    old = json.loads(path.read_text())
    diff = sorted(k for k in spec if k != "out" and old.get(k) != spec[k])
    if diff:
        raise ValueError(
            f"{path.parent} holds another sweep ({', '.join(diff)} differ): use another --out, or "
            "the same arguments to resume it"
        )


def sweep(
    env_id: str,
    algo: str = "ppo",
    seeds: Sequence[int] | str = (0,),
    grid: Mapping[str, Sequence[Any]] | Sequence[str] | None = None,
    out: str | Path | None = None,
    *,
    timesteps: int | None = None,
    n_envs: int | None = None,
    config: str | Path | dict[str, Any] | None = None,
    eval_episodes: int = DEFAULT_EVAL_EPISODES,
    eval_env_kwargs: Mapping[str, Any] | None = None,
    checkpoint_freq: int | None = None,
    max_concurrent: int | None = None,
    address: str | None = None,
    num_cpus: int | None = None,
    verbose: int = 1,
    gym_packages: Sequence[str] = (),
) -> SweepResult:
    """Train and evaluate every grid point x seed as Ray Tune trials; write the summary.

    Args:
        env_id: registered navgym id.
        algo: SB3 algorithm of :func:`agents.training.train`.
        seeds: training seeds (``"0..9"`` or a list).
        grid: ``{key: values}`` or ``["KEY=V1,V2", ...]`` overriding the entry (dotted keys
            set nested ones, e.g. ``policy_kwargs.net_arch``); none: the entry as it is.
        out: sweep folder (default ``runs/sweeps/<env name>-<algo>``).
        timesteps: override the entry's ``n_timesteps``.
        n_envs: override the entry's ``n_envs``.
        config: as :func:`agents.training.train` (default: the shipped entry of ``env_id``).
        eval_episodes: held-out episodes per trial (evaluation seeds 0..n-1 of the range).
        eval_env_kwargs: env kwargs of the evaluation (default: the env's defaults).
        checkpoint_freq: override the entry's ``checkpoint_freq`` (environment steps).
        max_concurrent: trials at once (default: as many as the cluster's CPUs, one per trial).
        address: Ray cluster address (``ray://head:10001``); ``None``: local Ray.
        num_cpus: CPUs of the local Ray (default: all cores).
        verbose: Tune's verbosity (0 silent, 1 status table).
        gym_packages: modules to import (here and in every trial) for an id registered outside
            navgym (``--gym-packages``).

    Returns:
        :class:`SweepResult`; ``out`` holds ``trials.csv``, ``summary.csv``, ``summary.md``.
    """
    require_ray(PROG)
    from ray import tune

    from agents.training.train import env_name

    t0 = time.time()
    seeds = parse_seeds(seeds)
    grid = parse_grid(grid) if grid is None or not isinstance(grid, Mapping) else dict(grid)
    out = Path(out or Path("runs") / "sweeps" / f"{env_name(env_id)}-{algo}").resolve()
    spec = _spec(
        env_id,
        algo,
        seeds,
        grid,
        out,
        timesteps,
        n_envs,
        config,
        eval_episodes,
        eval_env_kwargs,
        checkpoint_freq,
        gym_packages,
    )
    if max_concurrent is not None and max_concurrent < 1:
        raise ValueError(f"--max-concurrent must be >= 1; got {max_concurrent}")
    _check_same_sweep(out / SPEC_FILE, spec)
    out.mkdir(parents=True, exist_ok=True)
    (out / SPEC_FILE).write_text(json.dumps(spec, indent=1) + "\n")
    init_ray(address, num_cpus, temp_dir=out / "ray")  # a local Ray's session files under --out
    trainable = tune.with_resources(tune.with_parameters(run_trial, spec=spec), {"cpu": 1})
    exp = out / "tune"
    resumed = tune.Tuner.can_restore(str(exp))
    if resumed:
        tuner = tune.Tuner.restore(str(exp), trainable, resume_unfinished=True, resume_errored=True)
    else:
        tuner = tune.Tuner(
            trainable,
            param_space={"index": tune.grid_search(list(range(len(spec["trials"]))))},
            tune_config=tune.TuneConfig(max_concurrent_trials=max_concurrent, reuse_actors=False),
            run_config=tune.RunConfig(
                name="tune",
                storage_path=str(out),
                verbose=verbose,
                failure_config=tune.FailureConfig(max_failures=0),
            ),
        )
    results = tuner.fit()
    rows, errors = [], []
    for r in results:
        if r.error is not None:
            errors.append(f"{r.path}: {r.error}")
        elif r.metrics and "return" in r.metrics:
            rows.append({k: r.metrics[k] for k in TRIAL_COLUMNS})
    rows.sort(key=lambda r: (r["config_id"], r["seed"]))
    summary = summarize_trials(rows, spec["labels"])
    table = summary_table(summary)
    write_csv(out / "trials.csv", rows)
    write_csv(out / "summary.csv", summary)
    wall = time.time() - t0
    head = (
        f"# Sweep {env_id} ({spec['algo']}, seeds {seeds[0]}..{seeds[-1]}, {len(spec['trials'])} trials)\n\n"
        f"Mean [95 % t-interval] over seeds of the held-out means ({eval_episodes} evaluation episodes "
        f"per trial). Sweep wall time {wall:.0f} s{' (resumed)' if resumed else ''}.\n\n"
    )
    (out / "summary.md").write_text(head + table)
    return SweepResult(out, rows, summary, table, errors, resumed, wall)


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The arguments of ``navgym sweep``."""
    from agents.training.config import ALGOS

    parser.add_argument("env_id", help="environment id, e.g. navgym/Robot2dFading-v1")
    parser.add_argument("--algo", default="ppo", choices=ALGOS, help="SB3 algorithm (default: ppo)")
    add_gym_packages(parser)
    parser.add_argument("--seeds", default="0", help="training seeds: A..B (inclusive) or A,B,C (default: 0)")
    parser.add_argument(
        "--grid",
        nargs="*",
        default=[],
        metavar="KEY=V1,V2",
        help="entry keys to sweep (dotted: nested), e.g. learning_rate=1e-4,3e-4 gamma=0.95,0.97",
    )
    parser.add_argument("--timesteps", type=float, default=None, help="environment steps per trial")
    parser.add_argument("--n-envs", type=int, default=None, help="override the config's n_envs")
    parser.add_argument("--config", default=None, help="YAML file keyed by env id (default: agents/configs)")
    parser.add_argument("--out", default=None, help="sweep folder (default: runs/sweeps/<env name>-<algo>)")
    parser.add_argument("--eval-episodes", type=int, default=DEFAULT_EVAL_EPISODES, help="held-out episodes")
    parser.add_argument("--eval-env-kwargs", default="{}", help="env kwargs of the evaluation (JSON)")
    parser.add_argument("--checkpoint-freq", type=int, default=None, help="steps between checkpoints")
    parser.add_argument(
        "--max-concurrent", type=int, default=None, help="trials at once (default: one per CPU)"
    )
    parser.add_argument("--address", default=None, help="Ray cluster address, e.g. ray://head:10001")
    parser.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local Ray (default: all)")
    parser.add_argument("--quiet", action="store_true", help="no Tune status table")
    return parser


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym sweep`` to the ``navgym`` command's sub-parsers (:mod:`navgym.cli`)."""
    parser = subparsers.add_parser("sweep", help="train grid x seeds as Ray Tune trials; summary over seeds")
    add_arguments(parser)
    parser.set_defaults(_run=run)


def run(args: argparse.Namespace) -> int:
    """Run :func:`sweep` from parsed arguments; print the summary table.

    Without Ray: says how to install the ``scale`` extra, exit status 2. Expected input errors:
    ``navgym sweep: error: <message>``, status 2 (:mod:`agents.cli_errors`). A sweep with
    failed trials gives status 1.
    """
    from agents.cli_errors import report_errors

    try:
        require_ray(PROG)
    except MissingExtraError as exc:
        return report_missing(PROG, exc)
    return report_errors(PROG, _run, args)


def _run(args: argparse.Namespace) -> int:
    try:
        eval_kwargs = json.loads(args.eval_env_kwargs)
    except json.JSONDecodeError as e:
        raise ValueError(f"--eval-env-kwargs must be a JSON object ({e})") from None
    res = sweep(
        args.env_id,
        args.algo,
        args.seeds,
        args.grid,
        args.out,
        timesteps=None if args.timesteps is None else int(args.timesteps),
        n_envs=args.n_envs,
        config=args.config,
        eval_episodes=args.eval_episodes,
        eval_env_kwargs=eval_kwargs,
        checkpoint_freq=args.checkpoint_freq,
        max_concurrent=args.max_concurrent,
        address=args.address,
        num_cpus=args.num_cpus,
        verbose=0 if args.quiet else 1,
        gym_packages=args.gym_packages,
    )
    print(res.table, end="")
    print(f"\n{'resumed; ' if res.resumed else ''}wall time {res.wall_s:.0f} s; wrote {res.out}/summary.md")
    for e in res.errors:
        print(f"{PROG}: trial failed: {e}", file=sys.stderr)
    return 1 if res.errors else 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m agents.scale.sweep ...``."""
    parser = add_arguments(argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0]))
    return run(parser.parse_args(None if argv is None else list(argv)))


if __name__ == "__main__":
    raise SystemExit(main())
