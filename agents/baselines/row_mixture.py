"""Per-row mixture baselines (``*Mixture-v2`` envs, ``MixtureTask(per_row=True)``), from observations.

The per-row Mixture task takes one action per measurement row, ``eps_i = eps_max (a_i + 1) / 2``
on the platform's outlier rows (0 on the others), applied by the sequential per-row mixture
update :func:`filters.row_mixture.update`. :func:`row_eps_to_action` inverts the mapping.

**What the baselines read.** The ``innovation`` column holds each received row's normalized
innovation ``z_i = v_i / sqrt(S_i)`` (0 where not received) with ``S_i`` the row's *mixture*
predictive variance under the weight ``eps_prev,i`` the policy applied at that step (read from
``previous_action``), ``S_i = H P H^T + (1 + eps_prev,i (ratio - 1)) R_ii`` (eq. 73 moments).
Assuming ``H P H^T << R`` it is brought back to the nominal scale,
``z_nom,i = z_i sqrt(1 + eps_prev,i (ratio - 1))`` (as
:class:`agents.baselines.mixture.InnovationContamination` does), so that flagging a row does
not hide its fault at the next step. The ``innovation_avg`` memory column (10 s average of
``z_i``) is de-normalized the same way with the current ``eps_prev,i`` (exact when the weight
was constant over the average's memory; an approximation otherwise). Only the task's outlier
rows get a weight.

**Timing.** The weights chosen from step k's innovations apply at step k + 1: the tests here
catch *persistent* faults (a multipath bias, a bad satellite for a while), not a single
step's impulsive outlier (that one is the filter's job; a constant eps covers it). The reset
observation gets ``eps_low`` (``constant``: its eps).

Baselines:

* :class:`RowConstant` (``constant``; ``zero`` with eps = 0): one eps for every outlier row.
* :class:`RowChiSquare` (``chi_square``): RAIM-like chi-square test and exclusion
  (:func:`filters.innovation_adaptive.chi_square_exclusion` on ``z_nom`` with ``S = I``): rows
  it excludes get ``eps_max``, the others ``eps_low``; optional hold ``decay``.
* :class:`RowInnovationAverage` (``innovation_avg``): ``eps_i`` rises with the de-normalized
  per-row innovation average ``|avg_i|`` beyond ``threshold`` (a persistent bias).
* :class:`RowHuber` (``huber``): Huber-type smooth weight from an exponential average of
  ``z_nom^2`` per row: the variance inflation ``max(1, rms / k)`` matched by the mixture.
"""

from __future__ import annotations

import numpy as np

from agents.baselines.base import BaselinePolicy
from filters.innovation_adaptive import chi_square_exclusion
from navgym.envs.base import NavigationAPI
from navgym.envs.tasks import MixtureTask

__all__ = [
    "RowChiSquare",
    "RowConstant",
    "RowHuber",
    "RowInnovationAverage",
    "RowMixtureBaseline",
    "row_eps_to_action",
]


def row_eps_to_action(eps: np.ndarray, eps_max: float) -> np.ndarray:
    """``a_i = 2 eps_i / eps_max - 1`` clipped to [-1, 1], ``(B, m)`` float32."""
    a = 2.0 * np.asarray(eps, dtype=np.float64) / eps_max - 1.0
    return np.clip(a, -1.0, 1.0).astype(np.float32)


