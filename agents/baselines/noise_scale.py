"""Noise-scale baselines (``*NoiseScale-v2`` envs): classical adaptive Q / R scaling from observations.

The NoiseScale task (:class:`navgym.envs.tasks.NoiseScaleTask`) applies ``Q' = s_q Q`` and
``R' = s_r R``; the action is log-mapped, ``log10 s = lo + (a + 1) / 2 (hi - lo)`` (default
``lo = -1``, ``hi = 2``: 0.1 to 100; ``s = 1`` is ``a = -1/3``). :func:`scales_to_action` inverts it.

**What the baselines read.** The observation's ``innovation`` column holds each received row's
normalized innovation ``nu_i = v_i / sqrt(S_ii)`` (0 where not received, clipped to [-10, 10])
with ``S = H P^- H^T + s_r R`` the filter's predicted innovation covariance under the scale
``s_r`` *applied at that step* (the ``log_r_scale`` column). If the filter is consistent,
``E nu_i^2 = 1``; in general ``E nu_i^2 = S_true,ii / S_filter,ii`` (Mehra 1970's innovation
test). When ``R`` dominates ``S`` (the GNSS/compass rows of the platforms here, once the filter
has converged), ``S_true / S_nominal ~ R_true / R`` and the innovation brought back to the
nominal scale, ``x_i = nu_i^2 s_r,applied``, estimates the ratio ``R_true,ii / R_ii`` directly;
this de-normalization removes the feedback of the scale the baseline itself applied (without
it, the estimate would chase its own tail: a larger ``s_r`` shrinks ``nu``). Each step with
measurements contributes the mean ``x_k`` of ``x_i`` over its received rows. Where ``H P H^T``
is not negligible the ratio is biased upward (``S_true / S_filter`` also carries the state
uncertainty); the tuned gain absorbs that.

**Timing.** Like every baseline reading the observation, the scale chosen from step k's
innovations is applied at step k + 1 (one step of lag); the reset observation (no innovation)
is never absorbed and gets the plain filter (``s_q = s_r = 1``) for the adaptive baselines.

Baselines:

* :class:`ConstantScale` (``constant``; ``plain`` with ``s_q = s_r = 1``): fixed scales.
* :class:`IaeScale` (``iae``): innovation-based adaptive estimation of R over a moving window
  (Mehra 1970; Mohamed & Schwarz 1999, eq. 20-22: ``C_v = 1/N sum_j v_j v_j^T``,
  ``R = C_v - H P^- H^T``), in the normalized form above: ``r = mean of x_k`` over the last
  ``window`` steps with measurements, ``s_r = clip(1 + gain (r - 1), s_lo, s_hi)``.
* :class:`SageHusaScale` (``sage_husa``): Sage & Husa 1969's recursive R estimate with
  forgetting factor ``b``, ``r_k = (1 - d_k) r_{k-1} + d_k x_k``, ``d_k = (1 - b) / (1 - b^(k+1))``
  (``d_0 = 1``), ``s_r = clip(beta r_k, s_lo, s_hi)``.
* :class:`NisQScale` (``iae_q``): ``iae`` for R plus a Q-side rule: when few rows are received
  (``rows <= few_rows``: a GNSS outage or one constellation), the measurements cannot separate
  R from Q and a high short-term NIS is a sign of unmodelled motion; ``s_q`` is raised from the
  1 s NIS average (see :class:`NisQScale`).
"""

from __future__ import annotations

import numpy as np

from agents.baselines.base import BaselinePolicy
from navgym.envs.base import NavigationAPI

__all__ = [
    "ConstantScale",
    "IaeScale",
    "NisQScale",
    "NoiseScaleBaseline",
    "SageHusaScale",
    "normalized_r_ratio",
    "scales_to_action",
]


def scales_to_action(
    s_q: np.ndarray, s_r: np.ndarray, log_low: np.ndarray, log_high: np.ndarray
) -> np.ndarray:
    """Actions ``(B, 2)`` float32 of ``s_q, s_r (B,)``: ``a = -1 + 2 (log10 s - lo) / (hi - lo)``, clipped."""
    e = np.log10(np.stack([np.asarray(s_q, dtype=np.float64), np.asarray(s_r, dtype=np.float64)], axis=-1))
    a = -1.0 + 2.0 * (e - log_low) / (log_high - log_low)
    return np.clip(a, -1.0, 1.0).astype(np.float32)


