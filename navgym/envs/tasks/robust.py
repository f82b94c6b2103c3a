"""The Robust task (v2): the agent sets the threshold of a robust iterated EKF / ESKF each step.

The threshold ``c`` of the robust iterated EKF of :func:`filters.robust.iterated_update` (Huber
or Tukey weights of the whitened residuals, Belles et al. 2022, eq. 20, Algorithm 1).
``Box(-1, 1, (1,))``, log-mapped over ``threshold_range = (c_lo, c_hi)`` (default 0.5 to 1000):
``c = 10 ** (lo + (a + 1) / 2 (hi - lo))`` for ``a < 1`` and ``c = inf`` (weights 1: the plain
iterated EKF) at ``a = 1``, the neutral action. An observation model that is an
:class:`~navgym.envs.protocols.ErrorStateObservation` (the Jpa platform's DDs) is updated in
error-state form (ESKF): the update runs on ``N(0, P-)`` with the model about the predicted
mean, and ``inject`` resets the result into the mean (Belles et al. 2022, eq. 13-17).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState, robust
from filters import get as get_filter
from navgym.envs.arguments import Argument, Choice, Integer, Interval, Real
from navgym.envs.features import Feature
from navgym.envs.protocols import ErrorStateObservation, StepModels, TaskStep, TrueNoise
from navgym.envs.tasks.base import CLAIRVOYANT, CLAIRVOYANT_TEXT, GaussianTask
from navgym.envs.tasks.noise_scale import MAX_SCALE_DECADES
from navgym.envs.tasks.registry import TaskSpec, register_task

#: The Robust task's weight functions (:data:`filters.robust.WEIGHT_FUNCTIONS`).
ROBUST_WEIGHTS = ("huber", "tukey")


class RobustDiagnostics(NamedTuple):
    """The Robust task's diagnostics of a step (keys of ``info``; they feed the features)."""

    threshold: np.ndarray  #: (B,) the applied threshold c (inf: the plain iterated EKF)
    mean_weight: np.ndarray  #: (B,) mean robust weight of the rows used
    min_weight: np.ndarray  #: (B,) smallest robust weight


#: The Robust task's keyword arguments.
ARGUMENTS = (
    Argument("weight", "huber", Choice(ROBUST_WEIGHTS), "the weight function: Huber or Tukey"),
    Argument(
        "threshold_range",
        (0.5, 1000.0),
        Interval(0.0, low_open=True),
        "(c_lo, c_hi) of the threshold, 0 < c_lo < c_hi < inf, at most 1e12 wide",
        refused=((1.0, 1.0), (1e-7, 1e7)),
    ),
    CLAIRVOYANT,
)
_MAX_ITER = Integer(1, 100)
_TOL = Real(0.0, 1.0)