class RowMixtureBaseline(BaselinePolicy):
    """Base of the per-row mixture baselines: ``eps (B, m)`` mapped to the action."""

    task = "Mixture"

    def setup(self, env: NavigationAPI) -> None:
        task = env.task
        if not (isinstance(task, MixtureTask) and task.per_row):
            raise ValueError(f"{type(self).__name__} serves per-row Mixture tasks (v2, per_row=True)")
        self.eps_max = float(task.eps_max)
        self.variance_ratio = float(task.variance_ratio)
        self.m = int(task.m_max)
        #: (m,) True on the rows the outlier component may inflate.
        self.outlier = np.asarray(task.row_weights, dtype=np.float64) > 0

    def contamination(self, obs: np.ndarray, memory: dict, fresh: np.ndarray) -> tuple[np.ndarray, dict]:
        """``eps (B, m)`` and the new memory."""
        raise NotImplementedError

    def act(self, obs, memory, fresh):
        eps, memory = self.contamination(obs, memory, fresh)
        eps = np.where(self.outlier[None, :], np.clip(eps, 0.0, self.eps_max), 0.0)
        return row_eps_to_action(eps, self.eps_max), memory

    # ---------------------------------------------------------------------------- helpers
    def inflation(self, obs: np.ndarray) -> np.ndarray:
        """``sqrt(1 + eps_prev,i (ratio - 1))`` ``(B, m)`` from ``previous_action``."""
        a_prev = self.block(obs, "previous_action")
        eps_prev = np.clip(self.eps_max * (a_prev + 1.0) / 2.0, 0.0, 1.0) * self.outlier[None, :]
        return np.sqrt(1.0 + eps_prev * (self.variance_ratio - 1.0))

    def z_nominal(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """De-normalized innovations ``z_nom (B, m)`` and the received outlier rows ``(B, m)``."""
        z = self.block(obs, "innovation")
        used = (z != 0.0) & self.outlier[None, :]
        return z * self.inflation(obs), used

    def _check_eps(self, *keys: str) -> None:
        for k in keys:
            if (self.params[k] < 0).any():
                raise ValueError(f"{k} must be >= 0")


class RowConstant(RowMixtureBaseline):
    """The same constant ``eps`` on every outlier row (``eps = 0``: the plain base filter)."""

    name = "constant"
    defaults = {"eps": 0.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        self._check_eps("eps")

    def contamination(self, obs, memory, fresh):
        B = obs.shape[0]
        return np.repeat(self.param("eps", B)[:, None], self.m, axis=1), memory


class RowChiSquare(RowMixtureBaseline):
    """RAIM-like chi-square test of the rows' normalized innovations; failing rows get ``eps_max``.

    Each step with measurements: :func:`filters.innovation_adaptive.chi_square_exclusion` of
    the de-normalized innovations ``z_nom`` (module docstring) of the received outlier rows with
    ``S = I`` (they are already normalized): the NIS ``sum z_nom,i^2`` is tested against the
    chi-square ``1 - alpha`` quantile with ``n`` degrees of freedom, and while it fails the row
    with the largest ``z_nom^2`` is excluded (at most ``max_exclusions``, one row always kept).
    Excluded rows are flagged: ``f_i = 1``; otherwise ``f_i = decay f_i,prev`` (``decay = 0``:
    no memory; a hold keeps a fault's weight up for ``~1 / (1 - decay)`` steps). Then::

        eps_i = eps_low + (eps_max - eps_low) f_i

    Steps without measurements keep ``f``. Parameters: ``alpha`` in (0, 1), ``eps_low >= 0``,
    ``decay`` in [0, 1), ``max_exclusions`` (integer >= 0).
    """

    name = "chi_square"
    defaults = {"alpha": 0.01, "eps_low": 0.0, "decay": 0.0, "max_exclusions": 2.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        a, d = self.params["alpha"], self.params["decay"]
        if ((a <= 0) | (a >= 1)).any() or ((d < 0) | (d >= 1)).any():
            raise ValueError("alpha must lie in (0, 1) and decay in [0, 1)")
        self._check_eps("eps_low", "max_exclusions")

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"f": np.zeros((B, self.m))}

    def flags(self, obs: np.ndarray) -> np.ndarray:
        """``(B, m)`` rows excluded by the chi-square test this step."""
        return self._flags(*self.z_nominal(obs))

    def _flags(self, z: np.ndarray, used: np.ndarray) -> np.ndarray:
        """:meth:`flags` of the de-normalized innovations ``z (B, m)`` and their rows ``used``.

        One test call with each episode's ``alpha`` and ``max_exclusions``, on the innovations
        whitened (``S = I``).
        """
        kmax = np.round(self.params["max_exclusions"]).astype(np.int64)
        return chi_square_exclusion(z, None, used, alpha=self.params["alpha"], max_exclusions=kmax).excluded

    def contamination(self, obs, memory, fresh):
        B = obs.shape[0]
        z, used = self.z_nominal(obs)
        flagged = self._flags(z, used)
        step = used.any(axis=1) & ~fresh
        f = np.where(flagged, 1.0, self.param("decay", B)[:, None] * memory["f"])
        f = np.where(step[:, None], f, memory["f"])
        lo = self.param("eps_low", B)[:, None]
        return lo + (self.eps_max - lo) * f, {"f": f}


class RowInnovationAverage(RowMixtureBaseline):
    """Per-row weight from the ``innovation_avg`` memory column: a persistent bias gets outlier weight.

    ``m_i = |innovation_avg_i| sqrt(1 + eps_prev,i (ratio - 1))`` (de-normalized; module
    docstring). A consistent row averages to ``~0`` (the 10 s average of ~10-100 unit
    innovations has a standard deviation ~0.1-0.3); a bias of ``b`` sigma shows as ``m ~ b``::

        eps_i = eps_low + (eps_max - eps_low) clip(gain (m_i - threshold), 0, 1)

    (``gain`` large: a hard threshold.) Parameters: ``threshold >= 0``, ``gain > 0``, ``eps_low >= 0``.
    """

    name = "innovation_avg"
    defaults = {"threshold": 0.5, "gain": 2.0, "eps_low": 0.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        self._check_eps("threshold", "eps_low")
        if (self.params["gain"] <= 0).any():
            raise ValueError("gain must be > 0")

    def contamination(self, obs, memory, fresh):
        B = obs.shape[0]
        m = np.abs(self.block(obs, "innovation_avg")) * self.inflation(obs)
        u = np.clip(self.param("gain", B)[:, None] * (m - self.param("threshold", B)[:, None]), 0.0, 1.0)
        u = np.where(fresh[:, None], 0.0, u)
        lo = self.param("eps_low", B)[:, None]
        return lo + (self.eps_max - lo) * u, memory


class RowHuber(RowMixtureBaseline):
    """Huber-type smooth per-row weight from an exponential average of ``z_nom^2``.

    Per row, ``w_i <- (1 - alpha) w_i + alpha z_nom,i^2`` on the steps that received it (from
    1 at the start). Huber's M-estimator down-weights a residual of ``rms`` sigma beyond ``k`` by
    the factor ``k / rms``, i.e. inflates its variance by ``(rms / k)^2``; the mixture's average
    inflation ``1 + eps (ratio - 1)`` matches it with::

        eps_i = eps_low + clip(((sqrt(w_i) / k)^2 - 1) / (ratio - 1), 0, eps_max)

    a smooth weight, 0 (plus ``eps_low``) while the row's rms stays below ``k``. Parameters:
    ``k > 0``, ``alpha`` in (0, 1], ``eps_low >= 0``.
    """

    name = "huber"
    defaults = {"k": 1.5, "alpha": 0.2, "eps_low": 0.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        a = self.params["alpha"]
        if (self.params["k"] <= 0).any() or ((a <= 0) | (a > 1)).any():
            raise ValueError("k must be > 0 and alpha in (0, 1]")
        self._check_eps("eps_low")

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"w": np.ones((B, self.m))}

    def contamination(self, obs, memory, fresh):
        B = obs.shape[0]
        z, used = self.z_nominal(obs)
        used = used & ~fresh[:, None]
        a = self.param("alpha", B)[:, None]
        w = np.where(used, (1.0 - a) * memory["w"] + a * z * z, memory["w"])
        k = self.param("k", B)[:, None]
        infl = w / (k * k)
        eps = self.param("eps_low", B)[:, None] + np.clip(
            (infl - 1.0) / (self.variance_ratio - 1.0), 0.0, self.eps_max
        )
        return eps, {"w": w}
