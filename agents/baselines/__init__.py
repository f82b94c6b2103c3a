"""Classical hand-tuned baselines with SB3's ``predict``: what learned agents must beat.

* Fading (``*Fading-v*``): :class:`ConstantFading` (``plain``: lambda = 1; ``constant``),
  :class:`SuboptimalFading` (Benzerrouk 2014, eq. 67-70), :class:`StrongTracking` (Zhou & Frank 1996),
  :class:`SageHusaFading`.
* Mixture (``*Mixture-v*``): ``zero``, ``nominal``, ``constant`` (:class:`FixedContamination`),
  :class:`InnovationContamination`, :class:`PosteriorContamination`.
* NoiseScale (``*NoiseScale-v2``): ``plain``, ``constant`` (:class:`ConstantScale`),
  :class:`IaeScale` (Mehra 1970; Mohamed & Schwarz 1999), :class:`SageHusaScale`, :class:`NisQScale`.
* Per-row Mixture (``*Mixture-v2``, registry key ``"RowMixture"``): ``zero``, ``constant``
  (:class:`RowConstant`), :class:`RowChiSquare`, :class:`RowInnovationAverage`, :class:`RowHuber`.
* Robust (``*Robust-v2``): ``plain`` and ``constant`` (:class:`ConstantThreshold`), ``seed``
  (:class:`SeedThreshold`: 1.345 Huber / 4.685 Tukey, Belles et al. 2022), :class:`ChiSquareThreshold`.
* Jumps (``SignalTrackingJumps-v2``): ``plain`` and ``constant`` (:class:`ConstantJump`),
  :class:`LikelihoodJump` (a jump detector on the filter's likelihood).
* Resample (``*Resample-v*``): :class:`NeverResample`, :class:`AlwaysResample`,
  :class:`EssThreshold`, :class:`RedistributionRule` (Carvalho et al. 1997).
* :class:`HindsightOracle`, :class:`GreedyOracle`: read truth; references, never baselines.
* :class:`ConstantAction`: the same action every step (the plain filter, or a grid of constant
  knobs in one rollout), for any task.

Baselines read only observations. Build them with :func:`make_baselines` (tuned parameters from
:func:`load_tuned`) or :func:`make_baseline`.
"""

from agents.baselines.base import BaselinePolicy, navigation_env, task_name
from agents.baselines.constant import ConstantAction
from agents.baselines.fading import (
    ConstantFading,
    SageHusaFading,
    StrongTracking,
    SuboptimalFading,
    decode_traces,
    lambda_to_action,
)
from agents.baselines.jumps import ConstantJump, LikelihoodJump
from agents.baselines.mixture import (
    FixedContamination,
    InnovationContamination,
    NominalContamination,
    PosteriorContamination,
    ZeroContamination,
    eps_to_action,
    nominal_contamination,
)
from agents.baselines.noise_scale import ConstantScale, IaeScale, NisQScale, SageHusaScale, scales_to_action
from agents.baselines.oracle import GreedyOracle, HindsightOracle
from agents.baselines.registry import (
    BASELINES,
    TUNED_DIR,
    BaselineSpec,
    baseline_specs,
    baseline_task,
    load_tuned,
    make_baseline,
    make_baselines,
    tuned_path,
)
from agents.baselines.resample import AlwaysResample, EssThreshold, NeverResample, RedistributionRule
from agents.baselines.robust import ChiSquareThreshold, ConstantThreshold, SeedThreshold
from agents.baselines.row_mixture import (
    RowChiSquare,
    RowConstant,
    RowHuber,
    RowInnovationAverage,
    row_eps_to_action,
)

__all__ = [
    "ConstantJump",
    "LikelihoodJump",
    "ChiSquareThreshold",
    "ConstantThreshold",
    "SeedThreshold",
    "scales_to_action",
    "row_eps_to_action",
    "baseline_task",
    "RowInnovationAverage",
    "RowHuber",
    "RowConstant",
    "RowChiSquare",
    "SageHusaScale",
    "NisQScale",
    "IaeScale",
    "ConstantScale",
    "BASELINES",
    "TUNED_DIR",
    "AlwaysResample",
    "BaselinePolicy",
    "BaselineSpec",
    "ConstantAction",
    "ConstantFading",
    "EssThreshold",
    "FixedContamination",
    "GreedyOracle",
    "HindsightOracle",
    "InnovationContamination",
    "NeverResample",
    "NominalContamination",
    "PosteriorContamination",
    "RedistributionRule",
    "SageHusaFading",
    "StrongTracking",
    "SuboptimalFading",
    "ZeroContamination",
    "baseline_specs",
    "navigation_env",
    "decode_traces",
    "eps_to_action",
    "lambda_to_action",
    "load_tuned",
    "make_baseline",
    "make_baselines",
    "nominal_contamination",
    "task_name",
    "tuned_path",
]
