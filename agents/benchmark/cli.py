"""``navgym benchmark AGENT [AGENT ...] [--ids ID ...] [--episodes 500] [--out DIR] [--quick]``.

The standard protocol in one command (:mod:`agents.benchmark.protocol`): for each id, the plain
filter, every tuned classical baseline, the bar (the best tuned one, fixed on tuning seeds), the
agents and the upper references, all on the same held-out evaluation episodes; a leaderboard row
per (id, policy) with the paired 95 % CI of ΔRMSE % against the bar, and across training seeds
the mean and IQM with stratified-bootstrap CIs. Prints the table and writes ``DIR/leaderboard.md``,
``leaderboard.json``, ``leaderboard.csv`` and ``manifest.json`` (:mod:`agents.benchmark.leaderboard`).

AGENT: ``[LABEL=]PATH`` of a supervised or SB3 agent folder, or of a folder of ``seed_*/`` agent
folders (:mod:`agents.benchmark.agent_specs`). ``--quick``: 16 episodes and few bootstrap
resamples (smoke tests), unless ``--episodes`` says otherwise.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterable
from pathlib import Path

from agents.benchmark.aggregate import SEED_RESAMPLES
from agents.benchmark.leaderboard import compact_markdown, markdown, write_leaderboard, write_readme_block
from agents.benchmark.protocol import DEFAULT_EPISODES, QUICK_EPISODES, run_protocol
from agents.cli_args import add_gym_packages
from agents.evaluation.bootstrap import DEFAULT_RESAMPLES

__all__ = ["QUICK_RESAMPLES", "add_arguments", "register", "run"]

#: ``--quick``: bootstrap resamples over episodes and over training seeds.
QUICK_RESAMPLES = (200, 1000)
DEFAULT_OUT = "results/benchmark"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``navgym benchmark``."""
    parser.add_argument(
        "agents",
        nargs="*",
        metavar="AGENT",
        help=(
            "[LABEL=]PATH: a supervised agent folder (agents/zoo/<EnvName-vK>-supervised), a trained SB3 "
            "agent folder (model.zip + manifest.json), or a folder of seed_*/ agent folders (training "
            "seeds of one agent, aggregated); the label defaults to the folder's name"
        ),
    )
    parser.add_argument(
        "--ids",
        nargs="+",
        default=None,
        metavar="ID",
        help=(
            "env ids to run (default: the agents' ids); ids without an agent get the baselines and references"
        ),
    )
    add_gym_packages(parser)
    parser.add_argument(
        "--episodes",
        type=int,
        default=None,
        help=f"held-out episodes per id (default {DEFAULT_EPISODES}; {QUICK_EPISODES} with --quick)",
    )
    parser.add_argument("--out", default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"{QUICK_EPISODES} episodes, few bootstrap resamples (smoke test)",
    )
    parser.add_argument(
        "--bootstrap",
        type=int,
        default=None,
        help=(
            f"bootstrap resamples over episodes (default {DEFAULT_RESAMPLES}; "
            f"{QUICK_RESAMPLES[0]} with --quick)"
        ),
    )
    parser.add_argument(
        "--seed-resamples",
        type=int,
        default=None,
        help=(
            f"bootstrap resamples over training seeds (default {SEED_RESAMPLES}; "
            f"{QUICK_RESAMPLES[1]} with --quick)"
        ),
    )
    parser.add_argument("--boot-seed", type=int, default=0, help="offset of the bootstrap seeds")
    parser.add_argument(
        "--env-kwargs",
        default="{}",
        help="env kwargs of every run, JSON or key=value[,...]; not the standard protocol (a note says so)",
    )
    parser.add_argument(
        "--no-references", action="store_true", help="skip the clairvoyant and the regime oracle"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument(
        "--readme",
        type=Path,
        default=None,
        help="also write the compact leaderboard (plain, bar, agents, references) between "
        "<!-- leaderboard:begin --> and <!-- leaderboard:end --> of this file (e.g. README.md)",
    )


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym benchmark`` to the ``navgym`` command's sub-parsers (:mod:`navgym.cli`)."""
    parser = subparsers.add_parser(
        "benchmark",
        help="the standard protocol: baselines, the bar, agents and references on the same held-out episodes",
        description=__doc__.splitlines()[0],
    )
    add_arguments(parser)
    parser.set_defaults(_run=run)


def run(args: argparse.Namespace) -> int:
    """``navgym benchmark`` entry: input errors print one line and give exit status 2."""
    from agents.cli_errors import report_errors

    return report_errors("navgym benchmark", _run, args)


def _run(args: argparse.Namespace) -> int:
    from agents.evaluation.cli import parse_env_kwargs

    quick = bool(args.quick)
    episodes = _given(args.episodes, QUICK_EPISODES if quick else DEFAULT_EPISODES)
    n_boot = _given(args.bootstrap, QUICK_RESAMPLES[0] if quick else DEFAULT_RESAMPLES)
    seed_reps = _given(args.seed_resamples, QUICK_RESAMPLES[1] if quick else SEED_RESAMPLES)
    board = run_protocol(
        args.agents,
        args.ids,
        episodes,
        env_kwargs=parse_env_kwargs(args.env_kwargs),
        n_boot=n_boot,
        seed_reps=seed_reps,
        boot_seed=args.boot_seed,
        references=not args.no_references,
        progress=not args.quiet,
    )
    board.config["quick"] = quick
    board.config["arguments"] = {
        k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items() if not k.startswith("_")
    }
    command = list(sys.argv) if Path(sys.argv[0]).name == "navgym" else None  # else: the arguments
    write_leaderboard(board, args.out, command)
    if args.readme is not None:
        ids = ["--ids", *args.ids] if args.ids else []
        shown = " ".join(
            ["navgym benchmark", *braced(map(str, args.agents)), *ids, "--episodes", str(episodes)]
        )
        write_readme_block(args.readme, compact_markdown(board, shown))
    print(markdown(board), end="")
    print(f"\nwrote {Path(args.out)}/ (leaderboard.md, leaderboard.json, leaderboard.csv, manifest.json)")
    return 0


def braced(specs: Iterable[str]) -> list[str]:
    """AGENT arguments with one label folded in shell brace form, for a short command line.

    ``ppo=runs/A-v3 ppo=runs/B-v3`` -> ``ppo=runs/{A,B}-v3`` (bash expands it back to the two
    arguments); labels with one path, and paths without a common stem, are left as they are.
    """
    from agents.benchmark.agent_specs import split_label

    groups: dict[str, list[str]] = {}
    for spec in specs:
        label, path = split_label(spec)
        groups.setdefault(f"{label}=" if label else "", []).append(path)
    out = []
    for label, paths in groups.items():
        if len(paths) == 1:
            out.append(label + paths[0])
            continue
        head = os.path.commonprefix(paths)
        tail = os.path.commonprefix([p[len(head) :][::-1] for p in paths])[::-1]
        middles = [p[len(head) : len(p) - len(tail)] for p in paths]
        if any(not m or "," in m or "{" in m for m in middles):
            out += [label + p for p in paths]
        else:
            out.append(f"{label}{head}{{{','.join(middles)}}}{tail}")
    return out


def _given(value: int | None, default: int) -> int:
    return default if value is None else value
