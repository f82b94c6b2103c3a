"""``navgym tune`` / ``python -m agents.tuning``: tune the baselines of env ids, write their JSON.

Usage::

    python -m agents.tuning --env navgym/GpsInsFading-v0 --episodes 64
    navgym tune --env navgym/GpsInsFading-v0 --episodes 64 --ray [--samples 40] [--address ray://HEAD:10001]

The grid points are scored by :func:`agents.tuning.search.tune` (batched local rollouts, chunks of
grid points on every core by default: ``--workers``), or
with ``--ray`` (the ``scale`` extra) as Ray Tune trials, on local Ray or a cluster
(``--address``), with the same results (:class:`agents.scale.ray_tuning.RayTuneStrategy`);
``--samples K`` scores only K points chosen by Optuna's TPE sampler, for grids too large to score
whole. This command is the one place that chooses the strategy: the search itself
(:mod:`agents.tuning.search`) takes it as an argument.

The JSON files go to ``--out`` (default ``./tuned/``, a folder of the user's): the shipped values
in ``agents/baselines/tuned/`` change only with ``--out agents/baselines/tuned`` given on
purpose. ``navgym eval --tuned tuned/<EnvName-vK>.json`` evaluates with the new values.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from agents.baselines.registry import TUNED_DIR, tuned_path
from agents.cli_args import add_gym_packages
from agents.scale.ray_runtime import MissingExtraError, report_missing, require_ray
from agents.scale.ray_tuning import RayTuneStrategy
from agents.tuning.search import LocalTuneStrategy, TuneStrategy, tune_env
from agents.workers import MAX_DEFAULT_WORKERS, default_workers

__all__ = ["DEFAULT_OUT", "add_arguments", "main", "register", "run"]

#: ``--out`` when none is given: a folder of the user's, never the shipped ``agents/baselines/tuned``.
DEFAULT_OUT = "tuned"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of the tuning job."""
    parser.add_argument("--env", required=True, nargs="+", help="env id(s)")
    add_gym_packages(parser)
    parser.add_argument(
        "--baselines", nargs="+", default=None, help="baselines to tune (default: all of the task)"
    )
    parser.add_argument("--episodes", type=int, default=64, help="tuning episodes per grid point")
    parser.add_argument("--seed-offset", type=int, default=0, help="offset into the tuning seed range")
    parser.add_argument(
        "--env-kwargs", default="{}", help="env keyword arguments: JSON, or key=value[,key=value]"
    )
    parser.add_argument(
        "--out",
        default=None,
        help=(
            f"output directory (default ./{DEFAULT_OUT}/; the shipped {TUNED_DIR.name}/ values in "
            "agents/baselines/tuned change only with --out agents/baselines/tuned)"
        ),
    )
    parser.add_argument("--max-batch", type=int, default=None, help="sub-envs per batched rollout")
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        help=(
            "chunks of grid points scored at a time in forked processes (default: the available "
            f"cores, at most {MAX_DEFAULT_WORKERS}; 1: one process; the results do not depend on it)"
        ),
    )
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


def strategy_of(args: argparse.Namespace) -> TuneStrategy:
    """The strategy ``args`` ask for: local rollouts on ``--workers`` processes, or Ray Tune (``--ray``).

    Local: :func:`~agents.tuning.search.tune` as a :class:`~agents.tuning.search.LocalTuneStrategy`.

    Raises:
        ValueError: ``--samples`` or ``--address`` without ``--ray``, ``--workers`` with it or
            below 1.
        agents.scale.ray_runtime.MissingExtraError: ``--ray`` without Ray installed.
    """
    if not args.ray:
        if args.samples is not None or args.address is not None:
            raise ValueError("--samples and --address go with --ray")
        workers = default_workers() if args.workers is None else int(args.workers)
        if workers < 1:
            raise ValueError(f"--workers must be at least 1; got {workers}")
        return LocalTuneStrategy(workers)
    if args.workers is not None:
        raise ValueError("--workers goes without --ray (Ray Tune places its own trials)")
    require_ray("navgym tune --ray")
    return RayTuneStrategy(samples=args.samples, address=args.address)


def run(args: argparse.Namespace, argv: Sequence[str] | None = None) -> int:
    """Tune each ``--env``; print the best parameters (``--ray`` without Ray: says so, status 2).

    Expected errors (bad ``--env-kwargs``, unknown env id or baseline) print
    ``navgym tune: error: <message>`` and return 2 (:mod:`agents.cli_errors`).
    """
    from agents.cli_errors import report_errors

    try:
        strategy = strategy_of(args)
    except MissingExtraError as exc:
        return report_missing("navgym tune --ray", exc)
    return report_errors("navgym tune", _run, args, strategy, _command(argv))


def _run(args: argparse.Namespace, strategy: TuneStrategy, command: str) -> int:
    from agents.evaluation.cli import parse_env_kwargs

    env_kwargs = parse_env_kwargs(args.env_kwargs)
    out = args.out
    if out is None:
        out = DEFAULT_OUT
        print(
            f"writing to ./{DEFAULT_OUT}/ (--out DIR to choose; the shipped {TUNED_DIR} is left as it is)",
            file=sys.stderr,
        )
    for env_id in args.env:
        data = tune_env(
            env_id,
            args.baselines,
            episodes=args.episodes,
            seed_offset=args.seed_offset,
            env_kwargs=env_kwargs,
            out_dir=out,
            command=command,
            max_batch=args.max_batch,
            progress=not args.quiet,
            strategy=strategy,
        )
        print(f"{env_id} -> {tuned_path(env_id, out)}")
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
