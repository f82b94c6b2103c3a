"""Episodes simulated once per distinct generator: rows reset with the same seed share one simulation.

A batch whose rows are reset from generators in the same state (the same seed) and with drawn
scenarios holds the same episode in each of them: every platform draws an episode from its own
generator only, a fixed amount whatever the batch (the registry-wide *vector = single* tests hold
this), so simulating such a row again returns the same arrays and leaves its generator where the
first one's is left. Tuning and knob-reach searches reset one batch with the same episodes
repeated once per grid point (``agents.tuning.search``), where the simulation of new episodes is
most of a step's cost at large batches (``navgym bench step_profile``: 60-70 % at B = 1024 on the
v3 ids); :func:`simulate_distinct` simulates each distinct row once and copies it.

The result equals simulating every row: the episodes' arrays are the distinct rows' taken back
to every row (:func:`navgym.envs.rows.take_rows`), a duplicate's objects (an object array's
entries: per-episode generators that keep drawing during the episode) are its own deep copies,
each duplicate's generator is set to the state its twin's ends in, and its scenario is the
twin's (scenarios are immutable). Rows with a pinned
scenario are never merged (a scenario object is not compared).

A search also resets the *same* episodes again and again: every chunk of a tuning grid is a new
vector env reset with the same tuning seeds. Inside :meth:`EpisodeCache.active` the distinct rows'
simulation is kept, keyed by the platform (its fields, pickled), the horizon, the compiled-path switch and
the generators' states before the draw; a later reset of the same rows takes copies of the kept
arrays (object entries deep-copied) and sets the generators to the states the simulation left
them in, which is what simulating them again returns.
"""

from __future__ import annotations

import copy
import dataclasses
import pickle
from collections import OrderedDict
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, NamedTuple, cast

import numpy as np

from filters.core.compiled import compiled_enabled
from navgym.envs.protocols import Platform
from navgym.envs.rows import take_rows
from navgym.scenarios import Scenario

__all__ = ["EpisodeCache", "distinct_rows", "simulate_distinct"]


class CachedEpisodes(NamedTuple):
    """The distinct rows' simulation as :class:`EpisodeCache` keeps it."""

    episodes: Any  #: the platform's episodes NamedTuple (arrays never handed out, objects own copies)
    scenarios: tuple[Scenario, ...]  #: the drawn scenario of each row
    states: tuple[Mapping[str, Any], ...]  #: each row's generator state after the simulation


class EpisodeCache:
    """Episodes simulated once per search: resets of the same rows inside :meth:`active` reuse them.

    A tuning grid is scored in chunks, each a new vector env reset with the same tuning seeds
    (:func:`agents.tuning.search.score_points`); without a cache every chunk simulates the same
    episodes again (about a fifth of a QuadrotorRowScale-v3 chunk). Entries are keyed by the
    platform (the pickle of its dataclass fields), the horizon,
    :func:`filters.core.compiled.compiled_enabled` and every distinct row's generator state
    (pickled), with drawn (not pinned) scenarios only; the ``maxsize`` most recent are kept. A
    platform that does not pickle is not cached.

    The cache is an ordinary object: a forked worker process holds its own copy of it.
    """

    def __init__(self, maxsize: int = 2) -> None:
        if int(maxsize) < 1:
            raise ValueError(f"maxsize must be at least 1; got {maxsize}")
        self.maxsize = int(maxsize)
        self.hits = 0  #: resets served from the cache
        self.misses = 0  #: cacheable resets simulated (and kept)
        self._entries: OrderedDict[tuple[Any, ...], CachedEpisodes] = OrderedDict()

    def __len__(self) -> int:
        return len(self._entries)

    @contextmanager
    def active(self) -> Iterator[EpisodeCache]:
        """Resets inside the block (this thread or context) read and fill this cache."""
        token = _ACTIVE.set(self)
        try:
            yield self
        finally:
            _ACTIVE.reset(token)

    def key(
        self, platform: Platform, rngs: Sequence[np.random.Generator], scenarios: Sequence[Any | None], T: int
    ) -> tuple[Any, ...] | None:
        """The entry key of these rows, or ``None`` where they are not cacheable (a pinned scenario)."""
        if any(s is not None for s in scenarios):
            return None
        try:
            fingerprint = _fingerprint(platform)
        except (pickle.PicklingError, TypeError, AttributeError):
            return None
        states = tuple(pickle.dumps(g.bit_generator.state) for g in rngs)
        return (fingerprint, int(T), compiled_enabled(), states)

    def get(self, key: tuple[Any, ...]) -> CachedEpisodes | None:
        """The entry of ``key`` (now the most recent), or ``None``."""
        entry = self._entries.get(key)
        if entry is not None:
            self._entries.move_to_end(key)
            self.hits += 1
        return entry

    def put(self, key: tuple[Any, ...], entry: CachedEpisodes) -> None:
        """Keep ``entry``; the least recent beyond ``maxsize`` is dropped."""
        self.misses += 1
        self._entries[key] = entry
        self._entries.move_to_end(key)
        while len(self._entries) > self.maxsize:
            self._entries.popitem(last=False)


def _fingerprint(platform: Platform) -> bytes:
    """The pickle of a platform's defining state: a dataclass's fields (its class included).

    Not the whole object: a platform's ``cached_property`` values (``Q``, ``R``) enter its
    ``__dict__`` when first read, which would change the pickle between two resets.
    """
    if dataclasses.is_dataclass(platform):
        fields = [(f.name, getattr(platform, f.name)) for f in dataclasses.fields(platform)]
        return pickle.dumps((type(platform), fields))
    return pickle.dumps(platform)


