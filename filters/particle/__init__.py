"""Particle filters, batched over B filters and N particles, with log-weights.

Modules:

* :mod:`~filters.particle.bootstrap`: the bootstrap / SIR filter (Touil & Ghadi 2012, eq. 15-17;
  Carvalho et al. 1997, §III-A): ``predict``, ``update`` (with the age-weighting factor of
  Carvalho et al. 1997, Example 1 as the ``forgetting`` knob), ``resample`` with a per-filter
  decision ``(B,)``;
* :mod:`~filters.particle.triggers`: ESS threshold and Carvalho et al. 1997's redistribution rule;
* :mod:`~filters.particle.regularization`: Carvalho et al. 1997, §III-B regularization (age weighting,
  window of T terms) and position jitter (roughening, regularized-PF kernel);
* :mod:`~filters.particle.exploration`: n-conditional exploration with M auxiliary particles
  (Carvalho et al. 1997, §III-C);
* :mod:`~filters.particle.rao_blackwell`: Rao-Blackwellized PF, a Kalman filter per particle;
* :mod:`~filters.particle.dirac_gauss`: Dirac-Gauss PFs for hybrid discrete / continuous
  systems (Dirac-Gauss DPF n.d., §2): the random filter (an EKF per particle, sampled modes and jumps) and
  the deterministic one (branching over modes and a jump grid, maximum-likelihood selection);
* :mod:`~filters.particle.estimates`: weighted mean and covariance, ESS, health.

Resampling schemes live in :mod:`filters.core.resampling`.
"""

from filters.particle.bootstrap import (
    from_gaussian,
    particle_log_likelihood,
    predict,
    resample,
    update,
)
from filters.particle.estimates import (
    covariance,
    ess,
    healthy,
    logsumexp,
    mean,
    mean_and_covariance,
    normalize_log_weights,
    weights,
)
from filters.particle.exploration import explore
from filters.particle.rao_blackwell import (
    ConditionallyLinearModel,
    LinearSplitModel,
    RBParticleState,
    split_linear_model,
)
from filters.particle.regularization import (
    LikelihoodWindow,
    age_weight,
    kernel_jitter,
    optimal_bandwidth,
    roughen,
    window_init,
    window_resample,
    window_update,
)
from filters.particle.triggers import ess_trigger, redistribution_trigger

__all__ = [
    "ConditionallyLinearModel",
    "LikelihoodWindow",
    "LinearSplitModel",
    "RBParticleState",
    "age_weight",
    "covariance",
    "ess",
    "ess_trigger",
    "explore",
    "from_gaussian",
    "healthy",
    "kernel_jitter",
    "logsumexp",
    "mean",
    "mean_and_covariance",
    "normalize_log_weights",
    "optimal_bandwidth",
    "particle_log_likelihood",
    "predict",
    "redistribution_trigger",
    "resample",
    "roughen",
    "split_linear_model",
    "update",
    "weights",
    "window_init",
    "window_resample",
    "window_update",
]
