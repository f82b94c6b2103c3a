"""``navgym demo``: the shipped trained agent against the tuned baselines, on held-out episodes.

On the headline id (:data:`DEFAULT_ENV`, a v3 RowScale id) the demo loads the zoo agent
(``agents/zoo/<EnvName-vK>``; on a v3 id also the supervised agent it was warm-started from,
``agents/zoo/<EnvName-vK>-supervised``), builds every classical baseline of the task with its tuned
parameters (``agents/baselines/tuned``), evaluates all of them on the same held-out episodes
(evaluation seeds, never used for training or tuning) and says in one sentence whether the agent
beats the best tuned classical baseline (the highest tuning score, fixed before the evaluation:
:func:`agents.baselines.registry.best_tuned`), with the paired bootstrap CI of ΔRMSE %
(:mod:`agents.evaluation.comparison`). It plots the agent's and that baseline's knob over one
episode beside the C/N0 the receiver reported and the episode's regimes
(:mod:`agents.evaluation.episode_trace`; the episode is the
agent's median-RMSE one, not a chosen example), prints the table and writes
``results/demo/{report.md, table.csv, summary.csv, paired.csv, episodes.csv, knob_trace.png,
*.png, manifest.json}``. ``--quick`` runs a handful of short episodes (the tests use it).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np

from agents.cli_args import add_gym_packages
from agents.evaluation.cli import parse_policies, run_eval
from agents.evaluation.comparison import delta_rmse, verdict_sentence
from agents.evaluation.episode_trace import episode_trace, plot_episode_trace
from agents.evaluation.report import results_table
from navgym.envs.registration import superseded_ids_quiet

#: The headline id: the v3 id where the learned agent beats its best tuned baseline most clearly
#: in the study ``experiments.learned_v3`` (the README's "Learned agents on v3" table: the most
#: negative upper end of the CI of ΔRMSE %; ``tests/agents/test_demo.py`` holds this to it).
DEFAULT_ENV = "navgym/QuadrotorRowScale-v3"
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
    from agents.baselines.registry import best_tuned
    from agents.training.loading import load_agent

    out = Path(out)
    with superseded_ids_quiet():  # a zoo agent may be trained on a superseded id on purpose
        env_kwargs = {}
        if quick:
            episodes, env_kwargs = min(episodes, 6), {"episode_steps": 40, "max_episode_steps": 40}
        tuned = load_tuned(env_id)
        reference = best_tuned(env_id)[0] if tuned else None
        policies = parse_policies(["baselines"], env_id, env_kwargs, tuned)
        path = zoo_path(env_id)
        agent = load_agent(path)  # FileNotFoundError names the missing path
        label = f"learned (zoo {agent.algo.upper()})" if agent.algo else "learned (zoo)"
        supervised = path.with_name(path.name + "-supervised")
        if supervised.is_dir():  # a v3 id: its supervised agent (the RL agent's warm start) too
            from agents.supervised.files import load_policy

            policies["supervised (zoo)"] = lambda env: load_policy(supervised, env)
        policies[label] = agent
        print(f"navgym demo: {env_id}, {episodes} held-out episodes, agent {path}")
        n_boot = 500 if quick else 2000
        results = run_eval(
            env_id,
            policies,
            episodes,
            out,
            env_kwargs=env_kwargs,
            tuned=tuned,
            reference=reference,
            n_boot=n_boot,
            progress=progress,
        )
        sentence = ""
        if reference is not None:
            d = delta_rmse(results.episodes[label]["rmse_m"], results.episodes[reference]["rmse_m"], n_boot)
            sentence = verdict_sentence(env_id, label, reference, d)
        rmse = np.asarray(results.episodes[label]["rmse_m"], dtype=np.float64)
        i = int(np.nanargmin(np.abs(rmse - np.nanmedian(rmse))))  # the agent's median episode
        traced = {label: agent} | ({reference: policies[reference]} if reference else {})
        trace = episode_trace(env_id, traced, results.seeds[i], env_kwargs)
        plot = plot_episode_trace(
            trace, out / "knob_trace.png", f"{env_id}: episode seed {trace.seed} (the agent's median RMSE)"
        )
    shutil.copyfile(out / "summary.csv", out / "table.csv")
    _prepend_verdict(out / "report.md", sentence, plot.name, trace.seed)
    print(results_table(results), end="")
    if sentence:
        print("\n" + sentence)
    print(f"\nwrote {out}/ (report.md, table.csv, knob_trace.png, plots, manifest.json)")
    return 0


def _prepend_verdict(report: Path, sentence: str, plot: str, seed: int) -> None:
    """Put the verdict sentence and the knob-trace plot under the title of ``report.md``."""
    title, _, rest = report.read_text().partition("\n")
    lines = [title, ""]
    if sentence:
        lines += [f"**{sentence}**", ""]
    lines += [
        f"![knob over one episode]({plot}) The agent's and the best tuned baseline's knob over the "
        f"agent's median-RMSE episode (seed {seed}), beside the observed C/N0 (v3 ids) and the regimes "
        "the simulator drew (never observed).",
        "",
    ]
    report.write_text("\n".join(lines) + rest)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``navgym demo``."""
    parser.add_argument("--env", default=DEFAULT_ENV, help="environment id with a zoo agent")
    add_gym_packages(parser)
    parser.add_argument("--episodes", type=int, default=100, help="held-out episodes")
    parser.add_argument("--out", default="results/demo", help="output directory")
    parser.add_argument("--quick", action="store_true", help="a few short episodes (smoke test)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym demo`` to the ``navgym`` command's sub-parsers (:mod:`navgym.cli`)."""
    parser = subparsers.add_parser(
        "demo", help="the README's main job: the headline v3 zoo agent vs tuned baselines"
    )
    add_arguments(parser)
    parser.set_defaults(_run=run)


def run(args: argparse.Namespace) -> int:
    """``navgym demo`` entry."""
    return run_demo(args.env, args.out, args.episodes, args.quick, not args.quiet)
