"""What the Gaussian tasks share: the filter argument, the clairvoyant reference, failure handling.

A :class:`GaussianTask` steps a Gaussian filter's belief ``N(m, P)``: it maps the action to its
knob, predicts, isolates the rows whose prediction overflowed, updates, and reports its own
diagnostics. A subclass writes the knob (:meth:`GaussianTask.knob_of`), the prediction and the
update with that knob (:meth:`~GaussianTask.predict`, :meth:`~GaussianTask.update`) and its
features; :meth:`GaussianTask.step` is the rest.

**Clairvoyant reference** (``clairvoyant=True``; evaluation only): the task ignores the agent's
knob (reported as the neutral knob) and runs its plain filter with the step's true noise of the
platform (``StepModels.truth``, v2 platforms): ``Q = truth.Q`` in the prediction, ``R = truth.R``
in the update and ``z - truth.bias`` as the measurement. It reads truth: it is the upper
reference of what a knob could achieve (like the hindsight oracle), never a baseline, and its
observations must not be trained on. A platform that gives no truth (the v0/v1 platforms)
makes its first step raise :class:`NoTruthError`.

**Numerical failures.** A prediction that overflows in some rows (a huge fading factor on a
grown covariance) would make the update reject the whole batch; those rows are updated from
their (finite) state before the prediction instead and reported in the step's
``TaskStep.numerical_failure`` (B,), which the core turns into the end of their episodes (see
:mod:`navgym.envs.core`). The other rows' results do not change.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Generic, TypeVar

import numpy as np
from gymnasium import spaces

from filters import GaussianState
from filters import get as get_filter
from filters.registry import FILTERS, GaussianFilter, state_dim_error
from navgym.envs.arguments import Argument, Choice, Flag
from navgym.envs.protocols import StepModels, TaskDiagnostics, TaskStep, TrueNoise
from navgym.envs.rows import replace_rows, take_rows
from navgym.envs.tasks.actions import check_action

#: The ``filter`` argument of the tasks that steer any Gaussian filter of :mod:`filters.registry`.
FILTER_CHOICES = tuple(FILTERS)
#: The ``clairvoyant`` argument of the Gaussian tasks (module docstring).
CLAIRVOYANT = Argument(
    "clairvoyant",
    False,
    Flag(),
    "evaluation only: ignore the knob, run the plain filter with the step's true noise",
    opt_in=True,
)
#: What ``clairvoyant`` means, in the cards of the platforms with a Gaussian task.
CLAIRVOYANT_TEXT = (
    "``clairvoyant=True`` (Fading, Mixture, NoiseScale, Robust) is for evaluation only: the upper reference, "
    "never a baseline; the knob is ignored and the plain filter runs with the step's true ``Q``, ``R`` "
    "and measurement bias (``StepModels.truth`` of a v2 platform; it raises "
    "``navgym.envs.tasks.NoTruthError`` where the platform gives none)."
)


def filter_argument(default: str) -> Argument:
    """The ``filter`` argument: a Gaussian filter of :data:`filters.registry.FILTERS`."""
    return Argument("filter", default, Choice(FILTER_CHOICES), "the Gaussian filter the knob steers")


def runnable_filters(platform_spec: Any, task: str) -> str:
    """The cards' list of the filters of :data:`FILTER_CHOICES` that run on the platform's state size.

    ``"ghkf"`` / ``"ghkf5"`` take ``p**n`` points and are left out where ``make`` refuses them
    (:func:`filters.registry.state_dim_error`); the state size is that of ``platform_spec``'s
    platform for ``task`` with its default arguments.
    """
    n = int(platform_spec.platform(task).n)
    return ", ".join(f'``"{f}"``' for f in FILTER_CHOICES if state_dim_error(f, n) is None)


class NoTruthError(ValueError):
    """A clairvoyant task stepped on a platform that gives no true noise (``StepModels.truth``)."""


def truth_of(models: StepModels, task: str) -> TrueNoise:
    """The step's true noise of ``models`` for the clairvoyant ``task`` (:class:`NoTruthError` if None)."""
    if models.truth is None:
        raise NoTruthError(
            f"{task}(clairvoyant=True) runs the filter with the step's true noise, but this platform "
            "gives none (StepModels.truth is None: only the v2 platforms fill it); the clairvoyant "
            "is an evaluation reference of the v2 ids"
        )
    return models.truth


