"""The estimation problem of an environment family (the "platform"), as a protocol.

A platform simulates B episodes at once and tells the filter what it needs at each step. It
precomputes an episode's truth and sensor data at reset (vectorized over time, all randomness
from the per-episode generators), so steps only run the filter. Episodes are NamedTuples of
arrays with the episode axis first; rows of finished episodes are replaced in place when a
vector environment resets them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np

from filters import GaussianState
from navgym.envs.features import Feature


class StepModels(NamedTuple):
    """What the filter uses between step t and t + 1 for B episodes."""

    transition: Any  # TransitionModel (f, F, Q) with parameters batched over B
    observation: Any  # ObservationModel (h, H, R) with parameters batched over B
    z: np.ndarray  # (B, m_max) measurements (masked rows may be NaN)
    mask: np.ndarray  # (B, m_max) True where a measurement was received
    dt: float
    aux: Any = None  # platform-specific estimator-side extras for the features (e.g. geometry)


class Platform(Protocol):
    """A platform's estimation problem (GpsIns, Quadrotor, Robot2d)."""

    name: str
    dt: float  #: filter step [s]
    n: int  #: state dimension
    m_max: int  #: measurement rows (fixed; a mask says which are present)
    error_scale_m: float  #: position error giving reward -1 [m]
    divergence_m: float  #: position error ending an episode [m]

    def sample_scenario(self, rng: np.random.Generator) -> Any:
        """Draw one scenario from the platform's scenario distribution."""
        ...

    def sample_scenarios(self, rngs: Sequence[np.random.Generator]) -> list[Any]:
        """``[self.sample_scenario(r) for r in rngs]``, the same draws (batched where it pays).

        Optional: a platform without it gets one :meth:`sample_scenario` call per episode.
        """
        ...

    def simulate(self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Any], T: int) -> Any:
        """Truth and sensor data of ``len(rngs)`` episodes of ``T`` steps (a NamedTuple)."""
        ...

    def initial_belief(self, episodes: Any) -> GaussianState:
        """The filter's prior at t = 0 (from data drawn in :meth:`simulate`)."""
        ...

    def step_models(self, episodes: Any, t: np.ndarray) -> StepModels:
        """Models and measurements for the step from ``t`` to ``t + 1`` (``t (B,)`` ints).

        It may advance per-episode cursors kept in ``episodes`` (e.g. a pointer into buffered
        sensor noise); a platform that does names those fields in an optional attribute
        ``episode_cursors: tuple[str, ...]`` so that the vector env's autoreset, which steps a
        freshly reset episode once and then restores it, restores them too.
        """
        ...

    def position_error(
        self, mean: np.ndarray, episodes: Any, t: np.ndarray, P: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Evaluation quantities at step ``t`` (truth allowed here; it goes to ``info`` only).

        Returns ``pos_err_m (B,)`` horizontal error, ``truth_pos``/``est_pos (B, 2)`` north/east
        [m], ``cov_ne (B, 2, 2)`` the estimate's north/east covariance, and ``state_err (B, n)``
        (estimate minus true state, for NEES) when the state has a truth.
        """
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


def replace_rows(target: Any, idx: np.ndarray, source: Any, inplace: bool = False) -> Any:
    """NamedTuple ``target`` with rows ``idx`` of its arrays replaced by ``source``'s rows.

    With ``inplace`` the writeable arrays of ``target`` are modified (no copy of the whole batch:
    the episode data the core owns); otherwise, or for read-only views, a copy is made. Fields
    that are not arrays with a leading episode axis (metadata) are taken from ``target``.
    """
    if target is None:
        return source
    out = []
    for a, b in zip(target, source, strict=True):
        if (
            isinstance(a, np.ndarray)
            and a.ndim >= 1
            and isinstance(b, np.ndarray)
            and b.shape[1:] == a.shape[1:]
        ):
            if not (inplace and a.flags.writeable):
                a = a.copy(order="K")  # keep the layout (e.g. a particle cloud's (B, n, N) buffer)
            a[idx] = b
        elif isinstance(a, tuple) and hasattr(a, "_fields"):
            a = replace_rows(a, idx, b, inplace)
        out.append(a)
    return type(target)(*out)


def take_rows(source: Any, idx: np.ndarray) -> Any:
    """NamedTuple with the rows ``idx`` of every array field (metadata kept)."""
    out = []
    for a in source:
        if isinstance(a, np.ndarray) and a.ndim >= 1:
            a = a[idx]
        elif isinstance(a, tuple) and hasattr(a, "_fields"):
            a = take_rows(a, idx)
        out.append(a)
    return type(source)(*out)
