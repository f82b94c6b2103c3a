"""One-line error reports for the ``navgym train`` / ``navgym eval`` command lines.

Errors a user causes (a missing file, an unknown env id or config entry, a bad option value, a
model that does not load) print ``<prog>: error: <message>`` to stderr and give exit status 2,
like argparse's own usage errors. Any other exception is a bug and still raises with its
traceback; set ``NAVGYM_DEBUG=1`` to get the traceback of the expected ones too.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

EXIT_USAGE = 2


def expected_errors() -> tuple[type[BaseException], ...]:
    """The exception types reported in one line (imported lazily: gymnasium, agents.training)."""
    import yaml
    from gymnasium.error import Error as GymnasiumError

    from agents.training.config import UnknownEnvError
    from agents.training.loading import AgentLoadError

    # AgentLoadError is a ValueError; UnknownEnvError is the KeyError of a config lookup (a bare
    # KeyError is usually a bug, so it keeps its traceback). gymnasium.error.Error: unknown or
    # malformed env ids. Unknown keyword arguments raise navgym's UnknownKeywordError, a
    # ValueError. yaml.YAMLError: a malformed configuration file.
    return (FileNotFoundError, ValueError, AgentLoadError, UnknownEnvError, GymnasiumError, yaml.YAMLError)


def error_message(exc: BaseException) -> str:
    """``exc`` as one line (its message, or its type name when it has none)."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def report_errors(prog: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> int:
    """``fn(*args, **kwargs)`` as an exit status; an expected error prints one line and gives 2."""
    try:
        return int(fn(*args, **kwargs) or 0)
    except expected_errors() as exc:
        if os.environ.get("NAVGYM_DEBUG"):
            raise
        print(f"{prog}: error: {error_message(exc)} (NAVGYM_DEBUG=1 shows the traceback)", file=sys.stderr)
        return EXIT_USAGE
