"""``navgym demo``: the shipped trained agent against the tuned baselines, on held-out episodes.

On the default environment (``navgym/GpsInsFading-v0``) the demo loads the zoo agent
(``agents/zoo/GpsInsFading-v0``), builds every classical baseline of the task with its tuned
parameters (``agents/baselines/tuned``), evaluates all of them on the same held-out episodes
(evaluation seeds, never used for training or tuning), prints the table and writes
``results/demo/{report.md, table.csv, summary.csv, paired.csv, episodes.csv, *.png,
manifest.json}``. ``--quick`` runs a handful of short episodes (the tests use it).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from agents.evaluation.cli import parse_policies, run_eval
from agents.evaluation.report import markdown_table
from navgym.envs.registration import superseded_ids_quiet

DEFAULT_ENV = "navgym/GpsInsFading-v0"
ZOO = Path(__file__).resolve().parent / "zoo"


def zoo_path(env_id: str) -> Path:
    """Folder of the shipped agent of ``env_id`` (``agents/zoo/<EnvName-vK>``)."""
    return ZOO / env_id.split("/")[-1]


def run_demo(
    env_id: str = DEFAULT_ENV,
    out: str | Path = "results/demo",
    episodes: int = 100,
    quick: bool = False,
    progress: bool = True,
) -> int:
    """Evaluate the zoo agent and the tuned baselines; print the table; write ``out``."""
    from agents.baselines import load_tuned
    from agents.training.loading import load_agent

    with superseded_ids_quiet():  # the zoo agent was trained on its (-v0) id on purpose
        env_kwargs = {}
        if quick:
            episodes, env_kwargs = min(episodes, 6), {"episode_steps": 40, "max_episode_steps": 40}
        tuned = load_tuned(env_id)
        policies = parse_policies(["baselines"], env_id, env_kwargs, tuned)
        path = zoo_path(env_id)
        agent = load_agent(path)  # FileNotFoundError names the missing path
        policies[f"learned (zoo {agent.algo.upper()})" if agent.algo else "learned (zoo)"] = agent
        print(f"navgym demo: {env_id}, {episodes} held-out episodes, agent {path}")
        results = run_eval(
            env_id,
            policies,
            episodes,
            out,
            env_kwargs=env_kwargs,
            tuned=tuned,
            n_boot=500 if quick else 2000,
            progress=progress,
        )
    shutil.copyfile(Path(out) / "summary.csv", Path(out) / "table.csv")
    print(markdown_table(results))
    print(f"\nwrote {out}/ (report.md, table.csv, plots, manifest.json)")
    return 0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``navgym demo``."""
    parser.add_argument("--env", default=DEFAULT_ENV, help="environment id with a zoo agent")
    parser.add_argument("--episodes", type=int, default=100, help="held-out episodes")
    parser.add_argument("--out", default="results/demo", help="output directory")
    parser.add_argument("--quick", action="store_true", help="a few short episodes (smoke test)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym demo`` to the ``navgym`` command's sub-parsers (:mod:`navgym.cli`)."""
    parser = subparsers.add_parser("demo", help="the README's main job: zoo agent vs tuned baselines")
    add_arguments(parser)
    parser.set_defaults(_run=run)


def run(args: argparse.Namespace) -> int:
    """``navgym demo`` entry."""
    return run_demo(args.env, args.out, args.episodes, args.quick, not args.quiet)
