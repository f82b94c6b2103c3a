"""A loaded agent: a trained SB3 model whose ``predict`` takes the environment's raw observations.

:class:`TrainedAgent` wraps the model with what training put around it: the observation
normalization (:class:`agents.training.normalization.VecNormalizeStats`), the frame stack of a
``frame_stack`` agent (:class:`agents.policy_runner.FrameStack`, per episode), and the baseline
of a residual agent (:class:`agents.training.residual.ResidualRuntime`: base action computed,
appended when ``observe_base``, combined as ``clip(a_base + scale * a_res, low, high)``). Its
memory (frames, LSTM states, the baseline's) is in the ``state`` :meth:`TrainedAgent.predict`
returns. :func:`agents.training.loading.load_agent` builds it from an agent folder.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from agents.policy_runner import FrameStack, StackedState
from agents.training.config import frame_stack_of
from agents.training.normalization import VecNormalizeStats
from agents.training.residual import ResidualRuntime, ResidualState
from agents.training.sb3_archive import lstm_sizes
from agents.training.spaces import unstacked_space

__all__ = ["TrainedAgent"]


class TrainedAgent:
    """A trained SB3 model whose :meth:`predict` takes raw environment observations.

    Attributes:
        model: the stable-baselines3 model (its ``policy`` acts on normalized, and when
            ``frame_stack`` > 1 stacked, observations).
        normalizer: the saved observation normalization, or ``None``.
        algo, env_id, env_kwargs: from the run's ``config.yml`` when present.
        frame_stack: observations stacked per step (1: none).
        lstm: the recurrent policy's sizes (:func:`agents.training.sb3_archive.lstm_sizes`),
            ``None`` without memory.
        residual: a residual agent's baseline (:class:`agents.training.residual.ResidualRuntime`),
            ``None`` for a plain agent.
        observation_space: the environment's (raw, one frame), which :meth:`predict` takes.
        action_space: the environment's (the combined action's for a residual agent).
        path: the model archive.
        manifest: the checked ``manifest.json`` (``None`` for an agent loaded with ``trust``
            that has none).
    """

    def __init__(
        self,
        model: Any,
        normalizer: VecNormalizeStats | None,
        path: Path,
        info: dict[str, Any],
        manifest: dict[str, Any] | None = None,
        frame_stack: int = 1,
        observation_space: Any = None,
        residual: ResidualRuntime | None = None,
    ) -> None:
        self.model = model
        self.normalizer = normalizer
        self.path = path
        self.info = info
        self.manifest = manifest
        self.algo = info.get("algo")
        self.env_id = info.get("env_id")
        self.env_kwargs = dict(info.get("env_kwargs") or {})
        self.frame_stack = frame_stack_of(frame_stack)
        self.lstm = lstm_sizes(model)
        if observation_space is None:
            observation_space = unstacked_space(model.observation_space, self.frame_stack)
        #: One frame of what the model stacks (the env's observation, plus the base action of a
        #: residual agent with ``observe_base``).
        self.frame_space = observation_space
        self.residual = residual
        self.observation_space = residual.observation_space if residual is not None else observation_space
        self.action_space = residual.action_space if residual is not None else model.action_space
        self._stack = (
            FrameStack(self.frame_stack, observation_space.shape[0]) if self.frame_stack > 1 else None
        )

    @property
    def has_memory(self) -> bool:
        """Whether :meth:`predict`'s ``state`` carries memory (frames, LSTM states, a baseline's)."""
        return self._stack is not None or self.lstm is not None or self.residual is not None

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action(s) for raw observation(s) ``(n_obs,)`` or ``(B, n_obs)``; SB3's signature.

        An agent with memory keeps it in the returned ``state``: pass it back with the next
        step's observations, and ``episode_start`` True for the rows whose episode starts (their
        memory is reset; ``state=None`` starts every row afresh). A frame-stacked agent's state
        is a :class:`~agents.policy_runner.StackedState` (frames and the model's state), a
        RecurrentPPO's its LSTM states. A residual agent's is a
        :class:`~agents.training.residual.ResidualState` (the baseline's memory and the agent's
        own state) and its action ``clip(a_base + scale * a_res, low, high)``.
        :class:`agents.policy_runner.PredictRunner` does this.
        """
        obs = np.asarray(observation, dtype=np.float32)
        if obs.shape[-1:] != self.observation_space.shape:
            raise ValueError(
                f"observation must have shape {self.observation_space.shape} or (B, "
                f"{self.observation_space.shape[0]}); got {obs.shape}"
            )
        if self.residual is not None:
            return self._predict_residual(self.residual, obs, state, episode_start, deterministic)
        return self._predict_model(obs, state, episode_start, deterministic)

    def _predict_residual(
        self,
        residual: ResidualRuntime,
        obs: np.ndarray,
        state: Any,
        episode_start: np.ndarray | None,
        deterministic: bool,
    ) -> tuple[np.ndarray, Any]:
        single = obs.ndim == 1
        batch = obs.reshape(1, -1) if single else obs
        B = batch.shape[0]
        prev = state if isinstance(state, ResidualState) else None
        if prev is None:  # every row starts afresh (as the model's state None does)
            starts = np.ones(B, dtype=bool)
        elif episode_start is None:
            starts = np.zeros(B, dtype=bool)
        else:
            starts = np.asarray(episode_start, dtype=bool).reshape(B)
        base, base_state = residual.base(batch, None if prev is None else prev.base, starts)
        a_res, agent_state = self._predict_model(
            residual.model_obs(batch, base),
            None if prev is None else prev.agent,
            starts,
            deterministic,
        )
        actions = residual.combine(base, a_res)
        return (actions[0] if single else actions), ResidualState(base_state, agent_state)

    def _predict_model(
        self, obs: np.ndarray, state: Any, episode_start: np.ndarray | None, deterministic: bool
    ) -> tuple[np.ndarray, Any]:
        """The model's action for observations of :attr:`frame_space` (normalized, stacked here)."""
        if self.normalizer is not None:
            obs = self.normalizer(obs)
        if self._stack is None:
            return self.model.predict(
                obs, state=state, episode_start=episode_start, deterministic=deterministic
            )
        single = obs.ndim == 1
        batch = obs.reshape(1, -1) if single else obs
        prev = state if isinstance(state, StackedState) else None
        starts = None if episode_start is None else np.asarray(episode_start, dtype=bool).reshape(-1)
        frames = self._stack.push(None if prev is None else prev.frames, batch, starts)
        actions, model_state = self.model.predict(
            frames,
            state=None if prev is None else prev.model,
            episode_start=episode_start,
            deterministic=deterministic,
        )
        return (actions[0] if single else actions), StackedState(frames, model_state)

    def __repr__(self) -> str:
        norm = "normalized obs" if self.normalizer is not None else "raw obs"
        memory = f", {self.frame_stack} frames" if self.frame_stack > 1 else ""
        memory += f", LSTM {self.lstm['lstm_hidden_size']}" if self.lstm else ""
        if self.residual is not None:
            memory += f", residual on {self.residual.spec.baseline} x {self.residual.spec.scale:g}"
        return f"TrainedAgent({self.algo}, {self.env_id}, {norm}{memory}, {self.path})"
