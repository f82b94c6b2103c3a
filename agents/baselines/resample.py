"""Resampling baselines (``*Resample-v*`` envs): never, always, ESS threshold, Carvalho et al. 1997's rule.

The Resample task's action (``Discrete(2)``) decides whether the particles, as they stand after
the last update (whose ESS/N and redistribution flag the observation carries), are resampled
before the next prediction; each resampling costs ``resample_cost`` in the reward.
"""

from __future__ import annotations

import numpy as np

from agents.baselines.base import BaselinePolicy

__all__ = ["AlwaysResample", "EssThreshold", "NeverResample", "RedistributionRule", "ResampleBaseline"]


class ResampleBaseline(BaselinePolicy):
    """Base of the resampling baselines: a ``(B,)`` boolean decision, returned as int64."""

    task = "Resample"

    def decide(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def act(self, obs, memory, fresh):
        return np.asarray(self.decide(obs), dtype=bool).astype(np.int64), memory


class NeverResample(ResampleBaseline):
    """Never resample (sequential importance sampling)."""

    name = "never"

    def decide(self, obs):
        return np.zeros(obs.shape[0], dtype=bool)


class AlwaysResample(ResampleBaseline):
    """Resample at every step (the bootstrap filter of Gordon et al. 1993)."""

    name = "always"

    def decide(self, obs):
        return np.ones(obs.shape[0], dtype=bool)


class EssThreshold(ResampleBaseline):
    """Resample when ``ESS / N < threshold`` (Kong, Liu & Wong 1994).

    The decision of :func:`filters.particle.triggers.ess_trigger`, on the observed ``ess_frac``.
    """

    name = "ess"
    defaults = {"threshold": 0.5}

    def decide(self, obs):
        thr = self.param("threshold", obs.shape[0])
        return self.col(obs, "ess_frac") < thr * (1.0 - 1e-12)


class RedistributionRule(ResampleBaseline):
    """Carvalho et al. 1997's redistribution rule (§V).

    Resample when more than 10% of the particles weigh less than ``1/(10 N)``
    (:func:`filters.particle.triggers.redistribution_trigger`); the env computes the rule after
    each update and publishes it as ``redistribution_rule``.
    """

    name = "redistribution"

    def decide(self, obs):
        return self.col(obs, "redistribution_rule") > 0.5