def isolate_nonfinite(pred: GaussianState, before: GaussianState) -> tuple[GaussianState, np.ndarray]:
    """``pred`` with its failed rows replaced by ``before``'s, and which rows those were.

    A row has failed when an entry is not finite or its entries are so large that their sum
    overflows (a covariance near the float range, which the update could only turn into inf).
    """
    B = pred.m.shape[0]
    with np.errstate(over="ignore", invalid="ignore"):
        bad = ~(np.isfinite(pred.m.sum(axis=1)) & np.isfinite(pred.P.reshape(B, -1).sum(axis=1)))
    if bad.any():
        rows = np.flatnonzero(bad)
        pred = replace_rows(pred, rows, take_rows(before, rows))
    return pred, bad


def clairvoyant_update(
    filt: GaussianFilter, pred: GaussianState, models: StepModels, truth: TrueNoise
) -> tuple[GaussianState, Any]:
    """The plain update of ``filt`` with the step's true noise: ``R = truth.R``, ``z - truth.bias``."""
    z = np.asarray(models.z) - np.asarray(truth.bias)
    return filt.update(pred, z, models.observation, mask=models.mask, R=truth.R)


DiagnosticsT = TypeVar("DiagnosticsT", bound=TaskDiagnostics)


class GaussianTask(Generic[DiagnosticsT]):
    """A task that steers a Gaussian filter (module docstring); subclasses write their knob.

    Attributes set here: ``filter_name`` (the reports' name, ``"/clairvoyant"`` appended),
    ``filter`` (the :class:`~filters.registry.GaussianFilter` whose prediction the task runs),
    ``clairvoyant`` and ``action_space`` (``Box(-1, 1, (dim,))``).
    """

    name = ""
    baseline_family = ""

    def __init__(self, filter_name: str, filt: GaussianFilter, clairvoyant: bool, dim: int) -> None:
        #: Evaluation only: ignore the knob, run the plain filter with the true noise (module docstring).
        self.clairvoyant = CLAIRVOYANT.check(clairvoyant)
        self.filter = filt
        self.filter_name = filter_name + ("/clairvoyant" if self.clairvoyant else "")
        self.action_space: spaces.Space = spaces.Box(-1.0, 1.0, shape=(dim,), dtype=np.float32)

    @staticmethod
    def gaussian_filter(filter: str) -> GaussianFilter:
        """The filter named by the ``filter`` argument (checked: a key of :data:`FILTERS`)."""
        return get_filter(Choice(FILTER_CHOICES).check("filter", filter))

    # ------------------------------------------------------------------------------------ knob
    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        """The knob of a checked action (:func:`check_action`), the neutral one under the clairvoyant."""
        a, clipped = check_action(action, self.action_space, B)
        if self.clairvoyant:
            return self.neutral_knob(B), clipped
        return self.knob_of(a), clipped

    def knob_of(self, a: np.ndarray) -> np.ndarray:
        """The knob of the clipped actions ``a (B, dim)``."""
        raise NotImplementedError

    def neutral_knob(self, B: int) -> np.ndarray:
        """The knob of the plain filter, as the clairvoyant reports it."""
        raise NotImplementedError

    def init_state(self, belief: GaussianState, rngs: Sequence[np.random.Generator]) -> GaussianState:
        return belief

    # ------------------------------------------------------------------------------------ step
    def step(
        self,
        state: GaussianState,
        knob: np.ndarray,
        models: StepModels,
        rngs: Sequence[np.random.Generator] | None,
    ) -> TaskStep[GaussianState, DiagnosticsT]:
        """Predict, isolate the rows that overflowed, update (module docstring)."""
        truth = truth_of(models, type(self).__name__) if self.clairvoyant else None
        pred = self.predict(state, knob, models, truth)
        pred, failed = isolate_nonfinite(pred, state)
        post, info, diagnostics = self.update(pred, knob, models, truth)
        numerical_failure = None
        if failed.any():
            info = info._replace(healthy=np.asarray(info.healthy) & ~failed)
            numerical_failure = failed
        B = knob.shape[0]
        return TaskStep(post, post, info, pred.P, np.zeros(B), knob, diagnostics, numerical_failure)

    def predict(
        self, state: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> GaussianState:
        """The filter's plain prediction (``Q = truth.Q`` under the clairvoyant); a knob may override it."""
        Q = None if truth is None else truth.Q
        return self.filter.predict(state, models.transition, None, models.dt, Q=Q)

    def update(
        self, pred: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> tuple[GaussianState, Any, DiagnosticsT]:
        """The update with the knob (the clairvoyant's with the true noise): ``(post, info, diagnostics)``.

        ``info`` is the filter's :class:`~navgym.envs.protocols.UpdateDiagnostics` (a NamedTuple
        with ``healthy``, which :meth:`step` clears on the rows whose prediction failed).
        """
        raise NotImplementedError
