"""The navgym registry: ``navgym/<Platform><Task>-v<k>`` ids, collected from the platforms.

Each platform exports its own entries (``ENTRIES``: :class:`~navgym.envs.ids.EnvEntry`, each
with the classes that make the id, its ``max_episode_steps`` and its default keyword arguments)
from its own package: navgym's platforms are :data:`BUILTIN_PLATFORMS`; another package adds
its platforms (and tasks) through the entry-point group :data:`PLATFORM_GROUP`,
``navgym.platforms``, whose objects are entry lists or functions returning one (registering the
package's tasks first, :func:`navgym.envs.tasks.register_task`); a script registers a platform
with :func:`register_platform`. :func:`register_all` loads the entry points and registers every
id with Gymnasium (an ``entry_point`` for the single env, a ``vector_entry_point`` for the
native batched env, the default of ``gym.make_vec``), idempotently. Variants are keyword
arguments. ``docs/add_a_platform.md`` and ``docs/add_a_task.md`` are the checklists.
"""

from __future__ import annotations

import contextlib
import importlib
import warnings
from collections.abc import Callable, Iterable, Iterator
from importlib import metadata

import gymnasium as gym

from navgym.envs.ids import V1_PENALTY, V1_RESAMPLE, V2_CHANGES, EnvEntry

__all__ = [
    "BUILTIN_PLATFORMS",
    "ENVIRONMENTS",
    "PLATFORM_GROUP",
    "V1_PENALTY",
    "V1_RESAMPLE",
    "V2_CHANGES",
    "V2_ENVIRONMENTS",
    "EnvEntry",
    "entry",
    "load_platform_entry_points",
    "platform_entries",
    "register_all",
    "register_platform",
    "superseded_ids_quiet",
]

#: The entries navgym's own platforms export (``module:attribute``), in platform order.
BUILTIN_PLATFORMS = (
    "navgym.gps_ins.env_ids:ENTRIES",
    "navgym.quadrotor.env_ids:ENTRIES",
    "navgym.robot2d.env_ids:ENTRIES",
    "navgym.iridium.env_ids:ENTRIES",
    "navgym.pedestrian.env_ids:ENTRIES",
    "navgym.jpa.env_ids:ENTRIES",
    "navgym.signal_tracking.env_ids:ENTRIES",
    "navgym.recordings.env_ids:ENTRIES",
)
#: The entry-point group through which other packages register platforms and tasks.
PLATFORM_GROUP = "navgym.platforms"


def platform_entries(obj: Iterable[EnvEntry] | Callable[[], Iterable[EnvEntry] | None]) -> list[EnvEntry]:
    """The entries of a platform's export: a list of entries, or a function returning one.

    Raises:
        TypeError: something else, or an item that is not an :class:`EnvEntry`.
    """
    if callable(obj):
        obj = obj() or []
    entries = list(obj)
    wrong = [type(e).__name__ for e in entries if not isinstance(e, EnvEntry)]
    if wrong:
        raise TypeError(f"a platform's entries must be navgym.envs.ids.EnvEntry objects; got {wrong}")
    return entries


def _load(reference: str) -> list[EnvEntry]:
    module, _, attribute = reference.partition(":")
    return platform_entries(getattr(importlib.import_module(module), attribute))


def _ordered(platforms: list[list[EnvEntry]]) -> list[EnvEntry]:
    """Entries by release, then platform, then the platform's own order (see ``EnvEntry.release``)."""
    keyed = [((e.release, p, i), e) for p, entries in enumerate(platforms) for i, e in enumerate(entries)]
    return [e for _, e in sorted(keyed, key=lambda k: k[0])]


_PLATFORMS: list[list[EnvEntry]] = [_load(ref) for ref in BUILTIN_PLATFORMS]
#: Every id: navgym's own (the v0 ids, then v1 of the Fading and Mixture tasks, then v1 of the
#: Resample tasks, then the v2 ids platform by platform, then the replay ids), then those of the
#: platforms loaded through :data:`PLATFORM_GROUP` (added by :func:`register_all`).
ENVIRONMENTS: list[EnvEntry] = _ordered(_PLATFORMS)
#: navgym's own ``-v2`` ids (the platforms' v2 episodes).
V2_ENVIRONMENTS: list[EnvEntry] = [e for e in ENVIRONMENTS if e.id.endswith("-v2")]
#: Names of the entry points of :data:`PLATFORM_GROUP` already loaded.
_LOADED: set[str] = set()


