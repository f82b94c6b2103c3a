"""Episode scenarios: what degrades in an episode, sampled at reset and pinnable.

Public API:

* ``Scenario`` (frozen) with ``Outage``, ``PartialOutage``, ``ImpulsiveNoise``, ``Jamming``,
  ``OutlierSatellites`` intervals and the v2 events ``MotionBurst``, ``Multipath``,
  ``UrbanCanyon``; ``critical_scenario()`` (Carvalho et al. 1997, §V, 50 deg, 3600 s);
  constants ``CRITICAL_MASK_DEG``, ``CRITICAL_DURATION_S``, ``CRITICAL_DT_S``, ``MAX_PRN``
* ``ScenarioDistribution`` (frozen) with ``sample(rng) -> Scenario``,
  ``sample_many(seeds_or_rngs)``, ``sample_batch(seeds_or_rngs) -> ScenarioBatch``;
  ``BENZERROUK_VARIANCE_RATIOS`` (deprecated alias ``SEED001_VARIANCE_RATIOS``), ``OUTAGE_DURATIONS_S``
* ``stack_scenarios(scenarios) -> ScenarioBatch`` and the vectorized evaluators, for ``t``
  scalar, ``(B,)`` or ``(B, T)``: ``gnss_available``, ``max_satellites``,
  ``satellite_row_mask``, ``noise_regime -> NoiseRegimeParams`` (keyword arguments of
  ``navgym.gnss.make_regime``), ``motion_burst``, ``multipath_error``, ``canyon_regime``,
  ``degradation_flags``
* seeding: ``as_generators``, ``standard_normal_batch``, ``NormalStream``; ``default_rngs(seeds)``
  (``np.random.default_rng`` for many integer seeds at once, the same generators)
"""

from navgym.scenarios.batch import (
    BURST,
    CANYON,
    IMPULSIVE,
    JAMMING,
    MULTIPATH,
    OUTAGE,
    OUTLIERS,
    PARTIAL_OUTAGE,
    NoiseRegimeParams,
    ScenarioBatch,
    canyon_regime,
    degradation_flags,
    gnss_available,
    max_satellites,
    motion_burst,
    multipath_error,
    noise_regime,
    satellite_row_mask,
    stack_scenarios,
)
from navgym.scenarios.distribution import (
    BENZERROUK_VARIANCE_RATIOS,
    OUTAGE_DURATIONS_S,
    SEED001_VARIANCE_RATIOS,  # deprecated alias of BENZERROUK_VARIANCE_RATIOS
    ScenarioDistribution,
)
from navgym.scenarios.scenario import (
    CRITICAL_DT_S,
    CRITICAL_DURATION_S,
    CRITICAL_MASK_DEG,
    MAX_PRN,
    ImpulsiveNoise,
    Jamming,
    MotionBurst,
    Multipath,
    Outage,
    OutlierSatellites,
    PartialOutage,
    Scenario,
    UrbanCanyon,
    critical_scenario,
)
from navgym.scenarios.seed_sequence import default_rngs
from navgym.scenarios.seeding import NormalStream, as_generators, standard_normal_batch

__all__ = [
    "Scenario",
    "Outage",
    "PartialOutage",
    "ImpulsiveNoise",
    "Jamming",
    "OutlierSatellites",
    "MotionBurst",
    "Multipath",
    "UrbanCanyon",
    "critical_scenario",
    "CRITICAL_MASK_DEG",
    "CRITICAL_DURATION_S",
    "CRITICAL_DT_S",
    "MAX_PRN",
    "ScenarioDistribution",
    "BENZERROUK_VARIANCE_RATIOS",
    "SEED001_VARIANCE_RATIOS",
    "OUTAGE_DURATIONS_S",
    "ScenarioBatch",
    "NoiseRegimeParams",
    "stack_scenarios",
    "gnss_available",
    "max_satellites",
    "satellite_row_mask",
    "noise_regime",
    "motion_burst",
    "multipath_error",
    "canyon_regime",
    "degradation_flags",
    "OUTAGE",
    "PARTIAL_OUTAGE",
    "IMPULSIVE",
    "JAMMING",
    "OUTLIERS",
    "BURST",
    "MULTIPATH",
    "CANYON",
    "default_rngs",
    "as_generators",
    "standard_normal_batch",
    "NormalStream",
]
