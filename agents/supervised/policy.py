"""The supervised RowScale policy: predicted regimes -> the oracle's table -> the action.

:class:`SupervisedRowScalePolicy` reads only observations. Each step it computes the inputs of
:class:`~agents.supervised.features.RowFeatures` (its per-episode memory: the rows' averages of
``z_nom^2``), runs :class:`~agents.supervised.model.RowRegimeNet`, and maps the classes to the
scales of the regime oracle's table ``(s_nominal, s_noisy, s_biased, s_q_nominal, s_q_event)``
(searched on tuning seeds, :func:`experiments.knob_reach.row_regimes.search_row_table`):

* ``mode="argmax"``: each row's most probable regime's scale (*not received*: ``s_nominal``;
  the update ignores a masked row's scale), the motion's most probable regime's ``s_q``;
* ``mode="expected"``: the probability-weighted ``log10`` scale,
  ``log s_i = sum_c p(c | received) log table_c`` over the three received classes, and
  ``log s_q = p_event log s_q_event + (1 - p_event) log s_q_nominal``;
* ``mode="iae_mix"``: the rows' scales of ``"expected"`` mixed in ``log10`` with the scales of
  the tuned ``row_iae`` baseline (:class:`agents.baselines.row_scale.RowInnovationScale`) run on
  the same observations, ``log s_i = (1 - w) log s_i,expected + w log clip(beta r_i, 0.3, 1e4)``
  with ``w =`` :data:`IAE_WEIGHT` and ``r_i`` the average of ``z_nom^2`` with forgetting ``b``;
  ``b``, ``beta`` (and ``s_q``) are row_iae's tuned parameters of the env id, read from its tuned
  file by :func:`tuned_iae` (``navgym/Robot2dRowScale-v3``: ``b = 0.5, beta = 0.5, s_q = 1``) and
  kept in the policy's manifest. ``s_q`` by ``iae_q``: ``"table"`` as ``"expected"``; ``"mix"``
  the same ``log10`` mix of it with row_iae's ``s_q``; ``"iae"`` row_iae's ``s_q``. The
  classifier knows the regime's kind (its scale from the table), row_iae the row's current
  magnitude; the mix keeps both.

The scales go to the action through :meth:`navgym.envs.tasks.RowScaleTask.actions_of`.

A wrong hard class costs much (a biased row left at ``s_nominal``, a nominal row excluded), the
soft mix hedges; on 64 tuning episodes of ``navgym/Robot2dRowScale-v3`` (table ``1, 100, 1e4, 1,
10``, 256 training episodes, no DAgger) argmax gave a mean RMSE of 4.95 m, expected 2.04 m. With
512 training episodes and 2 DAgger rounds (128 tuning episodes): expected 1.50 m, ``"iae_mix"``
(the command's default) 1.42 m, the tuned row_iae 1.94 m; with the G1-searched table
``0.3, 3, 100, 1, 1`` instead: 1.62 m and 1.71 m.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from agents.baselines.registry import load_tuned, tuned_path
from agents.supervised.features import FORGETTING, RowFeatures
from agents.supervised.labels import NOT_RECEIVED
from agents.supervised.model import RowRegimeNet
from navgym.envs.base import navigation_env
from navgym.envs.tasks import RowScaleTask

__all__ = ["IAE_Q", "IAE_WEIGHT", "MODES", "SupervisedRowScalePolicy", "tuned_iae"]

#: How classes become scales (module docstring).
MODES = ("argmax", "expected", "iae_mix")
#: ``"iae_mix"``: the weight of row_iae's ``log10`` scale.
IAE_WEIGHT = 0.5
#: ``"iae_mix"``: where ``s_q`` comes from (module docstring).
IAE_Q = ("table", "mix", "iae")


def tuned_iae(env_id: str, tuned_file: str | Path | None = None) -> dict[str, float]:
    """row_iae's tuned ``{"b", "beta", "s_q"}`` of ``env_id`` (its tuned file, on tuning seeds).

    Raises:
        FileNotFoundError: no tuned file, or no ``row_iae`` entry in it (the file named).
    """
    path = Path(tuned_file) if tuned_file is not None else tuned_path(env_id)
    params = load_tuned(env_id, path, missing_ok=False).get("row_iae")
    if params is None:
        raise FileNotFoundError(f"{path} has no tuned row_iae parameters, needed by mode 'iae_mix'")
    return {k: float(params[k]) for k in ("b", "beta", "s_q")}


class SupervisedRowScalePolicy:
    """SB3-style ``predict`` of the per-row regime classifier (module docstring).

    Args:
        env: the env (single, vector, or id) whose observation layout and task it serves.
        model: the trained :class:`RowRegimeNet`.
        table: the oracle's five scales ``(s_nominal, s_noisy, s_biased, s_q_nominal, s_q_event)``.
        mode: one of :data:`MODES`.
        iae: ``"iae_mix"``: row_iae's tuned ``{"b", "beta", "s_q"}`` (:func:`tuned_iae`).
        iae_q: ``"iae_mix"``: where ``s_q`` comes from, one of :data:`IAE_Q`.
    """

    name = "supervised"
    is_baseline = False
    uses_truth = False

    def __init__(
        self,
        env: Any,
        model: RowRegimeNet,
        table: Sequence[float],
        mode: str = "argmax",
        iae: Mapping[str, float] | None = None,
        iae_q: str = "table",
    ) -> None:
        nav = navigation_env(env)
        task = nav.task
        if not isinstance(task, RowScaleTask):
            raise ValueError(
                f"SupervisedRowScalePolicy serves RowScale tasks (v3); the env's task is {task.name}"
            )
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}; got {mode!r}")
        if iae_q not in IAE_Q:
            raise ValueError(f"iae_q must be one of {IAE_Q}; got {iae_q!r}")
        self.iae = None if iae is None else {k: float(iae[k]) for k in ("b", "beta", "s_q")}
        if mode == "iae_mix" and self.iae is None:
            raise ValueError("mode 'iae_mix' needs row_iae's tuned parameters: iae=tuned_iae(env_id)")
        bad = self.iae is not None and not (0 <= self.iae["b"] < 1 and self.iae["beta"] > 0 < self.iae["s_q"])
        if bad:
            raise ValueError(f"row_iae's parameters need b in [0, 1), beta > 0, s_q > 0; got {self.iae}")
        self.iae_q = iae_q
        t = np.asarray(table, dtype=np.float64)
        if t.shape != (5,) or not (np.isfinite(t) & (t > 0)).all():
            raise ValueError(f"table must be five positive scales; got {table!r}")
        self.task = task
        #: The task's action space (the residual agents' base reads it).
        self.action_space = task.action_space
        self.features = RowFeatures.of(nav.observation_features, int(task.m_max))
        if (model.n_row, model.n_global) != (self.features.n_row, self.features.n_global):
            raise ValueError(
                f"the model takes {model.n_row} row and {model.n_global} global inputs; this env gives "
                f"{self.features.n_row} and {self.features.n_global}"
            )
        self.model = model.eval()
        self.table = t
        self.mode = mode
        self.obs_dim = int(nav.observation_features.dim)
        self._memory: dict[str, np.ndarray] | None = None
        self._iae_r: np.ndarray | None = None

    def describe(self) -> dict[str, Any]:
        """Name, class, table, mode and row_iae's parameters (for evaluation manifests)."""
        return {
            "name": self.name,
            "class": f"{type(self).__module__}.{type(self).__qualname__}",
            "params": {"table": self.table.tolist(), "mode": self.mode, "iae": self.iae, "iae_q": self.iae_q},
            "uses_truth": False,
        }

    def probabilities(
        self, obs: np.ndarray, memory: dict[str, np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray, dict]:
        """Row class probabilities ``(B, m, 4)``, motion ``(B, 2)`` and the new memory."""
        rows, glob, new = self.features(obs, memory)
        if self.iae is not None and self.iae["b"] in FORGETTING:
            self._iae_r = new["z2"][:, FORGETTING.index(self.iae["b"])]
        elif self.iae is not None:  # the features' update with row_iae's own b
            z_nom, received = self.features.z_nominal(obs)
            b = self.iae["b"]
            r = memory["iae_r"]
            new["iae_r"] = np.where(received, b * r + (1.0 - b) * z_nom * z_nom, r)
            self._iae_r = new["iae_r"]
        memory = new
        with torch.no_grad():
            lr, lm = self.model(torch.from_numpy(rows), torch.from_numpy(glob))
        return torch.softmax(lr, -1).double().numpy(), torch.softmax(lm, -1).double().numpy(), memory

    def scales(self, p_row: np.ndarray, p_motion: np.ndarray) -> np.ndarray:
        """The scales ``(B, m + 1)`` of class probabilities (``mode``)."""
        t = self.table
        if self.mode == "argmax":
            c = p_row.argmax(-1)
            rows = t[:3][np.where(c == NOT_RECEIVED, 0, c)]
            return np.column_stack([rows, t[3:5][p_motion.argmax(-1)]])
        rec = p_row[..., :NOT_RECEIVED]
        w = rec / np.maximum(rec.sum(-1, keepdims=True), 1e-12)
        rows = 10.0 ** (w @ np.log10(t[:3]))
        q = 10.0 ** (p_motion @ np.log10(t[3:5]))
        if self.mode == "iae_mix":
            if self._iae_r is None or self._iae_r.shape != rows.shape:
                raise ValueError("mode 'iae_mix' needs probabilities() of the same observations first")
            iae = np.clip(self.iae["beta"] * self._iae_r, 0.3, 1e4)
            rows = 10.0 ** ((1.0 - IAE_WEIGHT) * np.log10(rows) + IAE_WEIGHT * np.log10(iae))
            if self.iae_q == "mix":
                q = 10.0 ** ((1.0 - IAE_WEIGHT) * np.log10(q) + IAE_WEIGHT * np.log10(self.iae["s_q"]))
            elif self.iae_q == "iae":
                q = np.full_like(q, self.iae["s_q"])
        return np.column_stack([rows, q])

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        """Fresh per-episode memory: the features' (and row_iae's ``r`` when its ``b`` is not theirs)."""
        memory = self.features.init_memory(B)
        if self.iae is not None and self.iae["b"] not in FORGETTING:
            memory["iae_r"] = np.ones((B, self.features.m))
        return memory

    def reset(self) -> None:
        """Forget the memory (the next :meth:`predict` starts fresh episodes)."""
        self._memory = None

    def predict(
        self,
        observation: np.ndarray,
        state: dict[str, np.ndarray] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """SB3's ``predict``: actions ``(B, m + 1)`` (``(m + 1,)`` for one observation) and the memory."""
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        obs = obs.reshape(1, -1) if single else obs
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(
                f"observation must have shape (B, {self.obs_dim}) or ({self.obs_dim},); got {obs.shape}"
            )
        B = obs.shape[0]
        memory = state if state is not None else self._memory
        if memory is None or memory["z2"].shape[0] != B:
            memory = self.init_memory(B)
        if episode_start is not None:
            starts = np.asarray(episode_start, dtype=bool).reshape(B)
            if starts.any():
                fresh = self.init_memory(B)
                memory = {
                    k: np.where(starts.reshape((B,) + (1,) * (v.ndim - 1)), fresh[k], v)
                    for k, v in memory.items()
                }
        p_row, p_motion, memory = self.probabilities(obs, memory)
        actions = self.task.actions_of(self.scales(p_row, p_motion))
        self._memory = memory
        return (actions[0] if single else actions), memory
