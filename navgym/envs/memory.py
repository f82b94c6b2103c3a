"""Memory in the observation: innovation statistics averaged over past steps (opt-in, v2).

A knob has value where the filter's model goes wrong inside the episode (a process-noise burst,
a multipath bias on one satellite, a jamming ramp) and that shows in what the filter sees; one
step's innovations are too noisy to tell, a few seconds of them are not. With
``memory_features=True`` (a core argument, default False: the v0/v1 observations are unchanged)
:class:`~navgym.envs.core.NavCore` appends these columns to the observation, computed from the
filter's update diagnostics only (estimator side, no truth):

* ``log_nis_avg_<tau>s``, one per time constant ``tau`` of :data:`TIME_CONSTANTS_S` (1 s, 10 s):
  the exponentially weighted average of ``x_k = log(1 + NIS_k / rows_k)`` (the ``log_nis``
  column) over the steps that used a measurement, ``avg = s / w`` with
  ``s <- (1 - alpha) s + alpha x_k`` and ``w <- (1 - alpha) w + alpha`` on those steps,
  ``alpha = 1 - exp(-dt / tau)`` from the platform's step ``dt``. Steps without a measurement
  (an outage) leave both unchanged; the weight ``w`` makes the average that of the values seen
  so far from the first one on (no start-up transient toward 0), and 0 before any. In [0, 10].
* ``innovation_avg`` ``(m_max,)``: per row, the same average (time constant ``tau`` the longest
  of :data:`TIME_CONSTANTS_S`) of the row's normalized innovation ``v_i / sqrt(S_ii)`` clipped to
  [-10, 10] (the ``innovation`` column), over the steps that received the row; 0 before its
  first. A persistent non-zero mean is a bias of that row. In [-10, 10].
* ``innovation_whiteness``: the lag-1 autocorrelation of the normalized innovations over the
  last :data:`WINDOW_STEPS` steps, pooled over the rows, uncentred::

      r = sum c_k / sqrt(sum a_k sum b_k),  c_k = sum_i y_ik y_i,k-1,  a_k = sum_i y_ik^2,
      b_k = sum_i y_i,k-1^2

  over the rows ``i`` received at both steps k - 1 and k (``y`` the clipped normalized
  innovation), 0 where there is no such pair. In [-1, 1] (Cauchy-Schwarz). A consistent filter's
  innovations are white (``r ~ 0``); too small a gain or a bias makes them correlated (``r > 0``),
  too large a gain anti-correlated (``r < 0``): Mehra 1970's whiteness test.

The per-episode memory (:class:`MemoryState`) is reset with the episode and is part of the
core's :meth:`~navgym.envs.core.NavCore.snapshot` / ``restore`` (the vector env's autoreset,
the evaluation's episode stepper), so sub-env ``i`` of a vector env equals a single env seeded
``s + i`` with memory too. Bias estimates from the state are platform features (each platform
decides which states it publishes); no memory of them is kept here.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from filters.core.compiled import compiled_enabled
from navgym.envs.features import Feature
from navgym.envs.memory_kernel import memory_pass

#: Time constants [s] of the NIS averages (the per-row innovation averages use the longest).
TIME_CONSTANTS_S = (1.0, 10.0)
#: Steps of the whiteness window.
WINDOW_STEPS = 20
#: Bound of the normalized innovations averaged (the ``innovation`` column's).
INNOVATION_BOUND = 10.0
#: Bound of ``log(1 + NIS / rows)`` averaged (the ``log_nis`` column's).
LOG_NIS_BOUND = 10.0


class MemoryState(NamedTuple):
    """The per-episode memory of B episodes (rows = episodes; see the module docstring)."""

    nis_sum: np.ndarray  #: (B, K) weighted sums s of log(1 + NIS / rows), one per time constant
    nis_weight: np.ndarray  #: (B, K) their weights w
    innovation_sum: np.ndarray  #: (B, m_max) weighted sums of each row's normalized innovation
    innovation_weight: np.ndarray  #: (B, m_max) their weights
    last_innovation: np.ndarray  #: (B, m_max) the last step's normalized innovations (0 unused)
    last_used: np.ndarray  #: (B, m_max) rows the last step used
    pairs: np.ndarray  #: (B, WINDOW, 3) per step of the window: c_k, a_k, b_k (module docstring)


class InnovationMemory:
    """The memory features of a platform with step ``dt`` and ``m_max`` rows (module docstring)."""

    def __init__(
        self,
        dt: float,
        m_max: int,
        time_constants_s: tuple[float, ...] = TIME_CONSTANTS_S,
        window: int = WINDOW_STEPS,
    ) -> None:
        self.dt = float(dt)
        self.m_max = int(m_max)
        self.time_constants_s = tuple(float(t) for t in time_constants_s)
        if not self.time_constants_s or not all(t > 0 and np.isfinite(t) for t in self.time_constants_s):
            raise ValueError(f"time constants must be finite and > 0; got {time_constants_s!r}")
        self.window = int(window)
        if self.window < 1:
            raise ValueError(f"the whiteness window must be >= 1 step; got {window!r}")
        #: Per-step factors ``alpha = 1 - exp(-dt / tau)`` of the NIS averages.
        self.alphas = -np.expm1(-self.dt / np.asarray(self.time_constants_s))
        #: The per-row innovation averages' factor (the longest time constant).
        self.innovation_alpha = float(-np.expm1(-self.dt / max(self.time_constants_s)))

    def features(self) -> list[Feature]:
        """The memory columns (names carry the time constants)."""
        tau_long = max(self.time_constants_s)
        return [
            *(
                Feature(
                    f"log_nis_avg_{tau:g}s",
                    0.0,
                    LOG_NIS_BOUND,
                    "-",
                    f"average of log(1 + NIS / rows) over the steps with measurements, time constant "
                    f"{tau:g} s (exponentially weighted from the first; 0 before it)",
                )
                for tau in self.time_constants_s
            ),
            Feature(
                "innovation_avg",
                -INNOVATION_BOUND,
                INNOVATION_BOUND,
                "-",
                f"per row, average of the normalized innovation over the steps that received it, "
                f"time constant {tau_long:g} s (0 before the first)",
                self.m_max,
            ),
            Feature(
                "innovation_whiteness",
                -1.0,
                1.0,
                "-",
                f"lag-1 autocorrelation of the normalized innovations over the last {self.window} "
                "steps (uncentred, rows received at consecutive steps; 0 without such pairs)",
            ),
        ]

    def initial_state(self, B: int) -> MemoryState:
        """The memory of B episodes at reset: nothing seen."""
        K, m = len(self.time_constants_s), self.m_max
        return MemoryState(
            np.zeros((B, K)),
            np.zeros((B, K)),
            np.zeros((B, m)),
            np.zeros((B, m)),
            np.zeros((B, m)),
            np.zeros((B, m), dtype=bool),
            np.zeros((B, self.window, 3)),
        )

    def values(self, memory: MemoryState) -> dict[str, np.ndarray]:
        """The memory columns of ``memory`` (0 where nothing was seen)."""
        out = {
            f"log_nis_avg_{tau:g}s": _ratio(memory.nis_sum[:, k], memory.nis_weight[:, k])
            for k, tau in enumerate(self.time_constants_s)
        }
        out["innovation_avg"] = _ratio(memory.innovation_sum, memory.innovation_weight)
        c, a, b = (memory.pairs[:, :, j].sum(axis=1) for j in range(3))
        denominator = np.sqrt(a * b)
        r = np.divide(c, denominator, out=np.zeros_like(c), where=denominator > 0)
        out["innovation_whiteness"] = np.clip(r, -1.0, 1.0)
        return out

    def update(
        self, memory: MemoryState, t: np.ndarray, info: Any, mask: np.ndarray
    ) -> tuple[MemoryState, dict[str, np.ndarray]]:
        """The memory after the filter step from ``t`` (``(B,)`` steps before it) and its columns.

        ``info`` is the step's update diagnostics (``innovation``, ``S``, ``nis``, ``n_meas``),
        ``mask`` the rows received. The compiled twin
        (:func:`navgym.envs.memory_kernel.memory_pass`) takes the step unless
        :func:`filters.core.compiled.numpy_only` forces this NumPy form; ``memory`` is left
        unchanged either way (a snapshot may hold it).
        """
        if not compiled_enabled():
            return self.update_numpy(memory, t, info, mask)
        used = np.ascontiguousarray(mask, dtype=bool)
        B = used.shape[0]
        new = MemoryState(*(np.array(a, copy=True, order="C") for a in memory))
        K = len(self.time_constants_s)
        nis_avg, innovation_avg, whiteness = np.empty((B, K)), np.empty((B, self.m_max)), np.empty(B)
        memory_pass(
            np.asarray(info.S, dtype=np.float64), np.asarray(info.innovation, dtype=np.float64),
            np.asarray(info.nis, dtype=np.float64), np.asarray(info.n_meas, dtype=np.int64), used,
            np.asarray(t, dtype=np.int64) % self.window, self.alphas, self.innovation_alpha,
            INNOVATION_BOUND, LOG_NIS_BOUND, *new, nis_avg, innovation_avg, whiteness,
        )  # fmt: skip
        out = {f"log_nis_avg_{tau:g}s": nis_avg[:, k] for k, tau in enumerate(self.time_constants_s)}
        out["innovation_avg"] = innovation_avg
        out["innovation_whiteness"] = whiteness
        return new, out

    def update_numpy(
        self, memory: MemoryState, t: np.ndarray, info: Any, mask: np.ndarray
    ) -> tuple[MemoryState, dict[str, np.ndarray]]:
        """:meth:`update` in NumPy passes: the reference of the compiled twin."""
        B = mask.shape[0]
        used = np.asarray(mask, dtype=bool)
        S_diag = np.maximum(np.diagonal(info.S, axis1=1, axis2=2), 1e-12)
        y = np.where(used, np.asarray(info.innovation) / np.sqrt(S_diag), 0.0)
        y = np.clip(np.nan_to_num(y, nan=0.0), -INNOVATION_BOUND, INNOVATION_BOUND)
        n_meas = np.asarray(info.n_meas)
        x = np.log1p(np.maximum(np.asarray(info.nis, dtype=np.float64), 0.0) / np.maximum(n_meas, 1))
        x = np.clip(np.nan_to_num(x, nan=LOG_NIS_BOUND), 0.0, LOG_NIS_BOUND)
        seen = (n_meas > 0)[:, None]
        a = self.alphas[None, :]
        nis_sum = np.where(seen, (1.0 - a) * memory.nis_sum + a * x[:, None], memory.nis_sum)
        nis_weight = np.where(seen, (1.0 - a) * memory.nis_weight + a, memory.nis_weight)
        b = self.innovation_alpha
        innovation_sum = np.where(used, (1.0 - b) * memory.innovation_sum + b * y, memory.innovation_sum)
        innovation_weight = np.where(used, (1.0 - b) * memory.innovation_weight + b, memory.innovation_weight)
        both = used & memory.last_used
        y_last = memory.last_innovation
        pairs = memory.pairs.copy()
        slot = np.asarray(t, dtype=np.int64) % self.window
        rows = np.arange(B)
        pairs[rows, slot, 0] = np.where(both, y * y_last, 0.0).sum(axis=1)
        pairs[rows, slot, 1] = np.where(both, y * y, 0.0).sum(axis=1)
        pairs[rows, slot, 2] = np.where(both, y_last * y_last, 0.0).sum(axis=1)
        new = MemoryState(nis_sum, nis_weight, innovation_sum, innovation_weight, y, used.copy(), pairs)
        return new, self.values(new)


def _ratio(s: np.ndarray, w: np.ndarray) -> np.ndarray:
    return np.divide(s, w, out=np.zeros_like(s), where=w > 0)


__all__ = ["LOG_NIS_BOUND", "TIME_CONSTANTS_S", "WINDOW_STEPS", "InnovationMemory", "MemoryState"]
