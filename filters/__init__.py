"""Batched Bayesian filters: pure step functions on NamedTuple states, NumPy/SciPy plus Numba kernels.

Layers: :mod:`filters.core` (state types, linear algebra, quadrature rules, conditioning,
resampling, normals, validation, and the compiled kernels of the hot loops with the switch that
forces their NumPy twins, :mod:`filters.core.compiled`) and one module per family:
:mod:`filters.kalman` (KF, EKF, iterated EKF), :mod:`filters.sigma_point` (UKF, CKF, GHKF),
:mod:`filters.divided_difference` (DD1, DD2), :mod:`filters.information` (EIF, CIF),
:mod:`filters.adaptive` (fading formulas, strong tracking, Sage-Husa),
:mod:`filters.gaussian_sum` (GM filters, mixture reduction), :mod:`filters.row_mixture` (per-row
outlier mixtures), :mod:`filters.innovation_adaptive` (IAE of R, chi-square exclusion),
:mod:`filters.robust` (Huber/Tukey M-estimation) and :mod:`filters.particle` (bootstrap,
regularized, n-conditional, Rao-Blackwellized and Dirac-Gauss PFs). Every array carries the batch
axis first; ``docs/architecture.md`` ("filters") states the contracts.
"""

from filters.core.models import LinearGaussianModel, LinearTransition, ObservationModel, TransitionModel
from filters.core.quadrature import Cubature, GaussHermite, SigmaPoints, Unscented
from filters.core.types import (
    GaussianState,
    InformationState,
    MeasurementMoments,
    MixtureState,
    ParticleState,
    UpdateInfo,
)
from filters.registry import FILTERS, GaussianFilter, get

__all__ = [
    "FILTERS",
    "Cubature",
    "GaussHermite",
    "GaussianFilter",
    "GaussianState",
    "InformationState",
    "LinearGaussianModel",
    "LinearTransition",
    "MixtureState",
    "ObservationModel",
    "ParticleState",
    "SigmaPoints",
    "TransitionModel",
    "Unscented",
    "UpdateInfo",
    "MeasurementMoments",
    "get",
]
