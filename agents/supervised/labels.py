"""Supervised labels of the RowScale ids: the regime oracle's classes from the step's truth.

The RowScale task's regime oracle (:meth:`navgym.envs.tasks.RowScaleTask.regime_knob`) sets
each row's scale from its true regime and the process-noise scale from the motion's, both read
from ``StepModels.truth`` by :func:`navgym.envs.tasks.row_scale.step_regimes`. The labels here are
that classification, with one more row class, *not received* (the row's mask is False: its scale
is ignored by the update, so the policy need not know its regime):

* rows: ``0`` nominal, ``1`` noisy, ``2`` biased, ``3`` not received;
* motion: ``0`` nominal, ``1`` event.

**Timing.** The action chosen from observation ``k`` is applied at the env's next step, with
the models that ``platform.step_models(episodes, t)`` returns for the core's current ``t``; the
label of observation ``k`` is therefore the regime of *those* models. :func:`next_step_labels`
peeks them before the step (the core's snapshot/restore keeps platforms whose ``step_models``
advances per-episode cursors unchanged). Truth is read for labels only, never fed to a policy.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from agents.evaluation.runner import native_vector_env
from navgym.envs.protocols import StepModels
from navgym.envs.tasks import RowScaleTask
from navgym.envs.tasks.row_scale import step_regimes

__all__ = [
    "MOTION_CLASSES",
    "NOT_RECEIVED",
    "ROW_CLASSES",
    "StepLabels",
    "labels_of_models",
    "next_step_labels",
    "table_scales",
]

#: Row classes, in code order (the first three index the oracle table's row entries).
ROW_CLASSES = ("nominal", "noisy", "biased", "not_received")
#: The row code of a row not received at the step.
NOT_RECEIVED = 3
#: Motion classes, in code order (index the table's ``s_q_nominal``, ``s_q_event``).
MOTION_CLASSES = ("nominal", "event")


class StepLabels(NamedTuple):
    """One step's labels of ``B`` episodes."""

    row: np.ndarray  #: (B, m_max) int64 codes of :data:`ROW_CLASSES`
    motion: np.ndarray  #: (B,) int64 codes of :data:`MOTION_CLASSES`


def labels_of_models(models: StepModels, process_states: tuple[int, ...]) -> StepLabels:
    """The labels of one step's models: the oracle's regimes, ``3`` where the row's mask is False."""
    row, event = step_regimes(models, process_states)
    received = np.asarray(models.mask, dtype=bool)
    return StepLabels(np.where(received, row, NOT_RECEIVED).astype(np.int64), event.astype(np.int64))


def next_step_labels(env: Any) -> StepLabels:
    """The labels of the step the next action of the native vector ``env`` will be applied at.

    Peeks ``platform.step_models(episodes, t)`` of the env's core and puts back every
    per-episode field it may advance, so the episodes go on exactly as without the peek.
    """
    core = native_vector_env(env).core
    task = core.task
    if not isinstance(task, RowScaleTask):
        raise ValueError(f"labels serve RowScale tasks (v3); the env's task is {task.name}")
    idx = np.arange(core.B)
    snap = core.snapshot(idx)
    try:
        models = core.platform.step_models(core.episodes, core.t)
    finally:
        core.restore(idx, snap)
    return labels_of_models(models, task.process_states)


def table_scales(labels: StepLabels, table: np.ndarray) -> np.ndarray:
    """The scales ``(B, m_max + 1)`` the oracle's ``table`` gives the labels (not received: ``s_nominal``)."""
    t = np.asarray(table, dtype=np.float64)
    row = np.where(labels.row == NOT_RECEIVED, 0, labels.row)
    return np.column_stack([t[:3][row], t[3:5][labels.motion]])
