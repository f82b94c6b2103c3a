import numpy as np
import pytest

from navgym.scenarios import (
    OUTAGE_DURATIONS_S,
    SEED001_VARIANCE_RATIOS,
    ScenarioDistribution,
    stack_scenarios,
)

EVERYTHING = ScenarioDistribution(
    outage_probability=0.7,
    outage_count=(1, 3),
    outage_duration_choices=OUTAGE_DURATIONS_S,
    duration=600.0,
    partial_probability=0.5,
    impulsive_probability=0.5,
    impulsive_var_ratio_choices=SEED001_VARIANCE_RATIOS,
    jamming_probability=0.5,
    outlier_probability=0.5,
    critical_probability=0.2,
    mask_deg=(5.0, 15.0),
)


def test_batch_equals_single_draws():
    seeds = list(range(40, 48))
    batch = EVERYTHING.sample_batch(seeds)
    singles = stack_scenarios([EVERYTHING.sample(np.random.default_rng(s)) for s in seeds])
    for a, b in zip(batch, singles, strict=True):
        np.testing.assert_array_equal(a, b)
    assert EVERYTHING.sample(41) == EVERYTHING.sample(np.random.default_rng(41))


@pytest.mark.parametrize("B", [3, 100])  # below and above default_rngs' batching threshold
def test_sample_many_equals_single_draws_and_leaves_generators_alike(B):
    gens = [np.random.default_rng(1000 + i) for i in range(B)]
    refs = [np.random.default_rng(1000 + i) for i in range(B)]
    many = EVERYTHING.sample_many(gens)
    assert list(many) == [EVERYTHING.sample(r) for r in refs]
    assert [g.random() for g in gens] == [r.random() for r in refs]  # same amount drawn


def test_samples_respect_the_distribution():
    scenarios = EVERYTHING.sample_many(range(400))
    frac = lambda attr: np.mean([bool(getattr(s, attr)) for s in scenarios])  # noqa: E731
    assert frac("outages") == pytest.approx(0.7, abs=0.08)
    assert frac("impulsive") == pytest.approx(0.5, abs=0.08)
    assert frac("critical") == pytest.approx(0.2, abs=0.06)
    for s in scenarios:
        assert 1 <= len(s.outages) <= 3 or not s.outages
        assert all(np.isclose(o.duration, OUTAGE_DURATIONS_S).any() and o.start >= 30.0 for o in s.outages)
        assert all(i.var_ratio in SEED001_VARIANCE_RATIOS and 0.005 <= i.eps <= 0.3 for i in s.impulsive)
        assert all(2 <= p.max_satellites <= 4 for p in s.partial_outages)
        assert s.mask_deg == 50.0 if s.critical else 5.0 <= s.mask_deg <= 15.0


def test_probability_extremes():
    none = ScenarioDistribution(outage_probability=0.0).sample_many(range(50))
    assert not any(s.outages or s.impulsive or s.jamming or s.outliers or s.critical for s in none)
    always = ScenarioDistribution(outage_probability=1.0, jamming_probability=1.0).sample_many(range(50))
    assert all(s.outages and s.jamming for s in always)


def test_common_random_numbers_across_configurations():
    a = ScenarioDistribution(outage_probability=0.2, jamming_probability=1.0).sample_many(range(30))
    b = ScenarioDistribution(outage_probability=0.9, jamming_probability=1.0).sample_many(range(30))
    assert [s.jamming for s in a] == [s.jamming for s in b]


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"outage_probability": 1.2}, "outage_probability"),
        ({"jamming_probability": -0.1}, "jamming_probability"),
        ({"outage_duration": (-10.0, 5.0)}, "outage_duration"),
        ({"outage_duration": (60.0, 10.0)}, "outage_duration"),
        ({"mask_deg": (10.0, 95.0)}, "mask_deg"),
        ({"mask_deg": (-1.0, 10.0)}, "mask_deg"),
        ({"impulsive_eps": (0.1, 1.5)}, "impulsive_eps"),
        ({"impulsive_var_ratio": (0.5, 10.0)}, "impulsive_var_ratio"),
        ({"partial_satellites": (3, 2)}, "partial_satellites"),
        ({"outage_count": (1.5, 2)}, "outage_count"),
        ({"duration": -300.0}, "duration"),
        ({"start_margin": 400.0}, "start_margin"),
        ({"outage_duration_choices": (10.0, -5.0)}, "outage_duration_choices"),
        ({"outlier_count": (1, 40)}, "outlier_count"),
    ],
)
def test_bad_parameters_raise_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ScenarioDistribution(**kwargs)


