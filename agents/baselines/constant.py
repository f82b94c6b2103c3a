"""The same action every step: the plain filter (the task's neutral action) or a fixed knob.

:class:`ConstantAction` has SB3's ``predict`` over batched observations like the baselines, and
reads nothing of them: ``ConstantAction(task.action_space, task.neutral_action(), "plain")`` is
the plain filter of any task, and a batch of different actions (one per sub-env) runs a whole
grid of constant knobs in one rollout. The studies use it where a task has no ``constant``
baseline of its own, and as the ``plain`` reference of every task.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

__all__ = ["ConstantAction"]


class ConstantAction:
    """The same action every step: ``(G, *shape)`` actions, one per sub-env (G = B) or one for all.

    Args:
        space: the task's action space (``Discrete`` actions are integers, Box ones float32).
        action: one action, or ``G`` of them stacked on a first axis.
        name: the label in tables and manifests.
    """

    is_baseline = True
    uses_truth = False

    def __init__(self, space: spaces.Space, action: Any, name: str = "constant action") -> None:
        self.name = name
        self.discrete = isinstance(space, spaces.Discrete)
        a = np.asarray(action)
        #: ``(G,)`` int64 (Discrete) or ``(G, *shape)`` float32 actions.
        self.actions: np.ndarray
        if self.discrete:
            self.actions = a.astype(np.int64).reshape(-1)
        else:
            shape = tuple(space.shape or ())
            self.actions = a.astype(np.float32).reshape(-1, *shape)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3's ``predict``: the constant action(s) for ``(B, d)`` or ``(d,)`` observations.

        One action is broadcast to the ``B`` rows; ``G`` actions need ``G == B``. ``state`` is
        returned as given (there is no memory).
        """
        obs = np.asarray(observation)
        if obs.ndim == 1:
            return self.actions[0].copy(), state
        B, G = obs.shape[0], self.actions.shape[0]
        if G not in (1, B):
            raise ValueError(f"{G} constant actions for a batch of {B}")
        return np.broadcast_to(self.actions, (B, *self.actions.shape[1:])).copy(), state

    def describe(self) -> dict[str, Any]:
        """Name, class and the action(s), for manifests."""
        a = self.actions[0] if len(self.actions) == 1 else self.actions
        return {
            "name": self.name,
            "class": f"{type(self).__module__}.{type(self).__qualname__}",
            "params": {"action": a.tolist()},
        }
