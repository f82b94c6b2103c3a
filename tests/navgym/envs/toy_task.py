"""A toy task written as docs/add_a_task.md says: one file, one registration line.

``RScale``: the agent scales the measurement noise of a Gaussian filter, ``R' = s R`` with
``s = 10 ** (decades a)`` for ``a in [-1, 1]`` (``a = 0``: the plain filter). It is a
:class:`GaussianTask` (so the clairvoyant reference, the ``filter`` argument and the isolation
of rows that overflow come with it): its knob, its update with the knob, its diagnostics and
features, and its :class:`TaskSpec`, registered by the last line. Its tests are in
``test_toy_registration.py``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from navgym.envs.arguments import Argument, Real
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels, TaskStep, TrueNoise
from navgym.envs.tasks import TaskSpec, register_task
from navgym.envs.tasks.base import (
    CLAIRVOYANT,
    CLAIRVOYANT_TEXT,
    GaussianTask,
    clairvoyant_update,
    filter_argument,
)


class RScaleDiagnostics(NamedTuple):
    r_scale: np.ndarray  # (B,) the applied s: a key of info, the feature's input


ARGUMENTS = (
    filter_argument("ekf"),
    Argument("decades", 1.0, Real(0.0, 6.0, low_open=True), "s spans 10**-decades to 10**decades"),
    CLAIRVOYANT,
)


class RScaleTask(GaussianTask[RScaleDiagnostics]):
    name = "RScale"
    baseline_family = "RScale"

    def __init__(self, filter: str = "ekf", decades: float = 1.0, clairvoyant: bool = False) -> None:
        filt = self.gaussian_filter(filter)
        self.decades = ARGUMENTS[1].check(decades)
        super().__init__(filter, filt, clairvoyant, 1)

    def knob_of(self, a: np.ndarray) -> np.ndarray:
        return 10.0 ** (self.decades * a[:, 0])

    def neutral_knob(self, B: int) -> np.ndarray:
        return np.ones(B)

    def neutral_action(self) -> np.ndarray:
        return np.zeros(1, dtype=np.float32)

    def update(
        self, pred: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> tuple[GaussianState, Any, RScaleDiagnostics]:
        if truth is not None:
            post, info = clairvoyant_update(self.filter, pred, models, truth)
        else:
            R = knob[:, None, None] * np.asarray(models.observation.R)
            post, info = self.filter.update(pred, models.z, models.observation, mask=models.mask, R=R)
        return post, info, RScaleDiagnostics(knob)

    def features(self) -> list[Feature]:
        return [
            Feature("log_r_scale", -self.decades, self.decades, "log10", "log10 s, the applied scale of R")
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {"log_r_scale": np.zeros(B)}

    def feature_values(self, step: TaskStep[GaussianState, RScaleDiagnostics]) -> dict[str, np.ndarray]:
        return {"log_r_scale": np.log10(step.diagnostics.r_scale)}


R_SCALE = register_task(
    TaskSpec(
        name="rscale",
        title="RScale",
        cls=RScaleTask,
        arguments=ARGUMENTS,
        action_text="``RScale``: ``Box(-1, 1, (1,), float32)``, ``R' = 10 ** (decades a) R`` every {dt:g} s.",
        argument_text='``RScale``: ``filter="ekf"``, ``decades=1.0``, ``clairvoyant=False``',
        baseline="RScale",
        clairvoyant=True,
        card_note=CLAIRVOYANT_TEXT,
    )
)
