"""Grid search of the parametrised baselines on tuning seeds (:mod:`.search`) and its command.

* :mod:`.search` — :func:`tune` (one baseline's grid, batched), :func:`tune_env` (every
  baseline of an env, written to ``agents/baselines/tuned/<EnvName-vK>.json``), the
  :class:`TuneStrategy` seam that lets another scorer (:mod:`agents.scale.ray_tuning`) stand in
  for :func:`tune`;
* the grid's chunks run in forked worker processes (:func:`agents.workers.map_chunks`, shared
  with the evaluation's parts);
* :mod:`.cli` — ``navgym tune`` / ``python -m agents.tuning`` (chooses the strategy).

The search imports neither the command nor any scale-out code.
"""

from __future__ import annotations

from agents.tuning.search import (
    DEFAULT_MAX_BATCH,
    MAX_BATCH,
    LocalTuneStrategy,
    TuneStrategy,
    grid_points,
    score_points,
    tune,
    tune_env,
)

__all__ = [
    "DEFAULT_MAX_BATCH",
    "LocalTuneStrategy",
    "MAX_BATCH",
    "TuneStrategy",
    "grid_points",
    "score_points",
    "tune",
    "tune_env",
]
