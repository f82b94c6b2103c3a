"""One-line error reports for the ``navgym train`` / ``navgym eval`` command lines.

:func:`navgym.cli_errors.report_errors` with the agents' own input errors: a configuration
lookup that finds no entry (``UnknownEnvError``, a ``KeyError``; a bare ``KeyError`` is usually
a bug and keeps its traceback). A model that does not load raises ``AgentLoadError``, a
``ValueError``, which is reported anyway.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from navgym.cli_errors import EXIT_USAGE, error_message

__all__ = ["EXIT_USAGE", "GYM_PACKAGES_HINT", "error_message", "report_errors", "with_gym_packages_hint"]


#: What an unknown id's message adds: the option that imports the module registering it.
GYM_PACKAGES_HINT = "an id registered outside navgym needs its module: --gym-packages MODULE"


def with_gym_packages_hint(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn``, whose Gymnasium "not found" errors (unknown namespace, name) point to ``--gym-packages``."""
    from gymnasium.error import UnregisteredEnv

    @functools.wraps(fn)
    def call(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except UnregisteredEnv as exc:
            if "--gym-packages" in str(exc):
                raise
            raise type(exc)(f"{exc} ({GYM_PACKAGES_HINT})") from exc

    return call


def report_errors(prog: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> int:
    """``fn(*args, **kwargs)`` as an exit status; an expected error prints one line and gives 2.

    An id Gymnasium does not find gets :data:`GYM_PACKAGES_HINT`.
    """
    from agents.training.config import UnknownEnvError
    from navgym.cli_errors import report_errors as report

    return report(prog, with_gym_packages_hint(fn), *args, extra=(UnknownEnvError,), **kwargs)
