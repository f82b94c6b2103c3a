"""Jump-prior baselines (``SignalTrackingJumps-v2``): the jump probability of the random Dirac-Gauss PF.

The Jumps task (:class:`navgym.signal_tracking.task.JumpsTask`) sets the probability ``p`` that
each particle draws an acceleration jump in a code period, held over the env step; its
``action_of`` inverts the mapping (clipped into its ``jump_range``).

Baselines:

* :class:`ConstantJump` (``plain``: the nominal ``p = 2e-3``, 2 jumps per second; ``constant``: a
  tuned constant ``p``);
* :class:`LikelihoodJump` (``likelihood``): a jump detector on the filter's own likelihood, the
  classical reaction to a manoeuvre: when the step's mean log-likelihood per code period (the
  observation's ``mean_log_likelihood``) falls below ``threshold``, the next ``hold + 1`` steps run
  with ``p_high`` (particles spread over the jump hypotheses to catch the manoeuvre), the others
  with ``p_low``. The test of step k acts from step k + 1 (a detector cannot anticipate).

The deterministic Dirac-Gauss PF of the study (N = 144, every particle branched over 11 jump
hypotheses) is not a baseline here: it is a different filter, not a setting of this one, and it
costs about 50 times the task's filter per code period (``experiments.dirac_gauss`` compares the
two filters).

Every baseline reads the observation only (no truth).
"""

from __future__ import annotations

import numpy as np

from agents.baselines.base import BaselinePolicy
from navgym.envs.base import NavigationAPI

__all__ = ["ConstantJump", "JumpBaseline", "LikelihoodJump"]


class JumpBaseline(BaselinePolicy):
    """Base of the jump-prior baselines: ``p (B,)`` mapped to the action."""

    task = "Jumps"

    def setup(self, env: NavigationAPI) -> None:
        self.jump_task = env.task

    def probability(self, obs: np.ndarray, memory: dict, fresh: np.ndarray) -> tuple[np.ndarray, dict]:
        """``p (B,)`` and the new memory."""
        raise NotImplementedError

    def act(self, obs, memory, fresh):
        p, memory = self.probability(obs, memory, fresh)
        return self.jump_task.action_of(p), memory


class ConstantJump(JumpBaseline):
    """The same jump probability ``p`` every step (``2e-3``: the plain filter)."""

    name = "constant"
    defaults = {"p": 2e-3}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        if ((self.params["p"] <= 0) | (self.params["p"] > 1)).any():
            raise ValueError("p must lie in (0, 1]")

    def probability(self, obs, memory, fresh):
        return self.param("p", obs.shape[0]), memory


class LikelihoodJump(JumpBaseline):
    """``p_high`` for ``hold + 1`` steps once the mean log-likelihood < ``threshold``, else ``p_low``."""

    name = "likelihood"
    defaults = {"threshold": -10.5, "p_high": 0.02, "p_low": 2e-3, "hold": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        p = self.params
        if (
            ((p["p_high"] <= 0) | (p["p_high"] > 1)).any()
            or ((p["p_low"] <= 0) | (p["p_low"] > 1)).any()
            or (p["hold"] < 0).any()
        ):
            raise ValueError("p_high and p_low must lie in (0, 1], hold >= 0")

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"left": np.zeros(B)}

    def probability(self, obs, memory, fresh):
        B = obs.shape[0]
        fire = (self.col(obs, "mean_log_likelihood") < self.param("threshold", B)) & ~fresh
        left = np.where(fire, self.param("hold", B) + 1.0, np.maximum(memory["left"] - 1.0, 0.0))
        p = np.where(left > 0, self.param("p_high", B), self.param("p_low", B))
        return p, {"left": left}
