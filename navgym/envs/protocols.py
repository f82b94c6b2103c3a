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
from typing import Any, NamedTuple, Protocol, runtime_checkable

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


class StepModels(NamedTuple):
    """What the filter uses between step t and t + 1 for B episodes."""

    transition: Any  #: TransitionModel (f, F, Q) with parameters batched over B
    observation: Any  #: ObservationModel (h, H, R) with parameters batched over B
    z: np.ndarray  #: (B, m_max) measurements (masked rows may be NaN)
    mask: np.ndarray  #: (B, m_max) True where a measurement was received
    dt: float
    aux: Any = None  #: platform-specific estimator-side extras for the features (e.g. geometry)
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


class TaskStep(NamedTuple):
    """Result of one filter step under a task."""

    state: Any  #: the task's filter state (GaussianState or ParticleBelief)
    belief: GaussianState  #: Gaussian summary (mean, covariance) used for features and errors
    info: Any  #: UpdateInfo-like diagnostics (innovation, S, nis, log_likelihood, healthy, n_meas)
    P_pred: np.ndarray | None  #: predicted covariance (B, n, n), a baseline's input (None for particles)
    cost: np.ndarray  #: (B,) reward cost of this step's decision
    extras: dict[str, np.ndarray]  #: task features and info (ESS, mixture weights, ...)


class Platform(Protocol):
    """A platform's estimation problem (see the module docstring).

    :class:`navgym.envs.platform.PlatformBase` provides the members whose default serves most
    platforms (``gnss_rows``, ``outlier_rows``, ``episode_cursors``, ``sample_scenarios``, a rough
    ``episode_bytes``).
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
        :data:`navgym.envs.platform.MAX_EPISODE_BYTES`. The task's own state (a particle cloud)
        is not counted here.
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
        self, belief: GaussianState, info: Any, models: StepModels, episodes: Any, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Values of :meth:`features` from the filter's belief and update diagnostics."""
        ...


class Task(Protocol):
    """What the agent controls (see the module docstring); implementations in :mod:`navgym.envs.tasks`."""

    name: str  #: "Fading", "Mixture", "Resample"
    filter_name: str  #: the filter it steers, for reports (e.g. "ekf", "pf1000/f32")
    action_space: spaces.Space

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        """The filter knob ``(B,)`` of a validated action, and which rows were clipped ``(B,)``."""
        ...

    def neutral_action(self) -> np.ndarray:
        """The action of the plain filter (no fading, no outlier weight, never resample)."""
        ...

    def init_state(self, belief: GaussianState, rngs: Sequence[np.random.Generator]) -> Any:
        """The task's filter state from the platform's prior."""
        ...

    def step(
        self, state: Any, knob: np.ndarray, models: StepModels, rngs: Sequence[np.random.Generator]
    ) -> TaskStep:
        """One filter step (predict + update) with the knob."""
        ...

    def features(self) -> list[Feature]:
        """The task's observation features."""
        ...

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        """Values of :meth:`features` at reset (before any filter step)."""
        ...

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        """Values of :meth:`features` after a filter step."""
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
