"""``navgym bench <target>``: the benchmark commands, registered with the ``navgym`` command.

pyproject.toml declares :func:`register` under the entry-point group ``navgym.commands``;
:mod:`navgym.cli` calls it to add ``bench`` and its targets. A target is a module of this
package (not ``cli``, not ``_private``) with ``add_arguments(parser)`` and ``run(args) -> int``.
Each target starts with :func:`navgym.tune_malloc` (the allocator tuning its figures assume).
"""

from __future__ import annotations

import argparse
import functools
import importlib
import pkgutil
from collections.abc import Callable

import benchmarks

#: Modules of the package that are not targets.
NOT_TARGETS = frozenset({"cli", "soak"})


def bench_targets() -> dict[str, str]:
    """``navgym bench <target>`` -> module name, for every target module of :mod:`benchmarks`."""
    return {
        info.name: f"benchmarks.{info.name}"
        for info in pkgutil.iter_modules(benchmarks.__path__)
        if not info.name.startswith("_") and info.name not in NOT_TARGETS
    }


def run_target(run: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """Tune the allocator (:func:`navgym.tune_malloc`), then run one benchmark."""
    import navgym

    navgym.tune_malloc()
    return run(args)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``bench`` and one sub-command per target to the ``navgym`` command's sub-parsers."""
    bench = subparsers.add_parser("bench", help="run a benchmark and print its table")
    targets = bench.add_subparsers(dest="target", required=True)
    for name, module_name in sorted(bench_targets().items()):
        module = importlib.import_module(module_name)
        parser = targets.add_parser(name, help=(module.__doc__ or name).splitlines()[0])
        module.add_arguments(parser)
        parser.set_defaults(_run=functools.partial(run_target, module.run))
