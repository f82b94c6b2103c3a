"""Robust-threshold baselines (``*Robust-v2`` envs): the threshold of the robust iterated EKF.

The Robust task (:class:`navgym.envs.tasks.RobustTask`) sets the threshold ``c`` of the Huber or
Tukey weights of :func:`filters.robust.iterated_update` (Belles et al. 2022, eq. 20, Algorithm
1) each step; ``c = inf`` is the plain iterated EKF. The task's ``action_of`` inverts its
mapping (``c >= c_hi`` of its ``threshold_range``: the plain filter).

Baselines:

* :class:`ConstantThreshold` (``plain`` with ``c = 1e9``, i.e. ``inf``: the plain I-ESKF;
  ``constant``: a tuned constant ``c``);
* :class:`SeedThreshold` (``seed``): Belles et al. 2022's 95 %-efficiency constants, ``c = 1.345``
  with Huber weights, ``4.685`` with Tukey (Table 1; the env's ``weight``);
* :class:`ChiSquareThreshold` (``chi_square``): chi-square exclusion. The observed NIS of the
  last update (the plain update's, ``NIS = n (exp(log_nis) - 1)`` with ``n`` the rows used) is
  tested against the chi-square ``1 - alpha`` quantile with ``n`` degrees of freedom; while it
  fails (and ``hold`` steps after) the next update runs with the low threshold ``c_low``, which
  down-weights (Huber) or excludes (Tukey) the rows with large whitened residuals; otherwise the
  plain update (``c = inf``). The test of step k acts at step k + 1: it catches persistent
  faults (a cycle slip or a multipath segment lasts tens of steps).

Every baseline reads the observation only (no truth).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from agents.baselines.base import BaselinePolicy
from filters.robust import DEFAULT_THRESHOLDS
from navgym.envs.base import NavigationAPI

__all__ = ["ChiSquareThreshold", "ConstantThreshold", "RobustBaseline", "SeedThreshold"]


class RobustBaseline(BaselinePolicy):
    """Base of the robust-threshold baselines: ``c (B,)`` mapped to the action."""

    task = "Robust"

    def setup(self, env: NavigationAPI) -> None:
        self.robust_task = env.task
        self.m = int(self.features.index("innovation").stop - self.features.index("innovation").start)

    def threshold(self, obs: np.ndarray, memory: dict, fresh: np.ndarray) -> tuple[np.ndarray, dict]:
        """``c (B,)`` (``inf``: plain) and the new memory."""
        raise NotImplementedError

    def act(self, obs, memory, fresh):
        c, memory = self.threshold(obs, memory, fresh)
        return self.robust_task.action_of(c), memory


class ConstantThreshold(RobustBaseline):
    """The same threshold ``c`` every step (``c >= c_hi``, e.g. ``1e9``: the plain I-ESKF)."""

    name = "constant"
    defaults = {"c": 1.345}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        if (self.params["c"] <= 0).any():
            raise ValueError("c must be > 0")

    def threshold(self, obs, memory, fresh):
        return self.param("c", obs.shape[0]), memory


class SeedThreshold(RobustBaseline):
    """Belles et al. 2022's constant: 1.345 (Huber) or 4.685 (Tukey), the env's weight function."""

    name = "seed"
    defaults: dict[str, float] = {}

    def threshold(self, obs, memory, fresh):
        return np.full(obs.shape[0], DEFAULT_THRESHOLDS[self.robust_task.weight]), memory


class ChiSquareThreshold(RobustBaseline):
    """Chi-square exclusion: ``c_low`` while the NIS test fails (and ``hold`` steps after), else plain."""

    name = "chi_square"
    defaults = {"alpha": 0.01, "c_low": 1.345, "hold": 0.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        a = self.params["alpha"]
        if (
            ((a <= 0) | (a >= 1)).any()
            or (self.params["c_low"] <= 0).any()
            or (self.params["hold"] < 0).any()
        ):
            raise ValueError("alpha must lie in (0, 1), c_low > 0 and hold >= 0")

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"left": np.zeros(B)}

    def threshold(self, obs, memory, fresh):
        B = obs.shape[0]
        n = np.round(self.col(obs, "rows_used") * self.m)
        nis = n * np.expm1(self.col(obs, "log_nis"))
        q = chi2.ppf(1.0 - self.param("alpha", B), np.maximum(n, 1))
        fail = (n > 0) & (nis > q) & ~fresh
        left = np.where(fail, self.param("hold", B) + 1.0, np.maximum(memory["left"] - 1.0, 0.0))
        c = np.where(left > 0, self.param("c_low", B), np.inf)
        return c, {"left": left}
