"""What the agent controls, shared across platforms: one module per task, each with its spec.

A task owns the filter state, maps the agent's action to the filter's knob, runs one filter
step with that knob (a :class:`~navgym.envs.protocols.TaskStep` with its typed diagnostics) and
adds its own observation features and reward cost. Each task module declares the task's
:class:`TaskSpec` next to its class and registers it (:func:`register_task`):

* :mod:`~navgym.envs.tasks.fading` — :class:`FadingTask`, the fading factor of any Gaussian
  filter (``P- = lambda F P F^T + Q``; Benzerrouk 2014, eq. 63-70).
* :mod:`~navgym.envs.tasks.mixture` — :class:`MixtureTask`, the outlier weight of a
  Gaussian-sum filter's noise mixture (Benzerrouk 2014, eq. 71-76), one or one per row.
* :mod:`~navgym.envs.tasks.noise_scale` — :class:`NoiseScaleTask` (v2), the scales of ``Q``
  and ``R`` (after Gao et al. 2020).
* :mod:`~navgym.envs.tasks.row_scale` — :class:`RowScaleTask` (v3), one measurement-noise
  multiplier per row and a scale of the motion states' process noise.
* :mod:`~navgym.envs.tasks.robust` — :class:`RobustTask` (v2), the threshold of a robust
  iterated EKF / ESKF (Belles et al. 2022, eq. 20, Algorithm 1).
* :mod:`~navgym.envs.tasks.resample` — :class:`ResampleTask`, a bootstrap particle filter's
  decision to resample now.

The Gaussian tasks share :class:`~navgym.envs.tasks.base.GaussianTask` (the ``filter``
argument, the clairvoyant reference, the isolation of rows whose prediction overflowed), and
every task checks its actions with :func:`check_action`. A platform's own task registers from
the platform's package (SignalTracking's Jumps task, :mod:`navgym.signal_tracking.task`).

**Arguments** are declared in each task's spec (:class:`~navgym.envs.arguments.Argument`: rule
and documentation) and checked at construction (the error names the argument, the value and the
accepted range).
"""

from navgym.envs.protocols import TaskStep
from navgym.envs.tasks.actions import check_action
from navgym.envs.tasks.base import GaussianTask, NoTruthError, isolate_nonfinite, truth_of
from navgym.envs.tasks.fading import FADING, FadingDiagnostics, FadingTask, fading_traces
from navgym.envs.tasks.mixture import MIXTURE, MixtureDiagnostics, MixtureTask
from navgym.envs.tasks.noise_scale import (
    MAX_SCALE_DECADES,
    NOISE_SCALE,
    SCALE_SNAP,
    NoiseScaleDiagnostics,
    NoiseScaleTask,
)
from navgym.envs.tasks.registry import TaskSpec, make_task, register_task, task_spec, task_specs, task_title
from navgym.envs.tasks.resample import (
    MAX_PARTICLES,
    MAX_ROUGHENING,
    RESAMPLE,
    FilterStep,
    ParticleBelief,
    ResampleDiagnostics,
    ResampleTask,
)
from navgym.envs.tasks.robust import ROBUST, ROBUST_WEIGHTS, RobustDiagnostics, RobustTask
from navgym.envs.tasks.row_scale import ROW_SCALE, RowScaleDiagnostics, RowScaleTask

__all__ = [
    "FADING",
    "MAX_PARTICLES",
    "MAX_ROUGHENING",
    "MAX_SCALE_DECADES",
    "MIXTURE",
    "NOISE_SCALE",
    "RESAMPLE",
    "ROBUST",
    "ROBUST_WEIGHTS",
    "ROW_SCALE",
    "SCALE_SNAP",
    "FadingDiagnostics",
    "FadingTask",
    "FilterStep",
    "GaussianTask",
    "MixtureDiagnostics",
    "MixtureTask",
    "NoTruthError",
    "NoiseScaleDiagnostics",
    "NoiseScaleTask",
    "ParticleBelief",
    "ResampleDiagnostics",
    "ResampleTask",
    "RobustDiagnostics",
    "RobustTask",
    "RowScaleDiagnostics",
    "RowScaleTask",
    "TaskSpec",
    "TaskStep",
    "check_action",
    "fading_traces",
    "isolate_nonfinite",
    "make_task",
    "register_task",
    "task_spec",
    "task_specs",
    "task_title",
    "truth_of",
]