class RobustTask(GaussianTask[RobustDiagnostics]):
    """The agent sets the robust threshold of an iterated EKF / ESKF each step (v2; module docstring).

    The knob ``c (B,)`` goes to :func:`filters.robust.iterated_update` (Algorithm 1 of Belles et
    al. 2022: ``W = diag w(R^{-1/2} (z - h(x)))``, Huber ``w = min(1, c / |e|)`` or Tukey
    ``w = (1 - (e / c)^2)^2`` inside ``|e| < c``, reweighted until no weight moves more than
    ``tol``); ``c = inf`` is the plain iterated EKF. The observation carries ``log10 c`` and the
    mean and smallest weight of the last update.
    """

    name = "Robust"
    baseline_family = "Robust"

    def __init__(
        self,
        weight: str = "huber",
        threshold_range: tuple[float, float] = (0.5, 1000.0),
        clairvoyant: bool = False,
        max_iter: int = 5,
        tol: float = 1e-3,
        max_inner: int = 3,
    ) -> None:
        self.weight = ARGUMENTS[0].check(weight)
        #: Gauss-Newton steps per weighting (the attitude is the only nonlinearity; 3 reach 1e-6).
        self.max_inner = _MAX_ITER.check("max_inner", max_inner)
        lo, hi = ARGUMENTS[1].check(threshold_range)
        if not (lo < hi and np.isfinite(hi) and np.log10(hi / lo) <= MAX_SCALE_DECADES):
            raise ValueError(
                f"threshold_range must be a pair (low, high) with 0 < low < high < inf and high / low "
                f"<= 1e{MAX_SCALE_DECADES:g}; got {threshold_range!r}"
            )
        self.threshold_range = (lo, hi)
        self.max_iter = _MAX_ITER.check("max_iter", max_iter)
        self.tol = _TOL.check("tol", tol)
        # the prediction is the (extended) Kalman filter's; the update is the robust iterated one
        super().__init__(f"iekf/{self.weight}", get_filter("ekf"), clairvoyant, 1)
        self.log_low, self.log_high = float(np.log10(lo)), float(np.log10(hi))

    def thresholds(self, a: np.ndarray) -> np.ndarray:
        """``c (B,)`` of actions ``a (B,)`` in [-1, 1]: log-mapped, ``inf`` at ``a = 1``."""
        c = 10.0 ** (self.log_low + (a + 1.0) / 2.0 * (self.log_high - self.log_low))
        return np.where(a >= 1.0, np.inf, c)

    def action_of(self, c: np.ndarray | float) -> np.ndarray:
        """The action ``(..., 1)`` float32 of thresholds ``c`` (``inf`` or beyond ``c_hi``: 1)."""
        c = np.asarray(c, np.float64)
        with np.errstate(divide="ignore"):
            a = -1.0 + 2.0 * (np.log10(np.clip(c, *self.threshold_range)) - self.log_low) / (
                self.log_high - self.log_low
            )
        a = np.where(c >= self.threshold_range[1], 1.0, np.clip(a, -1.0, 1.0))
        return a.astype(np.float32)[..., None]

    def knob_of(self, a: np.ndarray) -> np.ndarray:
        return self.thresholds(a[:, 0])

    def neutral_knob(self, B: int) -> np.ndarray:
        return np.full(B, np.inf)

    def neutral_action(self) -> np.ndarray:
        """``a = 1``: ``c = inf``, the plain iterated EKF."""
        return np.array([1.0], dtype=np.float32)

    def update(
        self, pred: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> tuple[GaussianState, Any, RobustDiagnostics]:
        z, R = models.z, None
        if truth is not None:
            z, R = np.asarray(models.z) - np.asarray(truth.bias), truth.R
        obs = models.observation
        eskf = isinstance(obs, ErrorStateObservation)
        prior = GaussianState(np.zeros_like(pred.m), pred.P) if eskf else pred
        model = obs.error_state(pred.m) if eskf else obs
        post, info = robust.iterated_update(
            prior,
            z,
            model,
            models.mask,
            R,
            threshold=knob,
            weight=self.weight,
            max_iter=self.max_iter,
            tol=self.tol,
            max_inner=self.max_inner,
            inner_tol=1e-6,
        )
        if eskf:
            post = GaussianState(*obs.inject(pred.m, post.m, post.P))
        n = np.maximum(models.mask.sum(axis=1), 1)
        diagnostics = RobustDiagnostics(
            knob,
            np.where(models.mask, info.weights, 0.0).sum(axis=1) / n,
            np.where(models.mask, info.weights, 1.0).min(axis=1),
        )
        return post, info, diagnostics

    def features(self) -> list[Feature]:
        return [
            Feature(
                "log_threshold",
                self.log_low,
                self.log_high,
                "log10",
                "log10 c, the applied threshold (inf: the top)",
            ),
            Feature("mean_weight", 0.0, 1.0, "-", "mean robust weight of the rows used in the last update"),
            Feature("min_weight", 0.0, 1.0, "-", "smallest robust weight of the last update"),
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        ones = np.ones(B)
        return {"log_threshold": np.full(B, self.log_high), "mean_weight": ones, "min_weight": ones.copy()}

    def feature_values(self, step: TaskStep[GaussianState, RobustDiagnostics]) -> dict[str, np.ndarray]:
        d = step.diagnostics
        return {
            "log_threshold": np.log10(np.minimum(d.threshold, 10.0**self.log_high)),
            "mean_weight": d.mean_weight,
            "min_weight": d.min_weight,
        }


#: The Robust task's declaration.
ROBUST = register_task(
    TaskSpec(
        name="robust",
        title="Robust",
        cls=RobustTask,
        arguments=ARGUMENTS,
        action_text=(
            "``Robust``: ``Box(-1, 1, (1,), float32)``, the threshold ``c = 10 ** (lo + (a + 1) "
            "/ 2 (hi - lo))`` "
            "with ``lo, hi = log10`` of ``threshold_range`` (default 0.5 to 1000) for ``a < 1`` "
            "and ``c = inf`` "
            "at ``a = 1`` (the plain iterated filter, the neutral action), applied as the threshold of the "
            "Huber (or Tukey, ``weight``) weights of the robust iterated update of every {dt:g} s step "
            "(Belles et al. 2022, eq. 20 and Algorithm 1; ``filters.robust.iterated_update``)."
        ),
        argument_text=(
            '``Robust``: ``weight="huber"`` (or ``"tukey"``), ``threshold_range=(0.5, 1000)`` '
            "(``(c_lo, c_hi)``, "
            "``0 < c_lo < c_hi < inf``), ``clairvoyant=False``"
        ),
        baseline="Robust",
        clairvoyant=True,
        card_note=CLAIRVOYANT_TEXT,
    )
)
