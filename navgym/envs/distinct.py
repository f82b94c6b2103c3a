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
"""

from __future__ import annotations

import copy
import pickle
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

from navgym.envs.protocols import Platform
from navgym.envs.rows import take_rows
from navgym.scenarios import Scenario

__all__ = ["distinct_rows", "simulate_distinct"]


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

    Returns the episodes (every row) and the scenarios (drawn or pinned). Without duplicates this
    is ``sample_scenarios`` of the ``None`` rows then ``simulate`` of all. A platform whose episodes
    hold an array without the episode axis is simulated row by row as without duplicates.
    """
    rngs, scen = list(rngs), list(scenarios)
    inverse = distinct_rows(rngs, scen)
    own = inverse == np.arange(len(rngs))
    if own.all():
        return _simulate(platform, rngs, scen, T)
    keep = np.flatnonzero(own)
    sub_rngs = [rngs[k] for k in keep]
    saved = [g.bit_generator.state for g in sub_rngs]
    eps, sub_scen = _simulate(platform, sub_rngs, [scen[k] for k in keep], T)
    if not _batch_leading(eps, keep.size):
        for g, st in zip(sub_rngs, saved, strict=True):
            g.bit_generator.state = st
        return _simulate(platform, rngs, scen, T)
    position = np.empty(len(rngs), dtype=np.int64)
    position[keep] = np.arange(keep.size)
    rows = position[inverse]
    for j in np.flatnonzero(~own):
        rngs[j].bit_generator.state = rngs[inverse[j]].bit_generator.state
    return _own_objects(take_rows(eps, rows), np.flatnonzero(~own)), [sub_scen[r] for r in rows]


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
