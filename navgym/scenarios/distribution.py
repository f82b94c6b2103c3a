"""Distribution of scenarios, sampled at reset from the episode's generator.

:class:`ScenarioDistribution` holds the probabilities and ranges of each degradation. Sampling
is deterministic per generator and uses **common random numbers**: the parent generator first
draws one sub-seed per component (outage, partial outage, impulsive noise, jamming, outliers,
mask/critical), and each component draws from its own child generator. Changing, say, the
outage probability therefore leaves the jamming intervals of the same seed unchanged, so two
configurations can be compared on paired episodes.

The v2 events (motion bursts, multipath, urban canyons; :mod:`navgym.scenarios.scenario`) draw
from generators of their own, ``np.random.default_rng([s, k])`` with the episode's sixth
component seed ``s`` (k = 1, 2, 3), built only where their probability is > 0: the parent
generator draws nothing more, so a distribution without them (the default) draws exactly what
it drew before they existed, and switching one on leaves every other component unchanged. The
same holds inside the jamming component: a second jamming interval (``jamming_count``) and the
ramp (``jamming_ramp``) are drawn only where their range is not a single value.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from navgym.envs import arguments
from navgym.scenarios.batch import ScenarioBatch, stack_scenarios
from navgym.scenarios.scenario import (
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
)
from navgym.scenarios.seed_sequence import default_rngs
from navgym.scenarios.seeding import SeedsOrGenerators, as_generators

__all__ = [
    "ScenarioDistribution",
    "BENZERROUK_VARIANCE_RATIOS",
    "SEED001_VARIANCE_RATIOS",
    "OUTAGE_DURATIONS_S",
    "MAX_OUTAGE_COUNT",
    "MAX_VAR_RATIO",
    "MAX_ERROR_M",
    "MAX_EVENT_COUNT",
    "MAX_VELOCITY_SIGMA",
    "MAX_YAW_RATE_SIGMA",
    "MAX_NOISE_SCALE",
]

#: Variance ratios sigma_2^2 / sigma_1^2 used in Benzerrouk 2014, §2.5.
BENZERROUK_VARIANCE_RATIOS: tuple[float, ...] = (50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0)
#: Deprecated alias of :data:`BENZERROUK_VARIANCE_RATIOS` (the name cited the source document by
#: its old internal label "seed 001"); kept so existing imports work. Use the new name.
SEED001_VARIANCE_RATIOS: tuple[float, ...] = BENZERROUK_VARIANCE_RATIOS
#: Typical outage lengths of the benchmarks [s] (short, medium, long).
OUTAGE_DURATIONS_S: tuple[float, ...] = (10.0, 50.0, 300.0)

#: Most full outages of one episode (the high end of ``outage_count``): sampling draws them one
#: by one, and every step of the episode looks at each of them.
MAX_OUTAGE_COUNT = 100
#: Largest impulsive-noise variance ratio (``impulsive_var_ratio``, its ``_choices``);
#: Benzerrouk 2014, §2.5 uses 50 to 2000.
MAX_VAR_RATIO = 1e6
#: Largest jamming noise and outlier size [m] (``jamming_sigma``, ``outlier_scale``), also
#: multipath bias and noise (``multipath_bias``, ``multipath_sigma``).
MAX_ERROR_M = 1e5
#: Most events of one kind per episode (``jamming_count``, ``burst_count``, ``multipath_count``,
#: ``canyon_count``): the high end of their count range.
MAX_EVENT_COUNT = 100
#: Largest burst velocity error [m/s] (``burst_velocity_sigma``).
MAX_VELOCITY_SIGMA = 100.0
#: Largest burst yaw-rate error [rad/s] (``burst_yaw_rate_sigma``).
MAX_YAW_RATE_SIGMA = 10.0
#: Largest canyon noise factor (``canyon_noise_scale``).
MAX_NOISE_SCALE = 1e3
#: Largest measurement row a multipath segment may be drawn on (``multipath_rows``).
MAX_ROW = 1023

_COMPONENTS = 6
_PROBABILITIES = (
    "critical_probability",
    "outage_probability",
    "partial_probability",
    "impulsive_probability",
    "jamming_probability",
    "outlier_probability",
)
_DURATIONS = (
    "outage_duration",
    "partial_duration",
    "impulsive_duration",
    "jamming_duration",
    "outlier_duration",
)
#: Probabilities of the v2 events (their own generators, see the module docstring).
_EVENT_PROBABILITIES = ("burst_probability", "multipath_probability", "canyon_probability")
_EVENT_DURATIONS = ("jamming_ramp", "burst_duration", "multipath_duration", "canyon_duration")
_EVENT_COUNTS = ("jamming_count", "burst_count", "multipath_count", "canyon_count")


def _rows(name: str, value) -> tuple[int, ...]:
    """``value`` as a tuple of distinct measurement rows (integers in [0, ``MAX_ROW``])."""
    ok = isinstance(value, (tuple, list, np.ndarray)) and all(
        isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) for v in value
    )
    if not ok:
        raise arguments.ArgumentTypeError(f"{name} must be a tuple of integer rows; got {value!r}")
    rows = tuple(int(v) for v in value)
    if any(r < 0 or r > MAX_ROW for r in rows) or len(set(rows)) != len(rows):
        raise ValueError(f"{name} must hold distinct rows in [0, {MAX_ROW}]; got {value!r}")
    return rows


def _component_seeds(rng: np.random.Generator) -> np.ndarray:
    """Seeds of an episode's six component generators, drawn from its generator.

    One each for outages, partial outages, impulsive noise, jamming, outliers and the mask.
    """
    return rng.integers(0, 2**63, _COMPONENTS)


@dataclass(frozen=True)
class ScenarioDistribution:
    """Probabilities and ranges of the degradations of an episode.

    Ranges are ``(low, high)`` pairs sampled uniformly (integers inclusively); a non-empty
    ``*_choices`` tuple replaces the matching range by a uniform choice among its values.
    Probabilities lie in [0, 1], durations [s] are >= 0; every number must be a finite real
    (no strings, no bools) and every count an integer (see ``__post_init__``).
    Degradations start no earlier than ``start_margin`` (time for the filter to converge).

    Attributes:
        duration: Episode length [s].
        start_margin: Earliest start of any degradation [s], within [0, duration).
        mask_deg: Range of the elevation mask [deg], within [0, 90).
        max_satellites: Receiver channels.
        critical_probability: Probability of Carvalho et al. 1997's critical 3-to-2 situation (mask 50 deg).
        outage_probability: Probability of full outages in the episode.
        outage_count: Range of their number, within [0, ``MAX_OUTAGE_COUNT``] (100).
        outage_duration: Range of their length [s].
        outage_duration_choices: Optional lengths to choose from (e.g. ``OUTAGE_DURATIONS_S``).
        partial_probability: Probability of partial outages.
        partial_satellites: Range of the satellite cap k, within [0, ``MAX_PRN``].
        partial_duration: Range of their length [s].
        impulsive_probability: Probability of an impulsive-noise period (Benzerrouk 2014, eq. 71).
        impulsive_eps: Range of the contamination eps, within [0, 1].
        impulsive_var_ratio: Range of the variance ratio (Benzerrouk 2014: 50 to 2000), within
            [1, ``MAX_VAR_RATIO``] (1e6).
        impulsive_var_ratio_choices: Optional ratios (e.g. ``BENZERROUK_VARIANCE_RATIOS``).
        impulsive_duration: Range of its length [s].
        jamming_probability: Probability of a jamming period.
        jamming_sigma: Range of the jamming noise [m], within [0, ``MAX_ERROR_M``] (1e5 m).
        jamming_loss: Range of the per-satellite loss probability.
        jamming_duration: Range of its length [s].
        outlier_probability: Probability of an outlier-satellite period.
        outlier_count: Range of the number of faulty PRNs, within [1, ``MAX_PRN``].
        outlier_rate: Range of the per-step outlier probability.
        outlier_scale: Range of the gross-error size [m], within [0, ``MAX_ERROR_M``].
        outlier_duration: Range of its length [s].
        jamming_count: Range of the number of jamming periods, within [1, ``MAX_EVENT_COUNT``]
            (a single value draws nothing: the default (1, 1) samples as before it existed).
        jamming_ramp: Range of their ramp time [s] (:class:`~navgym.scenarios.scenario.Jamming`;
            (0, 0), the default, is a step and draws nothing).
        burst_probability: Probability of unmodelled-motion bursts in the episode (v2 event).
        burst_count: Range of their number, within [1, ``MAX_EVENT_COUNT``].
        burst_duration: Range of their length [s].
        burst_velocity_sigma: Range of their horizontal velocity error [m/s], within [0,
            ``MAX_VELOCITY_SIGMA``] (100).
        burst_yaw_rate_sigma: Range of their yaw-rate error [rad/s], within [0,
            ``MAX_YAW_RATE_SIGMA``] (10).
        multipath_probability: Probability of multipath/NLOS segments (v2 event).
        multipath_count: Range of their number, within [1, ``MAX_EVENT_COUNT``].
        multipath_duration: Range of their length [s].
        multipath_bias: Range of the bias magnitude [m], within [0, ``MAX_ERROR_M``]; the sign is
            drawn (+ or -, even odds).
        multipath_sigma: Range of their extra noise [m], within [0, ``MAX_ERROR_M``].
        multipath_rows: Measurement rows a segment is drawn on (uniformly; the platform's, e.g.
            Robot2d's GNSS rows (0, 1, 2, 3)); must not be empty where ``multipath_probability > 0``.
        canyon_probability: Probability of urban-canyon segments (v2 event).
        canyon_count: Range of their number, within [1, ``MAX_EVENT_COUNT``].
        canyon_duration: Range of their length [s].
        canyon_satellites: Range of their satellite cap, within [0, ``MAX_PRN``].
        canyon_noise_scale: Range of their noise factor, within [1, ``MAX_NOISE_SCALE``].
        canyon_loss: Range of their per-fix loss probability.

    """

    duration: float = 300.0
    start_margin: float = 30.0
    mask_deg: tuple[float, float] = (10.0, 10.0)
    max_satellites: int = 12
    critical_probability: float = 0.0
    outage_probability: float = 0.5
    outage_count: tuple[int, int] = (1, 1)
    outage_duration: tuple[float, float] = (10.0, 60.0)
    outage_duration_choices: tuple[float, ...] = ()
    partial_probability: float = 0.0
    partial_satellites: tuple[int, int] = (2, 4)
    partial_duration: tuple[float, float] = (30.0, 120.0)
    impulsive_probability: float = 0.0
    impulsive_eps: tuple[float, float] = (0.005, 0.3)
    impulsive_var_ratio: tuple[float, float] = (50.0, 2000.0)
    impulsive_var_ratio_choices: tuple[float, ...] = ()
    impulsive_duration: tuple[float, float] = (30.0, 120.0)
    jamming_probability: float = 0.0
    jamming_sigma: tuple[float, float] = (10.0, 50.0)
    jamming_loss: tuple[float, float] = (0.0, 0.5)
    jamming_duration: tuple[float, float] = (10.0, 60.0)
    outlier_probability: float = 0.0
    outlier_count: tuple[int, int] = (1, 2)
    outlier_rate: tuple[float, float] = (0.1, 0.3)
    outlier_scale: tuple[float, float] = (50.0, 300.0)
    outlier_duration: tuple[float, float] = (30.0, 120.0)
    jamming_count: tuple[int, int] = (1, 1)
    jamming_ramp: tuple[float, float] = (0.0, 0.0)
    burst_probability: float = 0.0
    burst_count: tuple[int, int] = (1, 1)
    burst_duration: tuple[float, float] = (2.0, 20.0)
    burst_velocity_sigma: tuple[float, float] = (0.5, 3.0)
    burst_yaw_rate_sigma: tuple[float, float] = (0.0, 0.0)
    multipath_probability: float = 0.0
    multipath_count: tuple[int, int] = (1, 1)
    multipath_duration: tuple[float, float] = (10.0, 40.0)
    multipath_bias: tuple[float, float] = (5.0, 30.0)
    multipath_sigma: tuple[float, float] = (0.0, 0.0)
    multipath_rows: tuple[int, ...] = ()
    canyon_probability: float = 0.0
    canyon_count: tuple[int, int] = (1, 1)
    canyon_duration: tuple[float, float] = (10.0, 40.0)
    canyon_satellites: tuple[int, int] = (3, 6)
    canyon_noise_scale: tuple[float, float] = (1.5, 4.0)
    canyon_loss: tuple[float, float] = (0.0, 0.3)

    def __post_init__(self) -> None:
        """Check every field (type, finiteness, range) and store it normalized (floats, ints, tuples).

        Errors name the field, its value and the accepted range: a ``TypeError`` (also a
        ``ValueError``, :class:`~navgym.envs.arguments.ArgumentTypeError`) for a value of the
        wrong type (a string, a bool for a number, a float for a count, a scalar for a pair), a
        ``ValueError`` for one out of range. Counts are bounded (``MAX_OUTAGE_COUNT``,
        ``MAX_PRN``), so sampling is fast whatever the arguments.
        """
        put = functools.partial(object.__setattr__, self)
        put("duration", arguments.real("duration", self.duration, 0.0, low_open=True))
        put(
            "start_margin",
            arguments.real("start_margin", self.start_margin, 0.0, self.duration, high_open=True),
        )
        put("mask_deg", arguments.interval("mask_deg", self.mask_deg, 0.0, 90.0, high_open=True))
        put("max_satellites", arguments.integer("max_satellites", self.max_satellites, 1))
        for name in _PROBABILITIES:
            put(name, arguments.real(name, getattr(self, name), 0.0, 1.0))
        for name in _DURATIONS:
            put(name, arguments.interval(name, getattr(self, name), 0.0))
        for name in ("impulsive_eps", "jamming_loss", "outlier_rate"):
            put(name, arguments.interval(name, getattr(self, name), 0.0, 1.0))
        for name in ("jamming_sigma", "outlier_scale"):
            put(name, arguments.interval(name, getattr(self, name), 0.0, MAX_ERROR_M))
        put(
            "impulsive_var_ratio",
            arguments.interval("impulsive_var_ratio", self.impulsive_var_ratio, 1.0, MAX_VAR_RATIO),
        )
        put("outage_count", arguments.count_range("outage_count", self.outage_count, 0, MAX_OUTAGE_COUNT))
        put(
            "partial_satellites",
            arguments.count_range("partial_satellites", self.partial_satellites, 0, MAX_PRN),
        )
        put("outlier_count", arguments.count_range("outlier_count", self.outlier_count, 1, MAX_PRN))
        put(
            "outage_duration_choices",
            arguments.reals("outage_duration_choices", self.outage_duration_choices, 0.0),
        )
        put(
            "impulsive_var_ratio_choices",
            arguments.reals(
                "impulsive_var_ratio_choices", self.impulsive_var_ratio_choices, 1.0, MAX_VAR_RATIO
            ),
        )
        # the v2 events
        for name in _EVENT_PROBABILITIES:
            put(name, arguments.real(name, getattr(self, name), 0.0, 1.0))
        for name in _EVENT_DURATIONS:
            put(name, arguments.interval(name, getattr(self, name), 0.0))
        for name in _EVENT_COUNTS:
            put(name, arguments.count_range(name, getattr(self, name), 1, MAX_EVENT_COUNT))
        put(
            "burst_velocity_sigma",
            arguments.interval("burst_velocity_sigma", self.burst_velocity_sigma, 0.0, MAX_VELOCITY_SIGMA),
        )
        put(
            "burst_yaw_rate_sigma",
            arguments.interval("burst_yaw_rate_sigma", self.burst_yaw_rate_sigma, 0.0, MAX_YAW_RATE_SIGMA),
        )
        for name in ("multipath_bias", "multipath_sigma"):
            put(name, arguments.interval(name, getattr(self, name), 0.0, MAX_ERROR_M))
        put("multipath_rows", _rows("multipath_rows", self.multipath_rows))
        if self.multipath_probability > 0.0 and not self.multipath_rows:
            raise ValueError(
                "multipath_rows must name the measurement rows to draw multipath on (e.g. (0, 1, 2, 3)) "
                f"when multipath_probability > 0; got multipath_probability={self.multipath_probability}"
            )
        put(
            "canyon_satellites",
            arguments.count_range("canyon_satellites", self.canyon_satellites, 0, MAX_PRN),
        )
        put(
            "canyon_noise_scale",
            arguments.interval("canyon_noise_scale", self.canyon_noise_scale, 1.0, MAX_NOISE_SCALE),
        )
        put("canyon_loss", arguments.interval("canyon_loss", self.canyon_loss, 0.0, 1.0))

    # -- sampling -------------------------------------------------------------------------------

    def _start(self, rng: np.random.Generator, length: float) -> float:
        latest = max(self.start_margin, self.duration - length)
        return float(rng.uniform(self.start_margin, latest))

    def _length(self, rng: np.random.Generator, rng_range, choices=()) -> float:
        if choices:
            return float(choices[rng.integers(len(choices))])
        return float(rng.uniform(*rng_range))

    def _count(self, rng: np.random.Generator, count: tuple[int, int]) -> int:
        """A count from its range; a single value draws nothing."""
        return count[0] if count[0] == count[1] else int(rng.integers(count[0], count[1] + 1))

    def _value(self, rng: np.random.Generator, rng_range: tuple[float, float]) -> float:
        """A uniform draw from the range; a single value draws nothing."""
        return rng_range[0] if rng_range[0] == rng_range[1] else float(rng.uniform(*rng_range))

    def sample(self, rng: np.random.Generator | int) -> Scenario:
        """Draw the scenario of one episode.

        Args:
            rng: The episode's generator (or an int seed).

        Returns:
            A frozen :class:`Scenario`.

        """
        (scenario,) = self.sample_many(rng)
        return scenario

    def _sample_components(
        self, subs: list[np.random.Generator], events: list[np.random.Generator | None]
    ) -> Scenario:
        """The scenario drawn from an episode's six component generators and its event generators.

        ``events`` holds the burst, multipath and canyon generators (None where disabled).
        """
        r_out, r_part, r_imp, r_jam, r_outl, r_mask = subs

        outages = []
        if r_out.uniform() < self.outage_probability:
            for _ in range(int(r_out.integers(self.outage_count[0], self.outage_count[1] + 1))):
                d = self._length(r_out, self.outage_duration, self.outage_duration_choices)
                s = self._start(r_out, d)
                outages.append(Outage(s, s + d))

        partial = []
        if r_part.uniform() < self.partial_probability:
            d = self._length(r_part, self.partial_duration)
            s = self._start(r_part, d)
            k = int(r_part.integers(self.partial_satellites[0], self.partial_satellites[1] + 1))
            partial.append(PartialOutage(s, s + d, k))

        impulsive = []
        if r_imp.uniform() < self.impulsive_probability:
            d = self._length(r_imp, self.impulsive_duration)
            s = self._start(r_imp, d)
            eps = float(r_imp.uniform(*self.impulsive_eps))
            ratio = self._length(r_imp, self.impulsive_var_ratio, self.impulsive_var_ratio_choices)
            impulsive.append(ImpulsiveNoise(s, s + d, eps, ratio))

        jamming = []
        if r_jam.uniform() < self.jamming_probability:
            for _ in range(self._count(r_jam, self.jamming_count)):
                d = self._length(r_jam, self.jamming_duration)
                s = self._start(r_jam, d)
                jamming.append(
                    Jamming(
                        s,
                        s + d,
                        float(r_jam.uniform(*self.jamming_sigma)),
                        float(r_jam.uniform(*self.jamming_loss)),
                        self._value(r_jam, self.jamming_ramp),
                    )
                )

        outliers = []
        if r_outl.uniform() < self.outlier_probability:
            d = self._length(r_outl, self.outlier_duration)
            s = self._start(r_outl, d)
            n = int(r_outl.integers(self.outlier_count[0], self.outlier_count[1] + 1))
            prns = tuple(sorted(int(p) for p in r_outl.choice(MAX_PRN, n, replace=False) + 1))
            outliers.append(
                OutlierSatellites(
                    s,
                    s + d,
                    prns,
                    float(r_outl.uniform(*self.outlier_rate)),
                    float(r_outl.uniform(*self.outlier_scale)),
                )
            )

        bursts, multipath, canyons = self._sample_events(events)

        critical = bool(r_mask.uniform() < self.critical_probability)
        mask = float(r_mask.uniform(*self.mask_deg))
        return Scenario(
            duration=self.duration,
            mask_deg=CRITICAL_MASK_DEG if critical else mask,
            max_satellites=self.max_satellites,
            outages=tuple(outages),
            partial_outages=tuple(partial),
            impulsive=tuple(impulsive),
            jamming=tuple(jamming),
            outliers=tuple(outliers),
            critical=critical,
            bursts=bursts,
            multipath=multipath,
            canyons=canyons,
        )

    def _sample_events(
        self, events: list[np.random.Generator | None]
    ) -> tuple[tuple[MotionBurst, ...], tuple[Multipath, ...], tuple[UrbanCanyon, ...]]:
        """The v2 events of an episode from their generators (None: that kind is disabled)."""
        r_burst, r_mp, r_canyon = events
        bursts = []
        if r_burst is not None and r_burst.uniform() < self.burst_probability:
            for _ in range(self._count(r_burst, self.burst_count)):
                d = self._length(r_burst, self.burst_duration)
                s = self._start(r_burst, d)
                v = self._value(r_burst, self.burst_velocity_sigma)
                w = self._value(r_burst, self.burst_yaw_rate_sigma)
                bursts.append(MotionBurst(s, s + d, v, w))
        multipath = []
        if r_mp is not None and r_mp.uniform() < self.multipath_probability:
            for _ in range(self._count(r_mp, self.multipath_count)):
                d = self._length(r_mp, self.multipath_duration)
                s = self._start(r_mp, d)
                row = self.multipath_rows[int(r_mp.integers(len(self.multipath_rows)))]
                sign = 1.0 if r_mp.uniform() < 0.5 else -1.0
                bias = sign * self._value(r_mp, self.multipath_bias)
                multipath.append(Multipath(s, s + d, row, bias, self._value(r_mp, self.multipath_sigma)))
        canyons = []
        if r_canyon is not None and r_canyon.uniform() < self.canyon_probability:
            for _ in range(self._count(r_canyon, self.canyon_count)):
                d = self._length(r_canyon, self.canyon_duration)
                s = self._start(r_canyon, d)
                k = self._count(r_canyon, self.canyon_satellites)
                scale = self._value(r_canyon, self.canyon_noise_scale)
                canyons.append(UrbanCanyon(s, s + d, k, scale, self._value(r_canyon, self.canyon_loss)))
        return tuple(bursts), tuple(multipath), tuple(canyons)

    def _event_rngs(self, seeds: np.ndarray) -> list[list[np.random.Generator | None]]:
        """Per episode, the burst, multipath and canyon generators (None where disabled).

        ``default_rng([s, k])`` with the episode's sixth component seed ``s`` and k = 1, 2, 3:
        nothing more is drawn from the episode's generator.
        """
        on = [getattr(self, p) > 0.0 for p in _EVENT_PROBABILITIES]
        return [
            [np.random.default_rng([int(row[-1]), k + 1]) if on[k] else None for k in range(len(on))]
            for row in seeds
        ]

    def sample_many(self, seeds_or_rngs: SeedsOrGenerators) -> tuple[Scenario, ...]:
        """Draw one scenario per generator (or seed): ``tuple(self.sample(r) for r in rngs)``.

        The component generators of all episodes are built at once (:func:`default_rngs`).
        """
        rngs = as_generators(seeds_or_rngs)
        seeds = np.array([_component_seeds(r) for r in rngs])
        subs = default_rngs(seeds)
        events = self._event_rngs(seeds)
        return tuple(
            self._sample_components(subs[i * _COMPONENTS : (i + 1) * _COMPONENTS], events[i])
            for i in range(len(rngs))
        )

    def sample_batch(self, seeds_or_rngs: SeedsOrGenerators, min_slots: int = 1) -> ScenarioBatch:
        """Draw B scenarios and stack them (equal to B single draws with the same seeds).

        Args:
            seeds_or_rngs: One seed or generator per episode.
            min_slots: See :func:`~navgym.scenarios.batch.stack_scenarios`.

        Returns:
            :class:`~navgym.scenarios.batch.ScenarioBatch` for the vectorized evaluators.

        """
        return stack_scenarios(self.sample_many(seeds_or_rngs), min_slots=min_slots)
