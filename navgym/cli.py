"""The ``navgym`` command line: ``navgym list | train | eval | bench | demo``.

Sub-commands import their implementation lazily so that ``navgym --help`` stays fast and
``navgym bench`` works without torch.
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: ``navgym bench <target>`` -> module exposing ``add_arguments(parser)`` and ``run(args)``.
BENCH_TARGETS: dict[str, str] = {
    "filters": "navgym.bench.filters",
    "sim": "navgym.bench.sim",
    "particles": "navgym.bench.particles",
    "envs": "navgym.bench.envs",
}


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="navgym", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    bench = sub.add_parser("bench", help="run a benchmark and print its table")
    bench_sub = bench.add_subparsers(dest="target", required=True)
    for name, module_name in BENCH_TARGETS.items():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:  # target not built yet or optional dependency missing
            if exc.name is not None and exc.name.startswith(module_name):
                continue
            raise
        p = bench_sub.add_parser(name, help=(module.__doc__ or name).splitlines()[0])
        module.add_arguments(p)
        p.set_defaults(_run=module.run)

    demo = sub.add_parser("demo", help="the README's main job")
    demo.set_defaults(_run=_demo)
    return parser


def _demo(args: argparse.Namespace) -> int:
    """Main job of the README's first command (for now: the default filter benchmark)."""
    from navgym.bench import filters as bench_filters

    p = argparse.ArgumentParser()
    bench_filters.add_arguments(p)
    return bench_filters.run(p.parse_args([]))


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``navgym`` console script."""
    args = _build_parser().parse_args(argv)
    return int(args._run(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
