"""The Fading task: the agent sets the fading factor of a Gaussian filter each step.

The fading factor ``lambda >= 1`` of any Gaussian filter of :mod:`filters.registry` is applied at
each prediction (``P- = lambda F P F^T + Q``; Benzerrouk 2014, eq. 63-70, gives the classical
formulas). The action ``a in [-1, 1]`` maps log-linearly: ``lambda = lambda_max ** ((a + 1) / 2)``
(``a = -1`` is the plain filter). The observation carries the four traces the classical fading
formulas need (:func:`fading_traces`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState, kalman
from navgym.envs.arguments import Argument, Real
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels, TaskStep, TrueNoise
from navgym.envs.tasks.base import (
    CLAIRVOYANT,
    CLAIRVOYANT_TEXT,
    GaussianTask,
    clairvoyant_update,
    filter_argument,
    runnable_filters,
)
from navgym.envs.tasks.registry import TaskSpec, register_task


class FadingDiagnostics(NamedTuple):
    """The Fading task's diagnostics of a step (keys of ``info``; the traces feed the features)."""

    fading: np.ndarray  #: (B,) the applied factor lambda
    tr_vv: np.ndarray  #: (B,) |v|^2 over the rows used
    tr_R: np.ndarray  #: (B,) tr R over the rows used
    tr_HQH: np.ndarray  #: (B,) tr(H Q H^T) over the rows used
    tr_M: np.ndarray  #: (B,) tr(H F P F^T H^T) over the rows used


