"""The ``navgym`` command line: ``navgym list | train | tune | eval | bench | demo``.

Sub-commands import their implementation lazily so that ``navgym --help`` stays fast and
``navgym bench`` works without torch.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys


def bench_targets() -> dict[str, str]:
    """``navgym bench <target>`` -> module: every module of :mod:`navgym.bench`.

    Each exposes ``add_arguments(parser)`` and ``run(args) -> int``.
    """
    import navgym.bench

    return {
        info.name: f"navgym.bench.{info.name}"
        for info in pkgutil.iter_modules(navgym.bench.__path__)
        if not info.name.startswith("_")
    }


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="navgym", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    bench = sub.add_parser("bench", help="run a benchmark and print its table")
    bench_sub = bench.add_subparsers(dest="target", required=True)
    for name, module_name in sorted(bench_targets().items()):
        module = importlib.import_module(module_name)
        p = bench_sub.add_parser(name, help=(module.__doc__ or name).splitlines()[0])
        module.add_arguments(p)
        p.set_defaults(_run=module.run)

    _add_agents_commands(sub)

    lst = sub.add_parser("list", help="print the environment registry")
    lst.set_defaults(_run=lambda args: __import__("navgym.envs.listing", fromlist=["x"]).print_registry())

    demo = sub.add_parser("demo", help="the README's main job: zoo agent vs tuned baselines")
    try:
        from agents import demo as agents_demo
    except ModuleNotFoundError as exc:
        missing = exc.name
        demo.set_defaults(
            _run=lambda args: print(f"navgym demo needs the agents extra ({missing} missing)") or 2
        )
    else:
        agents_demo.add_arguments(demo)
        demo.set_defaults(_run=agents_demo.run)
    return parser


def _add_agents_commands(sub) -> None:
    """``train``, ``tune`` and ``eval`` come from :mod:`agents` (needs the ``agents`` extra)."""
    try:
        from agents import tuning
        from agents.evaluation import cli as eval_cli
        from agents.training import cli as train_cli
    except ModuleNotFoundError as exc:  # torch / stable-baselines3 not installed
        missing = exc.name

        def unavailable(args: argparse.Namespace) -> int:
            print(
                f"navgym {args.command}: needs the 'agents' extra (missing module {missing!r}); "
                "pip install -e '.[agents]'"
            )
            return 2

        for name in ("train", "tune", "eval"):
            sub.add_parser(name, help=f"(needs the agents extra: {missing} missing)").set_defaults(
                _run=unavailable
            )
        return
    train = sub.add_parser("train", help="train an SB3 agent from agents/configs (rl-zoo3 layout)")
    train_cli.add_train_arguments(train)
    train.set_defaults(_run=train_cli.train_cli)
    tune = sub.add_parser("tune", help="grid-search the classical baselines on tuning seeds")
    tuning.add_arguments(tune)
    tune.set_defaults(_run=tuning.run)
    ev = sub.add_parser("eval", help="evaluate policies on held-out episodes (paired, bootstrap CIs)")
    eval_cli.add_arguments(ev)
    ev.set_defaults(_run=eval_cli.run)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``navgym`` console script.

    A user's input error prints ``navgym <command>: error: <message>`` and exits with status 2
    (:mod:`navgym.cli_errors`); other exceptions are bugs and keep their traceback.
    """
    from navgym.cli_errors import report_errors

    args = _build_parser().parse_args(argv)
    return report_errors(f"navgym {args.command}", args._run, args)


if __name__ == "__main__":
    sys.exit(main())
