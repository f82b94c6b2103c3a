"""Fading-factor baselines (``*Fading-v*`` envs): the classical formulas, run on observations.

The Fading task publishes, for the update of each step k over the measurement rows used, the
four traces that the classical fading formulas need (see :func:`navgym.envs.tasks.fading_traces`)::

    tr_vv = |v_k|^2,  tr_R = tr R_k,  tr_HQH = tr(H Q H^T),  tr_M = tr(H F P_{k-1} F^T H^T)

as ``log_tr_*`` features (log10, clipped to [-8, 12]; -8 means "no rows used"). The recursion
``V_k = (rho V_{k-1} + v v^T) / (1 + rho)`` (Benzerrouk 2014, eq. 70) is linear, so its trace runs on
``tr_vv``, and ``lambda = max(1, (gamma tr V - beta tr R - tr HQH) / tr M)`` (eq. 67-69) needs
nothing else. The traces are exactly those of the matrix formulas when the same rows are used
at every step; when satellites rise or set the trace recursion sums over every row seen (the
matrix form keeps per-row entries), a documented approximation.

**Timing.** The classical filter computes ``lambda_k`` inside step k from that step's
innovation (against the unfaded prediction) before its own prediction. An agent, and so a
baseline reading the observation, must choose the factor of step k + 1 from what step k
published: the baselines here apply ``lambda_k`` from step k's traces at step k + 1 (one step of
lag). The innovation does not depend on the factor applied (fading changes the predicted
covariance, not the predicted mean), so ``tr_vv`` is the classical ``v v^T`` trace exactly.

The factor maps back to the action by ``a = 2 log(lambda) / log(lambda_max) - 1`` clipped to
[-1, 1] (the inverse of :class:`navgym.envs.tasks.FadingTask`'s ``lambda_max ** ((a+1)/2)``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.baselines.base import BaselinePolicy
from filters.adaptive import FadingMemory, FadingTerms, strong_tracking_factor, suboptimal_fading_factor
from navgym.envs.base import NavigationAPI

__all__ = [
    "ConstantFading",
    "FadingBaseline",
    "SageHusaFading",
    "StrongTracking",
    "SuboptimalFading",
    "decode_traces",
    "lambda_to_action",
]

#: Lower bound of the ``log_tr_*`` features: a trace at (or below) it means "no rows used".
LOG_TRACE_FLOOR = -8.0
TRACE_NAMES = ("tr_vv", "tr_R", "tr_HQH", "tr_M")


def lambda_to_action(lam: np.ndarray, lambda_max: float) -> np.ndarray:
    """``a = 2 log(lambda) / log(lambda_max) - 1`` clipped to [-1, 1], ``(B, 1)`` float32."""
    lam = np.maximum(np.asarray(lam, dtype=np.float64), 1.0)
    a = 2.0 * np.log(lam) / np.log(lambda_max) - 1.0
    return np.clip(a, -1.0, 1.0).astype(np.float32).reshape(-1, 1)


def decode_traces(obs: np.ndarray, features: Any) -> dict[str, np.ndarray]:
    """The traces ``tr_vv, tr_R, tr_HQH, tr_M (B,)`` from the ``log_tr_*`` observation columns.

    Values at the lower bound (-8, "nothing used") decode to 0.
    """
    out = {}
    for name in TRACE_NAMES:
        x = obs[:, features.index("log_" + name)][:, 0]
        out[name] = np.where(x <= LOG_TRACE_FLOOR + 1e-6, 0.0, 10.0**x)
    return out


class FadingBaseline(BaselinePolicy):
    """Base of the fading baselines: the factor from the traces, mapped to the action."""

    task = "Fading"

    def setup(self, env: NavigationAPI) -> None:
        self.lambda_max = float(env.task.lambda_max)

    def factor(self, tr: dict[str, np.ndarray], memory: dict, fresh: np.ndarray) -> tuple[np.ndarray, dict]:
        """``lambda (B,)`` and the new memory from the decoded traces."""
        raise NotImplementedError

    def act(self, obs: np.ndarray, memory: dict, fresh: np.ndarray) -> tuple[np.ndarray, dict]:
        tr = decode_traces(obs, self.features)
        lam, memory = self.factor(tr, memory, fresh)
        lam = np.where(fresh, 1.0, lam)
        return lambda_to_action(lam, self.lambda_max), memory


class ConstantFading(FadingBaseline):
    """Constant fading factor ``lambda`` (``lambda = 1``: the plain filter)."""

    name = "constant"
    defaults = {"lam": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        if (self.params["lam"] < 1.0).any():
            raise ValueError("lam must be >= 1")

    def factor(self, tr, memory, fresh):
        B = tr["tr_vv"].shape[0]
        return self.param("lam", B).copy(), memory


class SuboptimalFading(FadingBaseline):
    """Benzerrouk 2014's suboptimal fading factor (eq. 67-70; Xia et al. 1994), on traces.

    ``V_k = (rho V_{k-1} + tr_vv) / (1 + rho)`` (``V_0 = tr_vv``; steps without measurements
    enter with ``tr_vv = 0`` and ``lambda = 1``), ``N = gamma V - beta tr_R - tr_HQH``,
    ``lambda = max(1, N / tr_M)``: :func:`filters.adaptive.suboptimal_fading_factor` on 1x1
    "trace matrices". Parameters: forgetting ``rho`` in (0, 1), softening ``beta > 0`` on R,
    weight ``gamma > 0`` on V. Applied one step later (module docstring).
    """

    name = "suboptimal"
    defaults = {"rho": 0.95, "beta": 1.0, "gamma": 1.0}

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"V": np.zeros(B), "k": np.zeros(B, dtype=np.int64)}

    def _terms(self, tr: dict[str, np.ndarray]) -> FadingTerms:
        used = tr["tr_R"] > 0
        col = lambda x: x[:, None, None]  # noqa: E731
        return FadingTerms(
            np.sqrt(tr["tr_vv"])[:, None], col(tr["tr_M"]), col(tr["tr_HQH"]), col(tr["tr_R"]), used[:, None]
        )

    def _formula(self, mem: FadingMemory, terms: FadingTerms, B: int) -> tuple[np.ndarray, FadingMemory]:
        return suboptimal_fading_factor(
            mem, terms, rho=self.param("rho", B), beta=self.param("beta", B), gamma=self.param("gamma", B)
        )

    def factor(self, tr, memory, fresh):
        B = tr["tr_vv"].shape[0]
        mem = FadingMemory(memory["V"][:, None, None], memory["k"])
        lam, new = self._formula(mem, self._terms(tr), B)
        keep = fresh  # the reset observation carries no innovation: do not absorb it
        V = np.where(keep, memory["V"], new.V[:, 0, 0])
        k = np.where(keep, memory["k"], new.k)
        return lam, {"V": V, "k": k}


class StrongTracking(SuboptimalFading):
    """Single-factor strong tracking filter (Zhou & Frank 1996), on traces.

    :func:`filters.adaptive.strong_tracking_factor`: the suboptimal factor with ``gamma = 1``
    and softening ``beta >= 1``; forgetting ``rho`` (0.95 in the paper).
    """

    name = "strong_tracking"
    defaults = {"rho": 0.95, "beta": 1.0}

    def _formula(self, mem, terms, B):
        return strong_tracking_factor(mem, terms, rho=self.param("rho", B), beta=self.param("beta", B))


class SageHusaFading(FadingBaseline):
    """Fading factor from a Sage-Husa-weighted innovation covariance estimate.

    What it is, exactly: a running estimate ``C_k`` of the innovation covariance trace with the
    Sage-Husa weights ``d_k = (1 - b) / (1 - b^(k+1))`` (Sage & Husa 1969; the weights of
    :func:`filters.adaptive.sage_husa_update`), counting only steps with measurements (steps
    without any keep ``C`` and ``k``, as the Sage-Husa R estimate keeps masked entries)::

        C_k = (1 - d_k) C_{k-1} + d_k tr_vv          (d_0 = 1: C_0 = tr_vv)
        lambda = max(1, (C_k - beta tr_R - tr_HQH) / tr_M)

    i.e. the factor that makes the predicted innovation covariance trace
    ``lambda tr_M + tr_HQH + beta tr_R`` match the estimate. Against :class:`SuboptimalFading`
    it differs in the averaging (growing memory ``1/(k+1)`` at the start, then an exponential
    window ``1 - b``) and in holding through outages. Parameters: forgetting ``b`` in (0, 1),
    softening ``beta > 0``.
    """

    name = "sage_husa"
    defaults = {"b": 0.95, "beta": 1.0}

    def setup(self, env: NavigationAPI) -> None:
        super().setup(env)
        b = self.params["b"]
        if not ((b > 0).all() and (b < 1).all()):
            raise ValueError("b must lie in (0, 1)")
        if not (self.params["beta"] > 0).all():
            raise ValueError("beta must be > 0")

    def init_memory(self, B: int) -> dict[str, np.ndarray]:
        return {"C": np.zeros(B), "k": np.zeros(B, dtype=np.int64)}

    def factor(self, tr, memory, fresh):
        B = tr["tr_vv"].shape[0]
        b, beta = self.param("b", B), self.param("beta", B)
        used = (tr["tr_R"] > 0) & ~fresh
        k = memory["k"]
        d = (1.0 - b) / (1.0 - b ** (k + 1))
        C = np.where(used, (1.0 - d) * memory["C"] + d * tr["tr_vv"], memory["C"])
        k = np.where(used, k + 1, k)
        num = C - beta * tr["tr_R"] - tr["tr_HQH"]
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = num / tr["tr_M"]
        ok = used & (tr["tr_M"] > 0) & np.isfinite(ratio)
        lam = np.where(ok, np.maximum(ratio, 1.0), 1.0)
        return lam, {"C": C, "k": k}
