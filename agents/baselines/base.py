"""Common machinery of the baseline policies: SB3's ``predict`` over batched observations.

A baseline is built from an environment (single, native vector, SB3 adapter, or an env id), from
which it reads only the *layout* of the observation (feature columns by name) and the task's
action mapping; at run time it reads only observations, never ``info`` or truth. Per-episode
memory (fading-memory innovation covariances, running contamination estimates) lives in a dict of
``(B, ...)`` arrays that :meth:`BaselinePolicy.predict` returns as SB3's ``state`` and also keeps
internally, so callers may either pass the state back (as SB3's ``evaluate_policy`` does) or
call ``predict(obs)`` step after step; rows whose ``episode_start`` is True are reset.

Parameters may be scalars or ``(B,)`` arrays (one value per sub-environment): the grid searches of
:mod:`agents.tuning` run a whole parameter grid as one batched rollout that way.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from navgym.envs.base import NavigationAPI, navigation_env

__all__ = ["BaselinePolicy", "navigation_env", "task_name"]


def task_name(env: Any) -> str:
    """The task of ``env``: ``"Fading"``, ``"Mixture"`` or ``"Resample"``."""
    return str(navigation_env(env).task.name)


class BaselinePolicy:
    """Base class: a hand-tuned policy with SB3's ``predict`` (subclasses implement :meth:`act`).

    Class attributes of subclasses:
        name: registry name (also the label in evaluation tables).
        task: the task it serves (``"Fading" | "Mixture" | "Resample"``).
        defaults: parameter names and default values.
        is_baseline: True (the oracle sets False: it is a reference, not a baseline to beat).
    """

    name: str = "baseline"
    task: str = ""
    defaults: dict[str, float] = {}
    is_baseline: bool = True
    uses_truth: bool = False
    #: Observation features it reads besides the filter's statistics (a receiver's or an IMU's
    #: context, v3); an env whose observation lacks one has no such baseline.
    context: tuple[str, ...] = ()

    def __init__(self, env: Any, **params: Any) -> None:
        nav = navigation_env(env)
        if self.task and nav.task.name != self.task:
            raise ValueError(f"{type(self).__name__} serves {self.task} tasks; env has task {nav.task.name}")
        unknown = set(params) - set(self.defaults)
        if unknown:
            from navgym.envs.arguments import UnknownKeywordError

            raise UnknownKeywordError(
                f"{type(self).__name__} got unknown parameters {sorted(unknown)}; has {sorted(self.defaults)}"
            )
        self.features = nav.observation_features
        self.obs_dim = int(nav.observation_features.dim)
        self.action_space = nav.task.action_space
        self.params: dict[str, np.ndarray] = {}
        for k, default in self.defaults.items():
            v = np.asarray(params.get(k, default), dtype=np.float64)
            if v.ndim > 1 or not np.isfinite(v).all():
                raise ValueError(f"parameter {k} must be a finite scalar or (B,) array; got {v!r}")
            self.params[k] = v
        self._memory: dict[str, np.ndarray] | None = None
        self.setup(nav)

    # ------------------------------------------------------------------------- to override
    def setup(self, env: NavigationAPI) -> None:
        """Read what the policy needs from the env's public API (columns, knob range)."""

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        """Fresh per-episode memory for ``B`` episodes (default: none)."""
        return {}

    def act(
        self, obs: np.ndarray, memory: dict[str, np.ndarray], fresh: np.ndarray
    ) -> tuple[np.ndarray, dict]:
        """Actions ``(B, ...)`` and the new memory from observations ``(B, d)`` (float64).

        ``fresh (B,)`` marks episodes whose observation is the reset observation (no measurement
        processed yet); the fading and contamination estimators do not absorb it.
        """
        raise NotImplementedError

    # ---------------------------------------------------------------------------- helpers
    def param(self, key: str, B: int) -> np.ndarray:
        """Parameter ``key`` broadcast to ``(B,)``."""
        v = self.params[key]
        if v.ndim == 1 and v.shape[0] != B:
            raise ValueError(f"parameter {key} has {v.shape[0]} values; the batch has {B} episodes")
        return np.broadcast_to(v, (B,))

    def col(self, obs: np.ndarray, name: str) -> np.ndarray:
        """Feature ``name`` of ``obs (B, d)``: ``(B,)`` for a scalar feature, else ``(B, size)``."""
        x = obs[:, self.features.index(name)]
        return x[:, 0] if x.shape[1] == 1 else x

    def block(self, obs: np.ndarray, name: str) -> np.ndarray:
        """Feature ``name`` of ``obs (B, d)`` as ``(B, size)`` (always two-dimensional)."""
        return obs[:, self.features.index(name)]

    def describe(self) -> dict[str, Any]:
        """Name, class and parameters (scalars as floats, arrays as lists) for manifests."""
        return {
            "name": self.name,
            "class": f"{type(self).__module__}.{type(self).__qualname__}",
            "params": {k: (v.item() if v.ndim == 0 else v.tolist()) for k, v in self.params.items()},
            "uses_truth": self.uses_truth,
        }

    def reset(self) -> None:
        """Forget the internal memory (the next :meth:`predict` starts fresh episodes)."""
        self._memory = None

    # -------------------------------------------------------------------------------- SB3
    def predict(
        self,
        observation: np.ndarray,
        state: dict[str, np.ndarray] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """SB3's ``predict``: actions for ``observation (B, d)`` or ``(d,)`` and the new state.

        Args:
            observation: batched ``(B, d)`` or single ``(d,)`` observations.
            state: the memory returned by the previous call, or None to use the internal one
                (a fresh one when there is none or its batch size differs).
            episode_start: ``(B,)`` booleans, True where an episode starts (memory reset).
            deterministic: ignored (the baselines are deterministic).

        Returns:
            ``(actions, state)``: ``(B, 1)`` float32 for Box tasks (``(1,)`` for a single
            observation), ``(B,)`` int64 for ``Discrete`` (a 0-d array for a single one).
        """
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        obs = obs.reshape(-1, self.obs_dim) if single else obs
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(
                f"observation must have shape (B, {self.obs_dim}) or ({self.obs_dim},); got {obs.shape}"
            )
        B = obs.shape[0]
        memory = state if state is not None else self._memory
        fresh = np.zeros(B, dtype=bool)
        if memory is None or _batch_of(memory) not in (None, B):
            memory = self.init_memory(B)
            fresh[:] = True
        memory = {k: np.array(v, copy=True) for k, v in memory.items()}
        if episode_start is not None:
            starts = np.asarray(episode_start, dtype=bool).reshape(B)
            if starts.any():
                init = self.init_memory(B)
                for k in memory:
                    memory[k][starts] = init[k][starts]
                fresh |= starts
        actions, memory = self.act(obs, memory, fresh)
        self._memory = memory
        if single:
            actions = actions[0]
        return actions, memory


def _batch_of(memory: dict[str, np.ndarray]) -> int | None:
    for v in memory.values():
        return int(np.shape(v)[0])
    return None