def test_an_interval_longer_than_the_time_left_lasts_through_the_last_epoch():
    """A 300 s outage in a 300 s episode (30 s start margin): no GNSS from its start to t = 300."""
    from navgym.scenarios import gnss_available

    dist = ScenarioDistribution(duration=300.0, outage_probability=1.0, outage_duration=(300.0, 300.0))
    scenarios = [dist.sample(seed) for seed in range(20)]
    t = np.arange(31.0, 301.0)
    for s in scenarios:
        (outage,) = s.outages
        assert 30.0 <= outage.start < 31.0 and outage.end > 300.0
    assert not gnss_available(stack_scenarios(scenarios), np.broadcast_to(t, (20, t.size))).any()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        # strings, bools and None were converted with float() (or compared) and accepted
        ({"outage_probability": "0.5"}, r"outage_probability must be a real number in \[0, 1\]; got '0.5'"),
        ({"jamming_probability": True}, r"jamming_probability must be a real number"),
        ({"critical_probability": None}, r"critical_probability must be a real number"),
        ({"outage_duration": ("10", 20.0)}, r"outage_duration must be a pair \(low, high\) of real numbers"),
        ({"impulsive_eps": (False, 0.3)}, r"impulsive_eps must be a pair"),
        ({"mask_deg": "ab"}, r"mask_deg must be a pair"),
        ({"duration": "300"}, r"duration must be a real number"),
        ({"start_margin": "5"}, r"start_margin must be a real number in \[0, 300\)"),
        ({"outage_count": (1.0, 2)}, r"outage_count must be a pair \(low, high\) of integers in \[0, 100\]"),
        ({"outage_count": (True, 2)}, r"outage_count must be a pair"),
        ({"partial_satellites": ("2", 4)}, r"partial_satellites must be a pair"),
        ({"max_satellites": 12.0}, r"max_satellites must be an integer >= 1; got 12.0"),
        ({"outage_duration_choices": "ab"}, r"outage_duration_choices must be a tuple of real numbers"),
        ({"impulsive_var_ratio_choices": ("50",)}, r"impulsive_var_ratio_choices must be a tuple"),
    ],
)
def test_wrong_types_raise_naming_the_parameter(kwargs, message):
    with pytest.raises(TypeError, match=message):
        ScenarioDistribution(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        # sampling drew outage_count outages one by one: (1, 10**9) hung the first reset
        ({"outage_count": (1, 10**9)}, r"outage_count must be a pair .* integers in \[0, 100\]"),
        ({"outage_count": (0, 101)}, r"outage_count .* in \[0, 100\]"),
        ({"partial_satellites": (2, 10**9)}, r"partial_satellites .* in \[0, 32\]"),
        ({"outlier_count": (0, 2)}, r"outlier_count .* in \[1, 32\]"),
        # non-finite or absurd sizes overflowed the simulated noise
        ({"impulsive_var_ratio": (50.0, 1e300)}, r"impulsive_var_ratio .* in \[1, 1e\+06\]"),
        ({"impulsive_var_ratio_choices": (50.0, 1e9)}, r"impulsive_var_ratio_choices .* \[1, 1e\+06\]"),
        ({"jamming_sigma": (10.0, 1e300)}, r"jamming_sigma .* in \[0, 100000\]"),
        ({"outlier_scale": (10.0, float("inf"))}, r"outlier_scale .* finite numbers in \[0, 100000\]"),
        ({"outage_duration": (10.0, float("nan"))}, r"outage_duration .* finite"),
        ({"outage_probability": float("nan")}, r"outage_probability must be a finite number in \[0, 1\]"),
        ({"start_margin": float("nan")}, r"start_margin must be a finite number"),
        ({"duration": float("inf")}, r"duration must be a finite number in \(0, inf\)"),
        ({"mask_deg": (10.0, 90.0)}, r"mask_deg .* in \[0, 90\)"),
    ],
)
def test_bad_values_raise_naming_the_parameter_and_its_range(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ScenarioDistribution(**kwargs)


def test_the_largest_outage_count_samples_fast():
    import time

    dist = ScenarioDistribution(outage_probability=1.0, outage_count=(100, 100), outage_duration=(1.0, 2.0))
    t0 = time.perf_counter()
    (scenario,) = dist.sample_many([np.random.default_rng(0)])
    assert len(scenario.outages) == 100 and time.perf_counter() - t0 < 1.0


def test_parameters_are_stored_normalized_and_sample_as_before():
    """Lists, NumPy numbers and ints give the same distribution (and draws) as tuples of floats."""
    loose = ScenarioDistribution(
        outage_duration=[10, 60],
        outage_count=[np.int64(1), 3],
        mask_deg=np.array([5.0, 15.0]),
        outage_probability=np.float32(0.5),
        outage_duration_choices=[10, 50],
    )
    strict = ScenarioDistribution(
        outage_duration=(10.0, 60.0),
        outage_count=(1, 3),
        mask_deg=(5.0, 15.0),
        outage_probability=0.5,
        outage_duration_choices=(10.0, 50.0),
    )
    assert loose == strict and hash(loose) == hash(strict)
    assert type(loose.outage_count[0]) is int and type(loose.outage_duration[0]) is float
    assert loose.sample_many(range(20)) == strict.sample_many(range(20))