def normalized_r_ratio(nu: np.ndarray, log_r_scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step: ``x_k = mean_i nu_i^2 s_r,applied`` over the received rows, and whether any was.

    ``nu (B, m)`` the ``innovation`` column (0: not received), ``log_r_scale (B,)`` the applied
    ``log10 s_r``. ``x_k`` estimates ``R_true / R`` when R dominates S (module docstring); 0 where
    no row was received.
    """
    used = nu != 0.0
    n = used.sum(axis=1)
    x = (nu * nu).sum(axis=1) / np.maximum(n, 1) * 10.0 ** np.asarray(log_r_scale, dtype=np.float64)
    return np.where(n > 0, x, 0.0), n > 0


class NoiseScaleBaseline(BaselinePolicy):
    """Base of the noise-scale baselines: ``(s_q, s_r)`` per episode, mapped to the action."""

    task = "NoiseScale"

    def setup(self, env: NavigationAPI) -> None:
        self.log_low = np.asarray(env.task.log_low, dtype=np.float64)
        self.log_high = np.asarray(env.task.log_high, dtype=np.float64)
        self.q_range = 10.0 ** np.array([self.log_low[0], self.log_high[0]])
        self.r_range = 10.0 ** np.array([self.log_low[1], self.log_high[1]])

    def scales(self, obs: np.ndarray, memory: dict, fresh: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
        """``s_q (B,)``, ``s_r (B,)`` and the new memory."""
        raise NotImplementedError

    def act(self, obs, memory, fresh):
        s_q, s_r, memory = self.scales(obs, memory, fresh)
        s_q = np.clip(s_q, *self.q_range)
        s_r = np.clip(s_r, *self.r_range)
        return scales_to_action(s_q, s_r, self.log_low, self.log_high), memory

    def _x(self, obs: np.ndarray, fresh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x, step = normalized_r_ratio(self.block(obs, "innovation"), self.col(obs, "log_r_scale"))
        return x, step & ~fresh


class ConstantScale(NoiseScaleBaseline):
    """Fixed scales ``s_q``, ``s_r`` (``s_q = s_r = 1``: the plain filter), clipped to the task's ranges."""

    name = "constant"
    defaults = {"s_q": 1.0, "s_r": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        if (self.params["s_q"] <= 0).any() or (self.params["s_r"] <= 0).any():
            raise ValueError("s_q and s_r must be > 0")

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        return self.param("s_q", B).copy(), self.param("s_r", B).copy(), memory


class IaeScale(NoiseScaleBaseline):
    """Innovation-based adaptive estimation of R over a moving window (Mehra 1970; Mohamed & Schwarz 1999).

    Mohamed & Schwarz estimate ``R = C_v - H P^- H^T`` with ``C_v`` the mean of ``v v^T`` over the
    last ``N`` epochs. Here, from the observation only, each step with measurements gives
    ``x_k = mean_i nu_i^2 s_r,applied`` (:func:`normalized_r_ratio`: the normalized innovations
    brought back to the nominal R; ``E x_k = R_true / R`` when R dominates S), and

        r = mean of x_k over the last ``window`` steps with measurements (fewer at the start)
        s_r = clip(1 + gain (r - 1), s_lo, s_hi),   s_q = 1

    ``gain = 1`` uses the estimate as it is (``s_r = r``: the IAE's R); ``gain < 1`` shrinks it
    toward the nominal R (smoother, less responsive), ``gain > 1`` overshoots (compensates
    the lag). On white unit innovations under ``s_r = 1`` (``x_k = 1``) it gives ``s_r = 1``
    exactly. Steps without measurements keep the window. Parameters: ``window`` N (steps, >= 1;
    rounded), ``gain > 0``.
    """

    name = "iae"
    defaults = {"window": 20.0, "gain": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        if (self.params["window"] < 1).any() or (self.params["gain"] <= 0).any():
            raise ValueError("window must be >= 1 and gain > 0")
        self.window_max = int(np.round(self.params["window"]).max())

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"buf": np.zeros((B, self.window_max)), "count": np.zeros(B, dtype=np.int64)}

    def r_estimate(self, obs, memory, fresh) -> tuple[np.ndarray, dict]:
        B = obs.shape[0]
        N = np.round(self.param("window", B)).astype(np.int64)
        x, step = self._x(obs, fresh)
        buf, count = memory["buf"].copy(), memory["count"].copy()
        rows = np.nonzero(step)[0]
        buf[rows, count[rows] % N[rows]] = x[rows]
        count = count + step
        n = np.minimum(count, N)
        cols = np.arange(self.window_max)[None, :]
        r = np.where(cols < n[:, None], buf, 0.0).sum(axis=1) / np.maximum(n, 1)
        r = np.where(n > 0, r, 1.0)
        return r, {"buf": buf, "count": count}

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        r, memory = self.r_estimate(obs, memory, fresh)
        s_r = 1.0 + self.param("gain", B) * (r - 1.0)
        return np.ones(B), s_r, memory


class SageHusaScale(NoiseScaleBaseline):
    """Sage & Husa 1969's recursive R estimate with a forgetting factor, on normalized innovations.

    The Sage-Husa estimator ``R_k = (1 - d_k) R_{k-1} + d_k (v v^T - H P^- H^T)`` with
    ``d_k = (1 - b) / (1 - b^(k+1))`` (weights of :func:`filters.adaptive.sage_husa_update`),
    in the normalized form of the module docstring (``H P H^T`` neglected against R)::

        r_k = (1 - d_k) r_{k-1} + d_k x_k     (d_0 = 1: r_0 = x_0; steps with measurements only)
        s_r = clip(beta r_k, s_lo, s_hi),   s_q = 1

    ``b`` in (0, 1) is the forgetting factor (effective memory ``1 / (1 - b)`` steps); ``beta > 0``
    a softening factor on the estimate (1: the estimate itself). Before any measurement ``s_r = 1``.
    """

    name = "sage_husa"
    defaults = {"b": 0.95, "beta": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        b = self.params["b"]
        if ((b <= 0) | (b >= 1)).any() or (self.params["beta"] <= 0).any():
            raise ValueError("b must lie in (0, 1) and beta > 0")

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"r": np.ones(B), "k": np.zeros(B, dtype=np.int64)}

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        b = self.param("b", B)
        x, step = self._x(obs, fresh)
        k = memory["k"]
        d = (1.0 - b) / (1.0 - b ** (k + 1.0))
        r = np.where(step, (1.0 - d) * memory["r"] + d * x, memory["r"])
        k = k + step
        return np.ones(B), self.param("beta", B) * r, {"r": r, "k": k}


class NisQScale(IaeScale):
    """``iae`` for R plus a Q-side rule from the short-term NIS when few rows are received.

    With many rows the innovations separate measurement noise from motion (IAE of R above); with
    few (``rows_used * m_max <= few_rows``: a GNSS outage, compass only, or one constellation)
    a high NIS is more likely unmodelled motion (process noise) than a noisy sensor. The 1 s NIS
    average ``log_nis_avg_1s = avg log(1 + NIS / rows)`` gives ``q = exp(avg) - 1`` (a geometric-
    type mean of ``NIS / rows``; ~0.5-0.7 for a consistent filter, below 1 by Jensen), and::

        s_q = clip(1 + gain_q max(0, q - threshold), 1, q_hi)   where rows are few, else 1

    ``s_r`` as :class:`IaeScale`. Parameters: ``window``, ``gain`` (R side), ``gain_q >= 0``,
    ``threshold`` (on q), ``few_rows`` (row count).
    """

    name = "iae_q"
    defaults = {"window": 20.0, "gain": 1.0, "gain_q": 3.0, "threshold": 1.0, "few_rows": 2.0}

    def scales(self, obs, memory, fresh):
        B = obs.shape[0]
        r, memory = self.r_estimate(obs, memory, fresh)
        s_r = 1.0 + self.param("gain", B) * (r - 1.0)
        m = self.block(obs, "innovation").shape[1]
        # the count of rows used: "rows_used", or "satellites" on the pseudo-range platforms (GpsIns)
        names = [f.name for f in self.features.features]
        rows = np.round(self.col(obs, "rows_used" if "rows_used" in names else "satellites") * m)
        few = (rows <= self.param("few_rows", B)) & ~fresh
        q = np.expm1(self.col(obs, "log_nis_avg_1s"))
        s_q = 1.0 + self.param("gain_q", B) * np.maximum(0.0, q - self.param("threshold", B))
        return np.where(few, s_q, 1.0), s_r, memory
