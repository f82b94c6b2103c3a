"""The Mixture task: the agent sets the outlier weight of a Gaussian-sum filter's noise mixture.

The prior weight ``eps`` of the outlier component of a two-component Gaussian-mixture
measurement noise ``(1 - eps) N(0, R) + eps N(0, ratio R)`` (Benzerrouk 2014, eq. 71) in a
Gaussian-sum filter (eq. 72-76), ``eps = eps_max (a + 1) / 2``. With ``per_row=True`` (v2) one
weight per measurement row, ``Box(-1, 1, (m_max,))``, ``eps_i = eps_max (a_i + 1) / 2`` on the
platform's outlier rows (0 on the others), applied by the sequential per-row mixture update
:func:`filters.row_mixture.update`; the observation then carries each row's posterior outlier
weight.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from filters import GaussianState, gaussian_sum, row_mixture
from navgym.envs.arguments import Argument, Flag, Integer, Real
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels, TaskStep, TrueNoise
from navgym.envs.tasks.base import (
    CLAIRVOYANT,
    CLAIRVOYANT_TEXT,
    GaussianTask,
    clairvoyant_update,
    filter_argument,
)
from navgym.envs.tasks.registry import TaskSpec, register_task


class MixtureDiagnostics(NamedTuple):
    """The Mixture task's diagnostics of a step (keys of ``info``)."""

    eps: np.ndarray  #: (B,) or (B, m_max) the applied outlier weights
    #: (B,) posterior weight of the outlier component, or (B, m_max) per row (0 on masked rows)
    outlier_posterior: np.ndarray


#: The Mixture task's keyword arguments.
ARGUMENTS = (
    filter_argument("ckf"),
    Argument(
        "eps_max",
        0.5,
        Real(0.0, 1.0, low_open=True, high_open=True),
        "the largest outlier weight (a = 1)",
    ),
    Argument("variance_ratio", 100.0, Real(1.0, low_open=True), "the outlier component's R / the nominal R"),
    Argument(
        "per_row",
        False,
        Flag(),
        "one weight per measurement row (Box(-1, 1, (m_max,))), each row's posterior weight observed",
        opt_in=True,
    ),
    CLAIRVOYANT,
)
_EPS_MAX, _RATIO, _PER_ROW = ARGUMENTS[1], ARGUMENTS[2], ARGUMENTS[3]


