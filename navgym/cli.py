"""The ``navgym`` command line: ``navgym list | train | tune | eval | bench | demo``.

navgym itself provides ``list`` and ``--version``. The other sub-commands belong to the layers
above the library and register themselves through the entry-point group ``navgym.commands``
(pyproject.toml, ``[project.entry-points."navgym.commands"]``): the entry point's name is the
command's name, its object a function ``register(subparsers)`` that adds the command's
sub-parser and sets ``_run`` (``args -> exit status``) as its default. This module imports none of
them by name. An entry point that cannot be loaded because a module is missing (an optional
extra not installed, named in the entry point's ``[extra]``) still gets a sub-command, which
says what to install and exits with status 2. ``navgym <command> ...`` loads that command's
entry point only (``list`` and ``--version`` none), so one command's imports neither slow nor
break another; the top-level help and usage errors load them all.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from importlib.metadata import EntryPoint, entry_points

from navgym import __version__

#: Entry-point group of the sub-commands (see the module docstring).
COMMAND_GROUP = "navgym.commands"


def command_entry_points() -> list[EntryPoint]:
    """The registered sub-commands, sorted by name."""
    return sorted(entry_points(group=COMMAND_GROUP), key=lambda ep: ep.name)


def _unavailable(ep: EntryPoint, missing: str | None) -> tuple[Callable[[argparse.Namespace], int], str]:
    """``(run, help)`` of ``navgym <ep.name>`` when its module cannot be imported: say so, exit 2."""
    extra = ep.extras[0] if ep.extras else None
    need = f"the {extra!r} extra" if extra else "an optional dependency"
    install = f"; pip install -e '.[{extra}]'" if extra else ""

    def run(args: argparse.Namespace) -> int:
        print(f"navgym {ep.name}: needs {need} (missing module {missing!r}){install}")
        return 2

    return run, f"(needs {need}: {missing} missing)"


def _build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser of ``navgym``; with ``argv`` naming a command, with that command only."""
    parser = argparse.ArgumentParser(prog="navgym", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"navgym {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    lst = sub.add_parser("list", help="print the environment registry")
    lst.add_argument(
        "pattern", nargs="?", default=None, help="only ids whose id or task contains it (or a glob: '*-v2')"
    )
    lst.add_argument("--json", action="store_true", help="JSON objects instead of the table")
    lst.set_defaults(_run=_list)

    first = (argv or [""])[0]
    eps = command_entry_points()
    named = [ep for ep in eps if ep.name == first]
    for ep in named if named or first in ("list", "--version") else eps:
        try:
            register = ep.load()
        except ModuleNotFoundError as exc:  # e.g. torch / stable-baselines3 not installed
            run, help_text = _unavailable(ep, exc.name)
            sub.add_parser(ep.name, help=help_text).set_defaults(_run=run)
            continue
        register(sub)
    return parser


def _list(args: argparse.Namespace) -> int:
    from navgym.envs.listing import print_registry

    return print_registry(as_json=args.json, pattern=args.pattern)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``navgym`` console script.

    A user's input error prints ``navgym <command>: error: <message>`` and exits with status 2
    (:mod:`navgym.cli_errors`); other exceptions are bugs and keep their traceback.
    """
    from navgym.cli_errors import report_errors

    argv = sys.argv[1:] if argv is None else list(argv)
    args = _build_parser(argv).parse_args(argv)
    return report_errors(f"navgym {args.command}", args._run, args)


if __name__ == "__main__":
    sys.exit(main())
