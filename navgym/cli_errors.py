"""One-line reports of a user's input errors for the command lines (``navgym``, ``agents``).

Errors a user causes (a missing file, an unknown or malformed env id, bad keyword arguments or
option values, a malformed JSON/YAML file) print ``<prog>: error: <message>`` to stderr and
give exit status 2, like argparse's own usage errors. Any other exception is a bug and raises
with its traceback; ``NAVGYM_DEBUG=1`` gives the traceback of the expected ones too (a
``ValueError`` can also come from a bug deep inside a command, so the line says so).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

EXIT_USAGE = 2


def is_user_error(exc: BaseException, extra: tuple[type[BaseException], ...] = ()) -> bool:
    """Whether ``exc`` is a user's input error rather than a bug.

    ``ValueError`` covers navgym's argument validation (``UnknownKeywordError`` included);
    gymnasium's unknown env ids (``UnregisteredEnv``) and malformed ones (a bare
    ``gymnasium.error.Error``) count, its other errors (``ResetNeeded``, ...) do not. ``extra``:
    a caller's own input-error types (e.g. a failed configuration lookup).
    """
    import yaml
    from gymnasium.error import Error as GymnasiumError
    from gymnasium.error import UnregisteredEnv

    expected = (FileNotFoundError, ValueError, yaml.YAMLError, UnregisteredEnv, *extra)
    return isinstance(exc, expected) or type(exc) is GymnasiumError


def error_message(exc: BaseException) -> str:
    """``exc`` as one line (its message, or its type name when it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__


def report_errors(
    prog: str,
    fn: Callable[..., Any],
    *args: Any,
    extra: tuple[type[BaseException], ...] = (),
    **kwargs: Any,
) -> int:
    """``fn(*args, **kwargs)`` as an exit status; a user's input error prints one line and gives 2."""
    try:
        return int(fn(*args, **kwargs) or 0)
    except Exception as exc:
        if os.environ.get("NAVGYM_DEBUG") or not is_user_error(exc, extra):
            raise
        print(f"{prog}: error: {error_message(exc)} (NAVGYM_DEBUG=1 shows the traceback)", file=sys.stderr)
        return EXIT_USAGE
