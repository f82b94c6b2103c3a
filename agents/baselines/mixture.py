"""Outlier-weight baselines (``*Mixture-v*`` envs): fixed and innovation-driven contamination.

The Mixture task's knob is the prior weight ``eps`` of the outlier component in the filter's
noise model ``(1 - eps) N(0, R) + eps N(0, ratio R)`` (Benzerrouk 2014, eq. 71-76), mapped from the
action by ``eps = eps_max (a + 1) / 2``; the baselines map back with
``a = 2 eps / eps_max - 1`` clipped to [-1, 1].
"""

from __future__ import annotations

import math

import numpy as np

from agents.baselines.base import BaselinePolicy
from navgym.envs.base import NavigationAPI

__all__ = [
    "FixedContamination",
    "InnovationContamination",
    "MixtureBaseline",
    "NominalContamination",
    "PosteriorContamination",
    "ZeroContamination",
    "eps_to_action",
    "nominal_contamination",
]


def eps_to_action(eps: np.ndarray, eps_max: float) -> np.ndarray:
    """``a = 2 eps / eps_max - 1`` clipped to [-1, 1], ``(B, 1)`` float32."""
    a = 2.0 * np.asarray(eps, dtype=np.float64) / eps_max - 1.0
    return np.clip(a, -1.0, 1.0).astype(np.float32).reshape(-1, 1)


def nominal_contamination(env: NavigationAPI) -> float:
    """The nominal contamination of the env's scenario *distribution* (a configuration constant).

    The mid-point of the distribution's ``impulsive_eps`` range (the contamination of an
    impulsive-noise period; Benzerrouk 2014, eq. 71), or 0 when the distribution has no impulsive
    noise.
    It is what a designer who knows the env's configuration, not the episode, would set; it is
    not the episode's truth (which varies per episode and is 0 outside impulsive periods).
    """
    dist = env.platform.scenarios
    if dist.impulsive_probability <= 0.0:
        return 0.0
    lo, hi = dist.impulsive_eps
    return 0.5 * (float(lo) + float(hi))


class MixtureBaseline(BaselinePolicy):
    """Base of the mixture baselines: ``eps (B,)`` mapped to the action."""

    task = "Mixture"

    def setup(self, env: NavigationAPI) -> None:
        self.eps_max = float(env.task.eps_max)
        self.variance_ratio = float(env.task.variance_ratio)
        #: Measurement rows the outlier component inflates (None: all), from the task's layout.
        self.outlier_rows = env.task.outlier_rows

    def contamination(self, obs: np.ndarray, memory: dict, fresh: np.ndarray) -> tuple[np.ndarray, dict]:
        raise NotImplementedError

    def act(self, obs, memory, fresh):
        eps, memory = self.contamination(obs, memory, fresh)
        return eps_to_action(eps, self.eps_max), memory


class FixedContamination(MixtureBaseline):
    """A constant outlier weight ``eps`` (tuned on the tuning seeds)."""

    name = "constant"
    defaults = {"eps": 0.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        if (self.params["eps"] < 0).any():
            raise ValueError("eps must be >= 0")

    def contamination(self, obs, memory, fresh):
        return self.param("eps", obs.shape[0]).copy(), memory


class ZeroContamination(FixedContamination):
    """``eps = 0``: the plain base filter (no outlier component)."""

    name = "zero"
    defaults = {"eps": 0.0}


class NominalContamination(FixedContamination):
    """``eps`` fixed at :func:`nominal_contamination` of the env's scenario distribution."""

    name = "nominal"
    defaults = {}

    def setup(self, env: NavigationAPI) -> None:
        self.params["eps"] = np.asarray(nominal_contamination(env))
        super().setup(env)


class InnovationContamination(MixtureBaseline):
    """Contamination estimated from the fraction of large normalized innovations.

    At each step with measurements: the observed normalized innovations ``z_i = v_i / sqrt(S_ii)``
    are normalized by the *mixture* ``S`` of the weight ``eps_prev`` applied at that step (read
    from ``previous_action``); assuming ``H P H^T << R`` they are brought back to the nominal
    scale, ``z_i sqrt(1 + eps_prev (ratio - 1))`` (``ratio`` the task's variance ratio; a
    slight overestimate otherwise). The fraction ``f`` of used rows beyond ``threshold`` gives a
    per-row contamination estimate by inverting ``f = (1 - e) p0 + e p1`` with
    ``p0 = P(|N(0,1)| > c)``, ``p1 = P(|N(0, ratio)| > c)``; it is averaged exponentially with
    weight ``alpha`` and ``eps = clip(gain * average, 0, eps_max)``. Only the rows the task's
    outlier component inflates (the task's ``outlier_rows``, the platform's) are counted.
    Parameters: ``threshold`` c, ``alpha`` in (0, 1], ``gain > 0``.
    """

    name = "innovation"
    defaults = {"threshold": 3.0, "alpha": 0.1, "gain": 1.0}

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"est": np.zeros(B)}

    def contamination(self, obs, memory, fresh):
        B = obs.shape[0]
        c, alpha, gain = self.param("threshold", B), self.param("alpha", B), self.param("gain", B)
        z = np.abs(self.block(obs, "innovation"))
        if self.outlier_rows is not None:
            z = z[:, list(self.outlier_rows)]
        used_rows = z > 0
        n_used = used_rows.sum(axis=1)
        a_prev = self.block(obs, "previous_action")[:, 0]
        eps_prev = np.clip(self.eps_max * (a_prev + 1.0) / 2.0, 0.0, 1.0)
        z_nom = z * np.sqrt(1.0 + eps_prev * (self.variance_ratio - 1.0))[:, None]
        frac = ((z_nom > c[:, None]) & used_rows).sum(axis=1) / np.maximum(n_used, 1)
        erfc = np.vectorize(math.erfc, otypes=[float])
        p0 = erfc(c / math.sqrt(2.0))
        p1 = erfc(c / math.sqrt(2.0 * self.variance_ratio))
        e_row = np.clip((frac - p0) / (p1 - p0), 0.0, 1.0)
        step = (n_used > 0) & ~fresh
        est = np.where(step, (1.0 - alpha) * memory["est"] + alpha * e_row, memory["est"])
        eps = np.clip(gain * est, 0.0, self.eps_max)
        return eps, {"est": est}


class PosteriorContamination(MixtureBaseline):
    """Recursive EM estimate of the outlier weight from the filter's ``outlier_posterior``.

    The posterior weight of the outlier component (Benzerrouk 2014, eq. 74), computed by the filter under
    the prior weight the policy applied, is the E-step; the stochastic-approximation M-step
    (Titterington 1984) averages it exponentially::

        est_k = (1 - alpha) est_{k-1} + alpha posterior_k   (steps with measurements only)
        eps = clip(max(est_k, floor), 0, eps_max)

    ``floor > 0`` keeps the estimate able to rise (with ``eps = 0`` the posterior is 0).
    Parameters: ``alpha`` in (0, 1], ``floor`` >= 0.
    """

    name = "posterior"
    defaults = {"alpha": 0.1, "floor": 0.01}

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"est": np.zeros(B)}

    def contamination(self, obs, memory, fresh):
        B = obs.shape[0]
        alpha, floor = self.param("alpha", B), self.param("floor", B)
        post = self.col(obs, "outlier_posterior")
        used = (np.abs(self.block(obs, "innovation")) > 0).any(axis=1) & ~fresh
        est = np.where(used, (1.0 - alpha) * memory["est"] + alpha * post, memory["est"])
        eps = np.clip(np.maximum(est, floor), 0.0, self.eps_max)
        return eps, {"est": est}
