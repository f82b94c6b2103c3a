"""Ray as an optional dependency: lazy import, the missing-extra message, cluster connection."""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any

__all__ = [
    "INSTALL_HINT",
    "MissingExtraError",
    "init_ray",
    "ray_temp_dir",
    "report_missing",
    "require_ray",
]

#: Longest temp folder path Ray's unix sockets fit under (``<dir>/session_<time>_<pid>/sockets/
#: plasma_store`` must stay within the 107 bytes of ``AF_UNIX``).
MAX_RAY_TEMP_PATH = 40

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


def ray_temp_dir(folder: str | Path) -> str:
    """A path for Ray's ``_temp_dir`` whose files land in ``folder`` (created).

    ``folder`` itself when its absolute path is short enough for Ray's unix sockets
    (:data:`MAX_RAY_TEMP_PATH`); else a short symbolic link in the system temp folder
    (``navgym-ray-<hash>``) that points to it, so the session files still land in ``folder``.
    """
    real = Path(folder).resolve()
    real.mkdir(parents=True, exist_ok=True)
    if len(str(real)) <= MAX_RAY_TEMP_PATH:
        return str(real)
    link = Path(tempfile.gettempdir()) / f"navgym-ray-{hashlib.sha1(str(real).encode()).hexdigest()[:10]}"
    if link.is_symlink() and Path(os.readlink(link)) != real:
        link.unlink()
    if not link.is_symlink():
        link.symlink_to(real, target_is_directory=True)
    return str(link)


def init_ray(
    address: str | None = None, num_cpus: int | None = None, temp_dir: str | Path | None = None
) -> ModuleType:
    """Start local Ray (``address`` None; ``num_cpus``: default all cores) or join a cluster.

    ``address``: ``ray://head:10001`` (Ray Client), ``auto`` or ``host:6379`` (a node of the
    cluster). An already initialised Ray is used as it is. ``temp_dir``: where a local Ray
    keeps its session files (logs, sockets, spilled objects; :func:`ray_temp_dir`) instead of
    its default temp folder. The workers import the modules of ``--gym-packages``
    (:func:`agents.cli_args.ray_runtime_env`).
    """
    from agents.cli_args import ray_runtime_env

    ray = require_ray()
    if ray.is_initialized():
        return ray
    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    runtime_env = ray_runtime_env()  # the workers import the modules of --gym-packages
    env: dict[str, Any] = {"runtime_env": runtime_env} if runtime_env else {}
    if address is None:
        extra = {} if temp_dir is None else {"_temp_dir": ray_temp_dir(temp_dir)}
        ray.init(
            num_cpus=num_cpus or os.cpu_count() or 1,
            include_dashboard=False,
            log_to_driver=False,
            configure_logging=False,
            **extra,
            **env,
        )
    else:
        ray.init(address=address, log_to_driver=False, configure_logging=False, **env)
    return ray
