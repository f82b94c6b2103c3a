"""The ``info`` of a step, built once by the core and viewed three ways.

:class:`StepInfo` holds what :meth:`navgym.envs.core.NavCore.advance` reports about a step of
B episodes: evaluation quantities (truth allowed: they never reach the observation), the
filter's diagnostics, the episode ends, the reward terms and the task's own diagnostics (its
:class:`~navgym.envs.protocols.TaskDiagnostics`, each field a key). Its views are what the
shells hand out:

* :meth:`StepInfo.as_dict`: the batched ``info`` of the core and of the native vector env's
  :meth:`~navgym.envs.base.EpisodeStepper.step`;
* :meth:`StepInfo.vector`: the vector env's ``info``, each key with Gymnasium's ``"_" + key``
  mask of the sub-envs it is valid for;
* :meth:`StepInfo.row`: a single env's ``info`` (row ``i``, NumPy scalars as Python numbers,
  the reward terms as ``info["reward_terms"]``);
* :meth:`StepInfo.sb3`: stable-baselines3's list of per-sub-env dicts of :data:`SB3_INFO_KEYS`.

The data flow of a step is described in ``docs/architecture.md``.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np

from navgym.envs.protocols import TaskDiagnostics

#: Per-step info keys copied into SB3's list of dicts (scalars per sub-env; cheap to copy).
SB3_INFO_KEYS = (
    "pos_err_m",
    "nis",
    "n_meas",
    "healthy",
    "diverged",
    "divergence_reason",
    "gnss_available",
    "knob",
    "action_clipped",
)
#: The keys of the reward terms in the batched ``info`` and their names in a single env's
#: ``info["reward_terms"]`` (``r = accuracy + cost + divergence_penalty``).
REWARD_TERMS = {"reward_accuracy": "accuracy", "reward_cost": "cost", "reward_penalty": "divergence_penalty"}


class StepInfo(NamedTuple):
    """What a step of B episodes reports (module docstring); ``(B, ...)`` arrays."""

    pos_err_m: np.ndarray  #: horizontal position error [m] (NaN for a numerical failure)
    nees: np.ndarray  #: normalized estimation error squared (NaN without ``eval_info``)
    truth_pos: np.ndarray  #: (B, 2) true north/east position [m]
    est_pos: np.ndarray  #: (B, 2) estimated north/east position [m]
    cov_ne: np.ndarray  #: (B, 2, 2) the estimate's north/east covariance [m^2]
    innovation: np.ndarray  #: (B, m) the update's innovations
    innovation_cov: np.ndarray  #: (B, m, m) their covariances S
    nis: np.ndarray  #: normalized innovation squared
    n_meas: np.ndarray  #: rows used
    filtered_cov: np.ndarray  #: (B, n, n) the posterior covariance
    healthy: np.ndarray  #: the filter's health flag and a finite error
    diverged: np.ndarray  #: the episode ended by a divergence rule
    divergence_reason: np.ndarray  #: the first rule that ended it ("" while it goes on)
    gnss_available: np.ndarray  #: a GNSS row was received
    knob: np.ndarray  #: the task's knob of the action (float64)
    action_clipped: np.ndarray  #: the action was clipped into its box
    reward_accuracy: np.ndarray  #: ``-min((pos_err_m + extra_err) / error_scale_m, reward_clip)``
    extra_err: np.ndarray | None  #: the platform's further error [m] (None: it gives none)
    reward_cost: np.ndarray  #: minus the task's cost of the decision
    reward_penalty: np.ndarray  #: minus the divergence penalty (0 while the episode goes on)
    t: np.ndarray  #: steps played of the episode
    predicted_cov: np.ndarray | None  #: (B, n, n) the predicted covariance (None for particles)
    task: TaskDiagnostics  #: the task's own diagnostics (each field a key)

    def items(self) -> Iterator[tuple[str, Any]]:
        """The keys and ``(B, ...)`` values of the batched ``info``, in its order.

        ``extra_err`` and ``predicted_cov`` only where given; the task's fields as arrays.
        """
        for k, v in zip(self._fields[:-1], self[:-1], strict=True):
            if v is not None:
                yield k, v
        for k, v in self.task._asdict().items():
            yield k, np.asarray(v)

    def as_dict(self) -> dict[str, Any]:
        """The batched ``info`` (module docstring)."""
        return dict(self.items())

    def vector(self, valid: np.ndarray) -> dict[str, Any]:
        """The vector env's ``info``: each key and its mask ``"_" + key``, ``valid`` (B,)."""
        out: dict[str, Any] = {}
        for k, v in self.items():
            out[k] = v
            out["_" + k] = valid
        return out

    def row(self, i: int) -> dict[str, Any]:
        """Row ``i`` as a single env's ``info``: Python numbers, ``reward_terms`` apart."""
        out: dict[str, Any] = {}
        terms: dict[str, Any] = {}
        for k, v in self.items():
            x = v[i]
            # NumPy scalars (rows of (B,) arrays) become Python numbers (.ndim: np.ndim costs more)
            nd = x.ndim if isinstance(x, (np.ndarray, np.generic)) else np.ndim(x)
            x = x.item() if nd == 0 else x
            if k in REWARD_TERMS:
                terms[REWARD_TERMS[k]] = x
            else:
                out[k] = x
        out["reward_terms"] = terms
        return out

    def sb3(self) -> list[dict[str, Any]]:
        """stable-baselines3's infos: per sub-env, the values of :data:`SB3_INFO_KEYS`."""
        cols = [(k, getattr(self, k)) for k in SB3_INFO_KEYS]
        return [{k: v[i] for k, v in cols} for i in range(self.pos_err_m.shape[0])]