def fading_traces(
    pred: GaussianState, info: Any, models: StepModels, lam: np.ndarray, H: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """Traces over the used rows that the classical fading formulas need (Benzerrouk 2014, eq. 67-70).

    ``tr_vv = |v|^2``, ``tr_R``, ``tr_HQH = tr(H Q H^T)`` with ``H`` the observation Jacobian at
    the predicted mean, and ``tr_M = tr(H F P F^T H^T) = (tr S - tr R - tr HQH) / lambda`` from
    the innovation covariance ``S = H (lambda F P F^T + Q) H^T + R`` of the applied factor. A
    baseline keeps its own ``V_k`` recursion on ``tr_vv`` (traces are linear), so these four
    numbers per step are all the formulas need; they are published in the observation. ``H``,
    when given, is that Jacobian (else it is evaluated).
    """
    w = models.mask.astype(np.float64)
    R = np.broadcast_to(models.observation.R, info.S.shape)
    tr_R = np.einsum("bii,bi->b", R, w)
    B, m, n = w.shape[0], w.shape[1], pred.m.shape[1]
    H = np.broadcast_to(models.observation.H(pred.m) if H is None else H, (B, m, n))
    Q = np.asarray(models.transition.Q)
    HQ = (H.reshape(B * m, n) @ Q).reshape(B, m, n) if Q.ndim == 2 else H @ Q
    tr_HQH = np.einsum("bjk,bjk,bj->b", HQ, H, w)
    tr_S = np.einsum("bii,bi->b", info.S, w)
    tr_M = np.maximum(tr_S - tr_R - tr_HQH, 0.0) / lam
    return {"tr_vv": (info.innovation**2 * w).sum(axis=1), "tr_R": tr_R, "tr_HQH": tr_HQH, "tr_M": tr_M}


#: The Fading task's keyword arguments.
ARGUMENTS = (
    filter_argument("ekf"),
    Argument(
        "lambda_max",
        10.0,
        Real(1.0, low_open=True),
        "the largest fading factor (a = 1); a platform may default it per second of filtering",
    ),
    CLAIRVOYANT,
)


class FadingTask(GaussianTask[FadingDiagnostics]):
    """The agent sets the fading factor of a Gaussian filter each step (module docstring)."""

    name = "Fading"
    baseline_family = "Fading"

    def __init__(
        self,
        filter: str = "ekf",
        lambda_max: float = 10.0,
        clairvoyant: bool = False,
    ) -> None:
        filt = self.gaussian_filter(filter)
        self.lambda_max = ARGUMENTS[1].check(lambda_max)
        super().__init__(filter, filt, clairvoyant, 1)
        #: The update takes the Jacobian at the predicted mean, evaluated once for it and the traces.
        self._takes_jacobian = filt.update is kalman.update

    def knob_of(self, a: np.ndarray) -> np.ndarray:
        return self.lambda_max ** ((a[:, 0] + 1.0) / 2.0)

    def neutral_knob(self, B: int) -> np.ndarray:
        return np.ones(B)

    def neutral_action(self) -> np.ndarray:
        return np.array([-1.0], dtype=np.float32)

    def predict(
        self, state: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> GaussianState:
        if truth is not None:
            return super().predict(state, knob, models, truth)
        return self.filter.predict(state, models.transition, None, models.dt, fading=knob)

    def update(
        self, pred: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> tuple[GaussianState, Any, FadingDiagnostics]:
        if truth is not None:
            post, info = clairvoyant_update(self.filter, pred, models, truth)
            H = None
        else:
            H = models.observation.H(pred.m)  # once: for the update and for the traces
            if self._takes_jacobian:
                post, info = kalman.update(pred, models.z, models.observation, mask=models.mask, H=H)
            else:
                post, info = self.filter.update(pred, models.z, models.observation, mask=models.mask)
        return post, info, FadingDiagnostics(knob, **fading_traces(pred, info, models, knob, H))

    def features(self) -> list[Feature]:
        return [
            Feature(name, -8.0, 12.0, "log10", text)
            for name, text in (
                ("log_tr_vv", "log10 |v|^2 over the rows used (innovation energy)"),
                ("log_tr_R", "log10 tr R over the rows used"),
                ("log_tr_HQH", "log10 tr(H Q H^T) over the rows used (Benzerrouk 2014, eq. 68)"),
                ("log_tr_M", "log10 tr(H F P F^T H^T) over the rows used (Benzerrouk 2014, eq. 69)"),
            )
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {f.name: np.zeros(B) for f in self.features()}

    def feature_values(self, step: TaskStep[GaussianState, FadingDiagnostics]) -> dict[str, np.ndarray]:
        d = step.diagnostics
        return {
            "log_tr_vv": np.log10(np.maximum(d.tr_vv, 1e-8)),
            "log_tr_R": np.log10(np.maximum(d.tr_R, 1e-8)),
            "log_tr_HQH": np.log10(np.maximum(d.tr_HQH, 1e-8)),
            "log_tr_M": np.log10(np.maximum(d.tr_M, 1e-8)),
        }


def _lambda_max(platform_spec: Any) -> str:
    lam = platform_spec.lambda_max_per_second
    return "10.0" if lam is None else f"{lam**platform_spec.dt:.4g}"


#: The Fading task's declaration.
FADING = register_task(
    TaskSpec(
        name="fading",
        title="Fading",
        cls=FadingTask,
        arguments=ARGUMENTS,
        action_text=(
            "``Fading``: ``Box(-1, 1, (1,), float32)``, ``lambda = lambda_max ** ((a + 1) / 2)`` applied as "
            "``P- = lambda F P F^T + Q`` at every {dt:g} s step (``a = -1``: the plain filter). "
            "``lambda >= 1``: fading can only inflate the predicted covariance, so it can only raise "
            "the gain (trust the measurements more), never lower it for a bad row; no Fading id enters "
            "v3 (told the events, a fading factor gains nothing over the best tuned baseline on the v2 "
            "Fading ids: ``experiments/knob_reach``; the per-row knob is RowScale)."
        ),
        argument_text=(
            '``Fading``: ``filter="ekf"`` (a Gaussian filter of :mod:`filters.registry` that runs on the '
            "platform's state size: {filters}), ``lambda_max={lambda_max}``, ``clairvoyant=False``"
        ),
        baseline="Fading",
        clairvoyant=True,
        card_note=CLAIRVOYANT_TEXT,
        platform_defaults=lambda spec, platform: (
            {}
            if spec.lambda_max_per_second is None
            else {"lambda_max": spec.lambda_max_per_second**platform.dt}
        ),
        card_fields=lambda spec: {
            "lambda_max": _lambda_max(spec),
            "filters": runnable_filters(spec, "fading"),
        },
    )
)
