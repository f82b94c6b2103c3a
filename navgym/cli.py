"""The ``navgym`` command line: ``navgym list | train | eval | bench | demo``.

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

    lst = sub.add_parser("list", help="print the environment registry")
    lst.set_defaults(_run=lambda args: __import__("navgym.envs.listing", fromlist=["x"]).print_registry())

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