#: The cache of the running :meth:`EpisodeCache.active` block (``None``: resets simulate).
_ACTIVE: ContextVar[EpisodeCache | None] = ContextVar("navgym_episode_cache", default=None)


def distinct_rows(rngs: Sequence[np.random.Generator], scenarios: Sequence[Any | None]) -> np.ndarray:
    """``inverse (B,)``: for each row, the first row whose generator state equals its own.

    Only rows whose scenario is ``None`` (to be drawn) are merged; a row with a pinned scenario is
    its own. The state is compared whole (``bit_generator.state``, pickled).
    """
    first: dict[bytes, int] = {}
    inverse = np.arange(len(rngs))
    for j, (g, s) in enumerate(zip(rngs, scenarios, strict=True)):
        if s is None:
            key = pickle.dumps(g.bit_generator.state)
            inverse[j] = first.setdefault(key, j)
    return inverse


def _batch_leading(a: Any, n: int) -> bool:
    """Every array field (nested NamedTuples included) has ``n`` rows."""
    for f in a:
        if isinstance(f, np.ndarray) and f.ndim >= 1 and f.shape[0] != n:
            return False
        if isinstance(f, tuple) and hasattr(f, "_fields") and not _batch_leading(f, n):
            return False
    return True


def _simulate(
    platform: Platform, rngs: list[np.random.Generator], scen: list[Any | None], T: int
) -> tuple[Any, list[Scenario]]:
    """Draw the ``None`` scenarios, then simulate every row."""
    drawn = [j for j, s in enumerate(scen) if s is None]
    if drawn:
        for j, s in zip(drawn, platform.sample_scenarios([rngs[j] for j in drawn]), strict=True):
            scen[j] = s
    full = cast(list[Scenario], scen)  # every one drawn or pinned now
    return platform.simulate(rngs, full, T), full


def simulate_distinct(
    platform: Platform, rngs: Sequence[np.random.Generator], scenarios: Sequence[Any | None], T: int
) -> tuple[Any, list[Scenario]]:
    """``platform.simulate`` of every row, drawing the ``None`` scenarios; each distinct row once.

    Returns the episodes (every row) and the scenarios (drawn or pinned). Without duplicates (and
    no active :class:`EpisodeCache`) this is ``sample_scenarios`` of the ``None`` rows then
    ``simulate`` of all. A platform whose episodes hold an array without the episode axis is
    simulated row by row as without duplicates (and not cached).
    """
    rngs, scen = list(rngs), list(scenarios)
    inverse = distinct_rows(rngs, scen)
    own = inverse == np.arange(len(rngs))
    cache = _ACTIVE.get()
    if own.all() and cache is None:
        return _simulate(platform, rngs, scen, T)
    keep = np.flatnonzero(own)
    sub_rngs, sub_in = [rngs[k] for k in keep], [scen[k] for k in keep]
    key = cache.key(platform, sub_rngs, sub_in, T) if cache is not None else None
    entry = cache.get(key) if cache is not None and key is not None else None
    if entry is not None:  # copies of the kept rows below; the generators where simulating leaves them
        for g, st in zip(sub_rngs, entry.states, strict=True):
            g.bit_generator.state = st
        eps, sub_scen = entry.episodes, list(entry.scenarios)
    else:
        saved = [g.bit_generator.state for g in sub_rngs]
        eps, sub_scen = _simulate(platform, sub_rngs, sub_in, T)
        if not _batch_leading(eps, keep.size):
            for g, st in zip(sub_rngs, saved, strict=True):
                g.bit_generator.state = st
            return _simulate(platform, rngs, scen, T)
        if cache is not None and key is not None:
            every = np.arange(keep.size)
            kept = _own_objects(take_rows(eps, every), every)
            cache.put(
                key, CachedEpisodes(kept, tuple(sub_scen), tuple(g.bit_generator.state for g in sub_rngs))
            )
        if own.all():
            return eps, sub_scen
    position = np.empty(len(rngs), dtype=np.int64)
    position[keep] = np.arange(keep.size)
    rows = position[inverse]
    for j in np.flatnonzero(~own):
        rngs[j].bit_generator.state = rngs[inverse[j]].bit_generator.state
    # every row owns its objects: the duplicates' (fresh simulation) or all (the cache's entry)
    owners = np.flatnonzero(~own) if entry is None else np.arange(len(rngs))
    return _own_objects(take_rows(eps, rows), owners), [sub_scen[r] for r in rows]


def _own_objects(eps: Any, duplicates: np.ndarray) -> Any:
    """``eps`` with each duplicate row's object entries replaced by deep copies (in place).

    :func:`~navgym.envs.rows.take_rows` copies arrays, but an object array's rows are references:
    a duplicate would share its twin's mutable objects (the GpsIns episodes' noise generators,
    which draw a new block every 64 steps), and the two rows would then draw from one stream.
    """
    for a in eps:
        if isinstance(a, np.ndarray) and a.dtype == object and a.ndim >= 1:
            for j in duplicates:
                a[j] = copy.deepcopy(a[j])
        elif isinstance(a, tuple) and hasattr(a, "_fields"):
            _own_objects(a, duplicates)
    return eps