class MixtureTask(GaussianTask[MixtureDiagnostics]):
    """The agent sets the outlier weight of a Gaussian-sum filter's noise mixture each step.

    One weight for every outlier row (v0/v1), or one per row with ``per_row=True`` (v2; needs the
    platform's ``m_max``).
    """

    name = "Mixture"

    def __init__(
        self,
        filter: str = "ckf",
        eps_max: float = 0.5,
        variance_ratio: float = 100.0,
        outlier_rows: tuple[int, ...] | None = None,
        per_row: bool = False,
        m_max: int | None = None,
        clairvoyant: bool = False,
    ) -> None:
        filt = self.gaussian_filter(filter)
        self.eps_max = _EPS_MAX.check(eps_max)
        self.variance_ratio = _RATIO.check(variance_ratio)
        #: Rows subject to impulsive noise, the platform's ``outlier_rows`` (None: every row).
        self.outlier_rows = None if outlier_rows is None else tuple(int(r) for r in outlier_rows)
        #: One weight per measurement row (v2), applied by :func:`filters.row_mixture.update`.
        self.per_row = _PER_ROW.check(per_row)
        super().__init__(filter, filt, clairvoyant, 1)
        #: The base filter of the Gaussian sum (also the clairvoyant's plain filter).
        self.base = filt
        #: The baselines of a per-row task act on one weight per row.
        self.baseline_family = "RowMixture" if self.per_row else "Mixture"
        self.m_max: int | None = None
        if self.per_row:
            if m_max is None:
                raise ValueError("per_row=True needs the platform's m_max (the rows of the action)")
            self.m_max = Integer(1).check("m_max", m_max)
            rows = range(self.m_max) if self.outlier_rows is None else self.outlier_rows
            if any(not 0 <= r < self.m_max for r in rows):
                raise ValueError(f"outlier_rows must lie in [0, {self.m_max - 1}]; got {self.outlier_rows}")
            #: (m_max,) 1.0 on the outlier rows, 0.0 elsewhere (their weight is always 0).
            self.row_weights = np.zeros(self.m_max)
            self.row_weights[list(rows)] = 1.0
            self.action_space = spaces.Box(-1.0, 1.0, shape=(self.m_max,), dtype=np.float32)

    def knob_of(self, a: np.ndarray) -> np.ndarray:
        """``eps (B,)``, or ``(B, m_max)`` per row (0 on the rows that are not outlier rows)."""
        if self.per_row:
            return self.eps_max * (a + 1.0) / 2.0 * self.row_weights
        return self.eps_max * (a[:, 0] + 1.0) / 2.0

    def neutral_knob(self, B: int) -> np.ndarray:
        return np.zeros(B if self.m_max is None else (B, self.m_max))

    def neutral_action(self) -> np.ndarray:
        return np.full(self.action_space.shape or (1,), -1.0, dtype=np.float32)

    def update(
        self, pred: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> tuple[GaussianState, Any, MixtureDiagnostics]:
        if truth is not None:
            post, info = clairvoyant_update(self.base, pred, models, truth)
            return post, info, MixtureDiagnostics(knob, np.zeros(knob.shape))
        if self.per_row:
            post, info = row_mixture.update(
                pred,
                models.z,
                models.observation,
                models.mask,
                eps=knob,
                variance_ratio=self.variance_ratio,
                base=self.base,
            )
            return post, info, MixtureDiagnostics(knob, np.where(models.mask, info.outlier_posterior, 0.0))
        R = np.asarray(models.observation.R)  # (m, m) shared or (B, m, m)
        # The outlier component inflates the rows the platform declares as impulsive (default:
        # all): R2 = D R D with D = sqrt(ratio) on those rows, 1 elsewhere (Benzerrouk 2014,
        # eq. 71 per row).
        d = np.ones(R.shape[-1])
        rows = self.outlier_rows
        d[slice(None) if rows is None else list(rows)] = np.sqrt(self.variance_ratio)
        # (K, m, m) when R is shared by the batch (no per-step (B, K, m, m) copy), else (B, K, m, m)
        R_components = np.stack([R, d[:, None] * R * d[None, :]], axis=-3)
        weights = np.stack([1.0 - knob, knob], axis=1)
        post, info = gaussian_sum.update(
            pred,
            models.z,
            models.observation,
            models.mask,
            R_components=R_components,
            weights=weights,
            base=self.base,
        )
        return post, info, MixtureDiagnostics(knob, np.exp(info.log_weights[:, 1]))

    def features(self) -> list[Feature]:
        if self.per_row:
            return [
                Feature(
                    "outlier_posterior",
                    0.0,
                    1.0,
                    "-",
                    "per row, posterior weight of its outlier noise component (eq. 74; 0 on rows "
                    "not received)",
                    self.m_max or 1,
                )
            ]
        return [
            Feature(
                "outlier_posterior", 0.0, 1.0, "-", "posterior weight of the outlier noise component (eq. 74)"
            )
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {"outlier_posterior": np.zeros(B if self.m_max is None else (B, self.m_max))}

    def feature_values(self, step: TaskStep[GaussianState, MixtureDiagnostics]) -> dict[str, np.ndarray]:
        return {"outlier_posterior": step.diagnostics.outlier_posterior}


#: The Mixture task's declaration.
MIXTURE = register_task(
    TaskSpec(
        name="mixture",
        title="Mixture",
        cls=MixtureTask,
        arguments=ARGUMENTS,
        action_text=(
            "``Mixture``: ``Box(-1, 1, (1,), float32)``, ``eps = eps_max (a + 1) / 2``, measurement noise "
            "``(1 - eps) N(0, R) + eps N(0, variance_ratio R)`` on the outlier rows (Benzerrouk "
            "2014, eq. 71); "
            "with ``per_row=True`` one weight per measurement row, ``Box(-1, 1, (m_max,), float32)``, "
            "``eps_i = eps_max (a_i + 1) / 2`` on the outlier rows (0 on the others, masked rows ignored), "
            "applied row by row (``filters.row_mixture``)."
        ),
        argument_text=(
            '``Mixture``: ``filter="ckf"``, ``eps_max=0.5``, ``variance_ratio=100``, ``per_row=False`` '
            "(True: one weight per row, observing each row's posterior outlier weight), ``clairvoyant=False``"
        ),
        baseline="Mixture",
        clairvoyant=True,
        card_note=CLAIRVOYANT_TEXT,
        platform_defaults=lambda spec, platform: {
            "outlier_rows": platform.outlier_rows,
            "m_max": platform.m_max,
        },
    )
)
