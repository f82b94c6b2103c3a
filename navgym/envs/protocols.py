"""The typed seams between the core, a platform and a task.

A **platform** is an estimation problem (GpsIns, Quadrotor, Robot2d): it simulates B episodes
at once and tells the filter what it needs at each step. It precomputes an episode's truth and
sensor data at reset (vectorized over time, all randomness from the per-episode generators),
so steps only run the filter. Episodes are NamedTuples of arrays with the episode axis first;
rows of finished episodes are replaced in place when a vector environment resets them.

A **task** is what the agent controls (fading factor, mixture weight, resampling): it owns the
filter state, maps the action to the filter's knob, runs one filter step with it and adds its
own observation features and reward cost.

:class:`~navgym.envs.core.NavCore` connects one platform and one task; it reads them only
through the members declared here.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Generic, NamedTuple, Protocol, TypeVar, runtime_checkable

import numpy as np
from gymnasium import spaces

from filters import GaussianState
from navgym.envs.features import Feature
from navgym.scenarios import Scenario


class TrueNoise(NamedTuple):
    """The noise the simulator really used between step t and t + 1 (evaluation only: truth).

    The v2 tasks' clairvoyant reference filter runs with these instead of the nominal ``Q`` and
    ``R``; nothing of it may reach an observation.
    """

    Q: np.ndarray  #: (B, n, n) process noise of the step, unmodelled events included
    R: np.ndarray  #: (B, m_max, m_max) measurement noise of epoch t + 1 (jamming, multipath, ...)
    bias: np.ndarray  #: (B, m_max) mean measurement error of epoch t + 1 (multipath/NLOS), else 0


#: The platform's own estimator-side data of a step (:attr:`StepModels.context`).
ContextT = TypeVar("ContextT")


class StepModels(NamedTuple, Generic[ContextT]):
    """What the filter uses between step t and t + 1 for B episodes.

    Generic in the platform's ``context``: its own estimator-side data of the step that its
    features read back (``StepModels[SatelliteGeometry]`` of GpsIns; None elsewhere). The core
    hands the :class:`StepModels` that ``Platform.step_models`` returned to the task and back to
    ``Platform.feature_values`` unchanged.
    """

    transition: Any  #: TransitionModel (f, F, Q) with parameters batched over B
    observation: Any  #: ObservationModel (h, H, R) with parameters batched over B
    z: np.ndarray  #: (B, m_max) measurements (masked rows may be NaN)
    mask: np.ndarray  #: (B, m_max) True where a measurement was received
    dt: float
    context: ContextT | None = None  #: the platform's estimator-side data for its features
    truth: TrueNoise | None = None  #: the step's true noise (v2 platforms; evaluation only)


class PositionError(NamedTuple):
    """Evaluation quantities of B episodes at one step (truth allowed: they go to ``info`` only)."""

    pos_err_m: np.ndarray  #: (B,) horizontal position error [m]
    truth_pos: np.ndarray  #: (B, 2) true north/east position [m]
    est_pos: np.ndarray  #: (B, 2) estimated north/east position [m]
    cov_ne: np.ndarray  #: (B, 2, 2) the estimate's north/east covariance [m^2]
    state_err: np.ndarray | None = None  #: (B, n) estimate minus true state (for NEES), if any
    #: (B,) further error [m] the reward adds to ``pos_err_m`` (e.g. Jpa's weighted attitude error)
    extra_error: np.ndarray | None = None


class UpdateDiagnostics(Protocol):
    """A filter update's diagnostics, as the core, the features and the memory read them.

    :class:`filters.core.types.UpdateInfo` and the tasks' own (e.g. the Jumps task's) provide
    them; ``(B, ...)`` arrays.
    """

    @property
    def innovation(self) -> np.ndarray:
        """(B, m) innovations ``z - h(m-)`` (0 on masked rows)."""
        ...

    @property
    def S(self) -> np.ndarray:
        """(B, m, m) innovation covariances."""
        ...

    @property
    def nis(self) -> np.ndarray:
        """(B,) normalized innovation squared ``v^T S^-1 v`` over the rows used."""
        ...

    @property
    def log_likelihood(self) -> np.ndarray:
        """(B,) log predictive likelihood of the measurements."""
        ...

    @property
    def healthy(self) -> np.ndarray:
        """(B,) False where the update failed numerically."""
        ...

    @property
    def n_meas(self) -> np.ndarray:
        """(B,) rows used."""
        ...


class TaskDiagnostics(Protocol):
    """A task's own diagnostics of a step: a NamedTuple of ``(B, ...)`` arrays.

    Each field is a key of the step's ``info`` (e.g. the Fading task's ``fading``, ``tr_vv``,
    ...), and the task's :meth:`Task.feature_values` reads its fields by name.
    """

    def _asdict(self) -> dict[str, Any]: ...


StateT = TypeVar("StateT")
DiagnosticsT = TypeVar("DiagnosticsT", bound=TaskDiagnostics)


class TaskStep(NamedTuple, Generic[StateT, DiagnosticsT]):
    """Result of one filter step under a task (``docs/architecture.md``: the step's data flow)."""

    state: StateT  #: the task's filter state (GaussianState, ParticleBelief, DiracGaussState)
    belief: GaussianState  #: Gaussian summary (mean, covariance) used for features and errors
    info: UpdateDiagnostics  #: the update's diagnostics (innovation, S, nis, healthy, ...)
    P_pred: np.ndarray | None  #: predicted covariance (B, n, n), a baseline's input (None for particles)
    cost: np.ndarray  #: (B,) reward cost of this step's decision
    knob: np.ndarray  #: the knob the filter applied, (B,) or (B, k)
    diagnostics: DiagnosticsT  #: the task's own: its features' input and keys of ``info``
    #: (B,) rows the task isolated as numerical failures (their episodes end), None when none
    numerical_failure: np.ndarray | None = None


class Platform(Protocol):
    """A platform's estimation problem (see the module docstring).

    :class:`navgym.envs.platform.PlatformBase` provides the members whose default serves most
    platforms (``gnss_rows``, ``outlier_rows``, ``process_noise_states``, ``episode_cursors``,
    ``sample_scenarios``, a rough ``episode_bytes``).
    """

    name: str
    dt: float  #: filter step [s]
    n: int  #: state dimension
    m_max: int  #: measurement rows (fixed; a mask says which are present)
    error_scale_m: float  #: position error giving reward -1 [m]
    divergence_m: float  #: position error ending an episode [m]

    @property
    def gnss_rows(self) -> tuple[int, ...]:
        """Measurement rows that are GNSS (the core's ``time_since_gnss`` looks at these)."""
        ...

    @property
    def outlier_rows(self) -> tuple[int, ...]:
        """Rows subject to impulsive noise (the Mixture task inflates only these)."""
        ...

    @property
    def process_noise_states(self) -> tuple[int, ...]:
        """States whose process noise the RowScale task's ``s_q`` scales (the motion's: velocity)."""
        ...

    @property
    def episode_cursors(self) -> tuple[str, ...]:
        """Fields of the episodes that :meth:`step_models` advances (e.g. a noise pointer).

        The vector env's autoreset steps a freshly reset episode once and then restores it,
        these fields included.
        """
        ...

    def sample_scenarios(self, rngs: Sequence[np.random.Generator]) -> list[Scenario]:
        """One scenario per generator, drawn from the platform's scenario distribution."""
        ...

    def episode_bytes(self, T: int) -> int:
        """Bytes one episode of ``T`` steps takes: its arrays and the peak of :meth:`simulate`.

        An estimate made before anything is allocated (about the measured peak, or above it, for
        episodes of more than a few hundred steps): ``make`` refuses a batch whose
        ``num_envs * episode_bytes(episode_steps)`` exceeds
        :data:`navgym.envs.build.MAX_EPISODE_BYTES`. The task's own state (a particle cloud)
        is not counted here but by its ``TaskSpec.state_bytes``, with the episodes.
        """
        ...

    def simulate(self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int) -> Any:
        """Truth and sensor data of ``len(rngs)`` episodes of ``T`` steps (a NamedTuple)."""
        ...

    def initial_belief(self, episodes: Any) -> GaussianState:
        """The filter's prior at t = 0 (from data drawn in :meth:`simulate`)."""
        ...

    def step_models(self, episodes: Any, t: np.ndarray) -> StepModels:
        """Models and measurements for the step from ``t`` to ``t + 1`` (``t (B,)`` ints)."""
        ...

    def position_error(self, mean: np.ndarray, episodes: Any, t: np.ndarray, P: np.ndarray) -> PositionError:
        """Evaluation quantities at step ``t`` (truth allowed here; it goes to ``info`` only)."""
        ...

    def features(self) -> list[Feature]:
        """Platform observation features (estimator-side only)."""
        ...

    def initial_feature_values(self, belief: GaussianState, episodes: Any) -> dict[str, np.ndarray]:
        """Values of :meth:`features` at reset (prior only, no measurement processed yet)."""
        ...

    def feature_values(
        self, belief: GaussianState, info: UpdateDiagnostics, models: StepModels, episodes: Any, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Values of :meth:`features` from the filter's belief and update diagnostics."""
        ...


class Task(Protocol[StateT, DiagnosticsT]):
    """What the agent controls (see the module docstring); the tasks of :mod:`navgym.envs.tasks`.

    A task's :class:`~navgym.envs.tasks.TaskSpec` (its title, keyword arguments, card text,
    baseline family) is declared next to its class and registered with
    :func:`~navgym.envs.tasks.register_task`.
    """

    name: str  #: the task's title: "Fading", "Mixture", "Resample", ...
    filter_name: str  #: the filter it steers, for reports (e.g. "ekf", "pf1000/f32")
    action_space: spaces.Space
    #: The baseline family of this instance (``agents.baselines.registry``): the spec's
    #: ``baseline``, or a variant (``"RowMixture"`` for the per-row Mixture).
    baseline_family: str

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        """The filter knob ``(B, ...)`` of a validated action, and which rows were clipped ``(B,)``."""
        ...

    def neutral_action(self) -> np.ndarray:
        """The action of the plain filter (no fading, no outlier weight, never resample)."""
        ...

    def init_state(self, belief: GaussianState, rngs: Sequence[np.random.Generator]) -> StateT:
        """The task's filter state from the platform's prior."""
        ...

    def step(
        self, state: StateT, knob: np.ndarray, models: StepModels, rngs: Sequence[np.random.Generator]
    ) -> TaskStep[StateT, DiagnosticsT]:
        """One filter step (predict + update) with the knob."""
        ...

    def features(self) -> list[Feature]:
        """The task's observation features."""
        ...

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        """Values of :meth:`features` at reset (before any filter step)."""
        ...

    def feature_values(self, step: TaskStep[StateT, DiagnosticsT]) -> dict[str, np.ndarray]:
        """Values of :meth:`features` after a filter step (from ``step.diagnostics``)."""
        ...


@runtime_checkable
class ReducibleObservation(Protocol):
    """An observation model with an "observed minus computed" form of the same likelihood.

    Pseudo-range models offer it so that float32 particle clouds are weighed with metres-sized
    numbers instead of ranges of 2e7 m.
    """

    def reduced(self, z: np.ndarray) -> tuple[Any, np.ndarray]:
        """The reduced model and measurements."""
        ...


@runtime_checkable
class ErrorStateObservation(Protocol):
    """An observation model updated in error-state form (ESKF; Belles et al. 2022, eq. 13-17).

    The Robust task updates ``N(0, P-)`` with :meth:`error_state` about the predicted mean and
    resets the result into the mean with :meth:`inject` (the Jpa platform's attitude manifold).
    """

    def error_state(self, m: np.ndarray) -> Any:
        """The observation model of the error state about the means ``m (B, n)``."""
        ...

    def inject(self, m: np.ndarray, dx: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(mean, P)`` after the reset of the error posterior ``N(dx, P)`` about ``m``."""
        ...
