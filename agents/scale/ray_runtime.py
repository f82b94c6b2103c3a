"""Ray as an optional dependency: lazy import, the missing-extra message, cluster connection."""

from __future__ import annotations

import os
import sys
from types import ModuleType

__all__ = ["INSTALL_HINT", "MissingExtraError", "init_ray", "report_missing", "require_ray"]

#: How to get the optional dependencies of the scale-out commands.
INSTALL_HINT = "pip install -e '.[scale]'"


class MissingExtraError(ModuleNotFoundError):
    """Ray (the ``scale`` extra) is not installed; the message says how to install it.

    ``detail``: the message without the name of what needed it.
    """

    def __init__(self, what: str, missing: str | None) -> None:
        self.detail = f"needs the 'scale' extra (missing module {missing!r}); {INSTALL_HINT}"
        super().__init__(f"{what}: {self.detail}", name=missing)


def require_ray(what: str = "this command") -> ModuleType:
    """``import ray`` (with Tune), or :class:`MissingExtraError` naming the extra to install."""
    try:
        import ray
        import ray.tune  # the [tune] part of the extra
    except ModuleNotFoundError as exc:
        raise MissingExtraError(what, exc.name) from exc
    return ray


def report_missing(prog: str, exc: MissingExtraError) -> int:
    """Print ``<prog>: needs the 'scale' extra ...`` to stderr; the exit status 2 of a missing extra."""
    print(f"{prog}: {exc.detail}", file=sys.stderr)
    return 2


def init_ray(address: str | None = None, num_cpus: int | None = None) -> ModuleType:
    """Start local Ray (``address`` None; ``num_cpus``: default all cores) or join a cluster.

    ``address``: ``ray://head:10001`` (Ray Client), ``auto`` or ``host:6379`` (a node of the
    cluster). An already initialised Ray is used as it is.
    """
    ray = require_ray()
    if ray.is_initialized():
        return ray
    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    if address is None:
        ray.init(
            num_cpus=num_cpus or os.cpu_count() or 1,
            include_dashboard=False,
            log_to_driver=False,
            configure_logging=False,
        )
    else:
        ray.init(address=address, log_to_driver=False, configure_logging=False)
    return ray
