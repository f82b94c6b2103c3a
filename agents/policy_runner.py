"""The one seam between a policy and the loops that step it: :class:`PolicyRunner`.

A loop that steps a batch of ``B`` episodes (the evaluation rollout, the training sanity check)
does not call a policy's ``predict`` itself; it holds a :class:`PolicyRunner` and calls

* ``reset(rows)`` when episodes start: ``reset()`` (all rows) after the env's reset, and
  ``reset(done)`` for the rows an autoresetting env restarted;
* ``act(obs)`` once per step, with the ``(B, d)`` observations, for the ``(B, ...)`` actions.

:class:`PredictRunner` runs anything with SB3's ``predict(obs, state, episode_start,
deterministic)``: it carries the state ``predict`` returns to the next step (a RecurrentPPO's
LSTM states, a baseline's per-episode memory, a frame-stacked agent's frames) and passes
``episode_start`` True for exactly the rows reset since the previous step, so every row's memory
starts afresh with its episode and no other. :class:`CallableRunner` runs a memoryless
``obs -> actions`` function. :class:`FrameStack` is the per-row observation stack of SB3's
``VecFrameStack`` (zeros before an episode's first step), for agents trained with
``frame_stack``.

What a loop may know of a policy is typed here too: :class:`Predictor` (SB3's ``predict``),
:class:`ResettablePolicy` (memory kept inside, forgotten by ``reset()``), and
:class:`DescribedPolicy` (the baselines, oracles and constant actions, which say whether they
read the truth and whether they are baselines); :func:`policy_kind` sorts any policy by them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal, NamedTuple, Protocol, runtime_checkable

import numpy as np

__all__ = [
    "CallableRunner",
    "DescribedPolicy",
    "FrameStack",
    "PolicyKind",
    "PolicyRunner",
    "PredictRunner",
    "Predictor",
    "ResettablePolicy",
    "StackedState",
    "policy_kind",
]

#: What a policy is in an evaluation: a truth-reading reference, a classical baseline, or an agent.
PolicyKind = Literal["oracle", "baseline", "agent"]


@runtime_checkable
class Predictor(Protocol):
    """Anything with SB3's ``predict``: baselines, SB3 / sb3-contrib models, trained agents."""

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Actions for ``observation`` and the state to pass back with the next step's."""
        ...


@runtime_checkable
class ResettablePolicy(Predictor, Protocol):
    """A :class:`Predictor` that also keeps its memory inside; ``reset()`` forgets it."""

    def reset(self) -> None:
        """Forget the internal memory (the next ``predict`` starts fresh episodes)."""
        ...


@runtime_checkable
class DescribedPolicy(Predictor, Protocol):
    """A policy that says what it is: the baselines, the oracles, a constant action.

    Attributes:
        is_baseline: a classical baseline (the paired comparisons' default reference is the
            best of them); False for an oracle.
        uses_truth: reads the truth (an oracle: an optimistic reference, never a baseline).
    """

    is_baseline: bool
    uses_truth: bool

    def describe(self) -> dict[str, Any]:
        """Name, class and parameters, for manifests."""
        ...


def policy_kind(policy: Any) -> PolicyKind:
    """``"oracle"`` (reads truth), ``"baseline"`` or ``"agent"`` (anything else, e.g. SB3 models)."""
    if not isinstance(policy, DescribedPolicy):
        return "agent"
    if policy.uses_truth:
        return "oracle"
    return "baseline" if policy.is_baseline else "agent"


@runtime_checkable
class PolicyRunner(Protocol):
    """A policy stepped over a batch of episodes, with its per-episode memory kept inside."""

    def reset(self, rows: np.ndarray | None = None) -> None:
        """Episodes start in ``rows`` (a ``(B,)`` boolean mask or indices; ``None``: every row)."""
        ...

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Actions ``(B, ...)`` for the observations ``(B, d)`` of this step."""
        ...


class PredictRunner:
    """:class:`PolicyRunner` of an SB3-style ``predict`` policy (state carried, reset per row).

    Args:
        policy: anything with ``predict(obs, state=, episode_start=, deterministic=)`` that
            returns ``(actions, state)``: baselines, SB3 / sb3-contrib models, trained agents.
        deterministic: passed to ``predict``.
    """

    def __init__(self, policy: Any, deterministic: bool = True) -> None:
        self.policy = policy
        self.deterministic = bool(deterministic)
        self.state: Any = None
        self._starts: np.ndarray | None = None  # None: every row starts at the next act

    def reset(self, rows: np.ndarray | None = None) -> None:
        if rows is None:
            self.state, self._starts = None, None
            return
        if self._starts is None:  # every row starts anyway
            return
        rows = np.asarray(rows)
        if rows.dtype == bool:
            self._starts |= rows.reshape(self._starts.shape)
        else:
            self._starts[rows.astype(np.int64)] = True

    def act(self, obs: np.ndarray) -> np.ndarray:
        B = int(np.shape(obs)[0])
        starts = np.ones(B, dtype=bool) if self._starts is None else self._starts
        if starts.shape != (B,):
            raise ValueError(f"the runner was reset for {starts.shape[0]} rows; got {B} observations")
        actions, self.state = self.policy.predict(
            obs, state=self.state, episode_start=starts.copy(), deterministic=self.deterministic
        )
        self._starts = np.zeros(B, dtype=bool)
        return actions


class CallableRunner:
    """:class:`PolicyRunner` of a memoryless ``obs (B, d) -> actions`` function."""

    def __init__(self, fn: Callable[[np.ndarray], np.ndarray]) -> None:
        self.fn = fn

    def reset(self, rows: np.ndarray | None = None) -> None:
        return None

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.fn(obs)


class StackedState(NamedTuple):
    """The ``predict`` state of a frame-stacked agent: its frames and the model's own state."""

    frames: np.ndarray  # (B, n_stack * d) the last n_stack (normalized) observations, oldest first
    model: Any  # the model's state (a RecurrentPPO's LSTM states) or None


class FrameStack:
    """SB3 ``VecFrameStack``'s stacking of flat observations, one stack per row.

    At an episode's first step its row is zeros but for the newest frame; each step shifts the
    frames by one observation (oldest dropped) and writes the new one last.
    """

    def __init__(self, n_stack: int, obs_dim: int) -> None:
        if int(n_stack) < 1:
            raise ValueError(f"n_stack must be >= 1; got {n_stack}")
        self.n_stack = int(n_stack)
        self.obs_dim = int(obs_dim)

    def push(self, frames: np.ndarray | None, obs: np.ndarray, starts: np.ndarray | None) -> np.ndarray:
        """The new ``(B, n_stack * d)`` frames after ``obs (B, d)`` (``frames`` is not changed).

        ``frames`` ``None`` (or of another batch size) starts every row afresh; rows whose
        ``starts`` is True start afresh.
        """
        obs = np.asarray(obs, dtype=np.float32)
        B, d = obs.shape[0], self.obs_dim
        if obs.shape != (B, d):
            raise ValueError(f"observations must have shape (B, {d}); got {obs.shape}")
        if frames is None or np.shape(frames) != (B, self.n_stack * d):
            out = np.zeros((B, self.n_stack * d), dtype=np.float32)
        else:
            out = np.roll(np.asarray(frames, dtype=np.float32), -d, axis=-1)
            if starts is not None:
                out[np.asarray(starts, dtype=bool).reshape(B)] = 0.0
        out[:, -d:] = obs
        return out
