"""Arguments shared by the ``navgym`` commands that take an env id: ``--gym-packages``.

Ids registered outside navgym (a package of one's own calling ``gym.register``, or a platform
registered with :func:`navgym.envs.registration.register_platform`) are found by ``navgym
train / tune / eval / sweep / demo / import`` once their module is imported:
``--gym-packages PKG [PKG ...]`` (rl-zoo3's spelling) imports each module, after ``navgym``
itself (whose import registers navgym's ids and those of the ``navgym.platforms`` entry
points), while the command line is parsed, so before the id is resolved. The current folder is
searched as ``python -m`` does. A module that does not import is a usage error naming it.

Gymnasium's own ``module:Env-v0`` form of an id (``gym.make`` imports ``module`` first) works as
well where the command passes the id to ``gym.make`` unchanged.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "LOADED_PACKAGES",
    "GymPackagesError",
    "add_gym_packages",
    "import_gym_packages",
    "module_roots",
    "ray_runtime_env",
    "setup_ray_worker",
]

#: The modules imported by :func:`import_gym_packages` in this process, in order (Ray workers
#: import them too, :func:`agents.scale.ray_runtime.init_ray`).
LOADED_PACKAGES: list[str] = []


class GymPackagesError(ValueError):
    """A module named by ``--gym-packages`` did not import."""


def module_roots(names: Iterable[str]) -> list[str]:
    """The folders to put on ``sys.path`` for ``names`` (imported already) to import in another process."""
    roots: list[str] = []
    for name in names:
        file = getattr(sys.modules.get(name), "__file__", None)
        if file is None:
            continue
        path = Path(file).resolve()
        depth = name.count(".") + (1 if path.name == "__init__.py" else 0)
        root = str(path.parents[depth])
        if root not in roots:
            roots.append(root)
    return roots


def import_gym_packages(names: Iterable[str], paths: Iterable[str] = ()) -> list[str]:
    """Import navgym (its ids, its ``navgym.platforms`` entry points), then each module of ``names``.

    Returns the names. The current folder is searched after the installed packages, as
    ``python -m`` does (the ``navgym`` script's own ``sys.path`` lacks it), and so are ``paths``
    (:func:`module_roots` of another process, e.g. a sweep's Ray trials).

    Raises:
        GymPackagesError: a module does not import (its name and the reason).
    """
    import navgym  # noqa: F401  (registers navgym's ids)
    from navgym.envs.registration import register_all

    register_all()  # entry points installed since navgym was imported
    names = [str(n) for n in names]
    for folder in [*([os.getcwd()] if "" not in sys.path else []), *paths] if names else []:
        if folder not in sys.path:
            sys.path.append(folder)
    for name in names:
        try:
            importlib.import_module(name)
        except Exception as exc:
            if os.environ.get("NAVGYM_DEBUG"):
                raise
            reason = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
            raise GymPackagesError(
                f"--gym-packages: cannot import module {name!r} ({reason}); it must be importable "
                "from the current folder or the Python path (PYTHONPATH)"
            ) from exc
        if name not in LOADED_PACKAGES:
            LOADED_PACKAGES.append(name)
    return names


#: Environment variables of Ray's workers: the modules to import and the folders to search.
PACKAGES_VAR, PATHS_VAR = "NAVGYM_GYM_PACKAGES", "NAVGYM_GYM_PATHS"


def ray_runtime_env() -> dict[str, Any]:
    """Ray's ``runtime_env`` importing :data:`LOADED_PACKAGES` in every worker (``{}`` when none).

    A worker process starts with :func:`setup_ray_worker` (Ray's ``worker_process_setup_hook``),
    so that ``navgym eval --ray``, ``navgym tune --ray`` and ``navgym sweep`` find the ids.
    """
    if not LOADED_PACKAGES:
        return {}
    return {
        "worker_process_setup_hook": f"{__name__}.setup_ray_worker",
        "env_vars": {
            PACKAGES_VAR: os.pathsep.join(LOADED_PACKAGES),
            PATHS_VAR: os.pathsep.join(module_roots(LOADED_PACKAGES)),
        },
    }


def setup_ray_worker() -> None:
    """Import the modules :func:`ray_runtime_env` names (a Ray worker's setup hook)."""
    names = [n for n in os.environ.get(PACKAGES_VAR, "").split(os.pathsep) if n]
    paths = [p for p in os.environ.get(PATHS_VAR, "").split(os.pathsep) if p]
    import_gym_packages(names, paths)


class _ImportGymPackages(argparse.Action):
    """``--gym-packages``: imports the modules as the option is parsed (before any id is resolved)."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[Any] | None,
        option_string: str | None = None,
    ) -> None:
        names = [values] if isinstance(values, str) else list(values or [])
        try:
            import_gym_packages(names)
        except GymPackagesError as exc:
            raise argparse.ArgumentError(self, str(exc).removeprefix("--gym-packages: ")) from None
        setattr(namespace, self.dest, [*(getattr(namespace, self.dest, None) or []), *names])


def add_gym_packages(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add ``--gym-packages PKG [PKG ...]`` to a command that takes an env id; return the parser."""
    parser.add_argument(
        "--gym-packages",
        nargs="+",
        default=[],
        metavar="PKG",
        action=_ImportGymPackages,
        help=(
            "modules to import before the env id is resolved, for ids registered outside navgym "
            "(e.g. a module calling gym.register); the current folder is searched"
        ),
    )
    return parser
