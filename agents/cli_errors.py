"""One-line error reports for the ``navgym train`` / ``navgym eval`` command lines.

:func:`navgym.cli_errors.report_errors` with the agents' own input errors: a configuration
lookup that finds no entry (``UnknownEnvError``, a ``KeyError``; a bare ``KeyError`` is usually
a bug and keeps its traceback). A model that does not load raises ``AgentLoadError``, a
``ValueError``, which is reported anyway.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from navgym.cli_errors import EXIT_USAGE, error_message

__all__ = ["EXIT_USAGE", "error_message", "report_errors"]


def report_errors(prog: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> int:
    """``fn(*args, **kwargs)`` as an exit status; an expected error prints one line and gives 2."""
    from agents.training.config import UnknownEnvError
    from navgym.cli_errors import report_errors as report

    return report(prog, fn, *args, extra=(UnknownEnvError,), **kwargs)
