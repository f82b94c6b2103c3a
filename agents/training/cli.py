"""Command-line entry of training: ``python -m agents.training`` and ``navgym train``.

``navgym train ENV_ID [--algo ppo] [--seed 0] [--timesteps N | --n-timesteps N] [--out DIR] [--resume]
[--config FILE] [--n-envs B] [--no-progress] [--verbose 1]``. :func:`register` adds it to the
``navgym`` command (entry point ``train`` of the group ``navgym.commands``, pyproject.toml).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from agents.cli_args import add_gym_packages
from agents.training.config import ALGOS


def add_train_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the arguments of :func:`agents.training.train` to ``parser`` (a subcommand's)."""
    parser.add_argument("env_id", help="environment id, e.g. navgym/GpsInsFading-v0")
    parser.add_argument("--algo", default="ppo", choices=ALGOS, help="SB3 algorithm (default: ppo)")
    add_gym_packages(parser)
    parser.add_argument("--seed", type=int, default=0, help="training seed (default: 0)")
    parser.add_argument(
        "--timesteps",
        "--n-timesteps",
        "-n",
        dest="timesteps",
        type=float,
        default=None,
        help="total environment steps (default: the config's n_timesteps)",
    )
    parser.add_argument(
        "--out", default=None, help="output folder (default: runs/<env name>/<algo>_seed<seed>)"
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue from the newest valid checkpoint in --out (a finished run: with more --timesteps)",
    )
    parser.add_argument(
        "--config", default=None, help="YAML file keyed by env id (default: agents/configs/<algo>.yml)"
    )
    parser.add_argument("--n-envs", type=int, default=None, help="override the config's n_envs")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default: 1)")
    parser.add_argument(
        "--eval-freq",
        type=float,
        default=None,
        help="environment steps between evaluations on tuning seeds, the best model kept in OUT/best "
        "(default: the config's eval_freq; 0: none)",
    )
    parser.add_argument(
        "--eval-episodes", type=int, default=None, help="tuning episodes per evaluation (default: 16)"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--verbose", type=int, default=0, help="SB3 verbosity (0 or 1)")
    return parser


PROG = "navgym train"


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym train`` to the ``navgym`` command's sub-parsers (:mod:`navgym.cli`)."""
    parser = subparsers.add_parser("train", help="train an SB3 agent from agents/configs (rl-zoo3 layout)")
    add_train_arguments(parser)
    parser.set_defaults(_run=train_cli)


def train_cli(args: argparse.Namespace | Sequence[str] | None = None) -> int:
    """Run :func:`agents.training.train` from parsed arguments (or an argv list); print the folder.

    Expected errors (missing config file, unknown env id or config entry, bad values, a
    checkpoint that does not load) print ``navgym train: error: <message>`` to stderr and return
    2 (:mod:`agents.cli_errors`); other exceptions raise.
    """
    from agents.cli_errors import report_errors

    if args is None or not isinstance(args, argparse.Namespace):
        parser = add_train_arguments(argparse.ArgumentParser(prog=PROG, description=__doc__))
        args = parser.parse_args(None if args is None else list(args))
    return report_errors(PROG, _train, args)


def _train(args: argparse.Namespace) -> int:
    from agents.training.train import already_finished, finished_message, train

    total = None if args.timesteps is None else int(args.timesteps)
    if args.resume:
        done = already_finished(args.env_id, args.algo, args.config, args.seed, total, args.out)
        if done is not None:  # a finished run is left as it is
            print(finished_message(*done))
            return 0
    out = train(
        args.env_id,
        algo=args.algo,
        config=args.config,
        seed=args.seed,
        total_timesteps=total,
        out_dir=args.out,
        resume=args.resume,
        progress=not args.no_progress,
        n_envs=args.n_envs,
        verbose=args.verbose,
        torch_threads=args.threads,
        eval_freq=None if args.eval_freq is None else int(args.eval_freq),
        eval_episodes=args.eval_episodes,
    )
    print(f"saved agent to {out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m agents.training ...``."""
    return train_cli(list(argv) if argv is not None else None)