def platform_entry_points() -> list[metadata.EntryPoint]:
    """The entry points of :data:`PLATFORM_GROUP`, sorted by name."""
    return sorted(metadata.entry_points(group=PLATFORM_GROUP), key=lambda ep: ep.name)


def _add(entries: list[EnvEntry]) -> list[str]:
    """Add a platform's entries to :data:`ENVIRONMENTS` (those not there yet); the ids taken by others."""
    known = {e.id: e for e in ENVIRONMENTS}
    taken = sorted(e.id for e in entries if e.id in known and known[e.id] != e)
    fresh = [e for e in entries if e.id not in known]
    if not taken and fresh:
        _PLATFORMS.append(fresh)
        ENVIRONMENTS[:] = _ordered(_PLATFORMS)
    return taken


def _register(entries: Iterable[EnvEntry]) -> list[str]:
    """Register ``entries`` with Gymnasium (those not registered yet); their ids."""
    ids = []
    for e in entries:
        if e.id not in gym.registry:
            gym.register(
                id=e.id,
                entry_point=e.entry_point,
                vector_entry_point=e.vector_entry_point,
                max_episode_steps=e.steps,
                kwargs={"task": e.task, **e.defaults},
            )
        ids.append(e.id)
    return ids


def register_platform(
    entries: Iterable[EnvEntry] | Callable[[], Iterable[EnvEntry] | None],
) -> list[str]:
    """Register a platform's entries (the one line a platform needs outside a package); their ids.

    Adds them to :data:`ENVIRONMENTS` and registers them with Gymnasium; the same entries again
    change nothing. ``entries`` is what an entry point of :data:`PLATFORM_GROUP` names: a list
    of :class:`EnvEntry`, or a function returning one.

    Raises:
        ValueError: an id is registered already with another entry.
    """
    new = platform_entries(entries)
    taken = _add(new)
    if taken:
        raise ValueError(f"ids registered already with other entries: {taken}")
    return _register(new)


def load_platform_entry_points() -> list[EnvEntry]:
    """Load the entry points of :data:`PLATFORM_GROUP` not loaded yet; add their ids to ENVIRONMENTS.

    Returns the entries added. An entry point that fails to load, or whose ids are taken
    already, is skipped with a ``RuntimeWarning`` naming it (a broken plug-in does not break
    ``import navgym``).
    """
    added: list[EnvEntry] = []
    for ep in platform_entry_points():
        if ep.name in _LOADED:
            continue
        _LOADED.add(ep.name)
        try:
            entries = platform_entries(ep.load())
        except Exception as exc:
            warnings.warn(
                f"navgym: the {PLATFORM_GROUP} entry point {ep.name!r} ({ep.value}) failed to load: {exc!r}",
                RuntimeWarning,
                stacklevel=2,
            )
            continue
        taken = _add(entries)
        if taken:
            warnings.warn(
                f"navgym: the {PLATFORM_GROUP} entry point {ep.name!r} registers ids taken already: {taken}",
                RuntimeWarning,
                stacklevel=2,
            )
            continue
        added += entries
    return added


def register_all() -> list[str]:
    """Register every navgym environment, those of :data:`PLATFORM_GROUP` included; return the ids.

    A second call changes nothing (it loads entry points installed since).
    """
    load_platform_entry_points()
    return _register(ENVIRONMENTS)


@contextlib.contextmanager
def superseded_ids_quiet() -> Iterator[None]:
    """Silence gymnasium's "out of date" notice for the superseded navgym ids inside the block.

    For tools that use a ``-v0`` id on purpose (a zoo agent trained on it, benchmarks whose
    targets were set on it); everywhere else the notice points users to the ``-v1`` ids.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", message=r".*navgym/\S*-v[01] is out of date", category=DeprecationWarning
        )
        yield


def entry(env_id: str) -> EnvEntry:
    """The entry of ``env_id`` (``KeyError`` if it is not a navgym id)."""
    for e in ENVIRONMENTS:
        if e.id == env_id:
            return e
    raise KeyError(env_id)
