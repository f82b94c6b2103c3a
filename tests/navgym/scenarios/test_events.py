"""The v2 within-episode events: dataclasses, batch evaluators and their sampling.

Motion bursts, multipath/NLOS segments, urban canyons and jamming ramps (docs/architecture.md,
"v2: events and the clairvoyant reference"). Disabled (the defaults) they draw nothing, so every
existing scenario and distribution samples exactly as before
(``tests/navgym/envs/test_traces.py`` holds the ids).
"""

import dataclasses

import numpy as np
import pytest

from navgym.scenarios import (
    BURST,
    CANYON,
    JAMMING,
    MULTIPATH,
    PARTIAL_OUTAGE,
    Jamming,
    MotionBurst,
    Multipath,
    Outage,
    PartialOutage,
    Scenario,
    ScenarioDistribution,
    UrbanCanyon,
    canyon_regime,
    degradation_flags,
    max_satellites,
    motion_burst,
    multipath_error,
    noise_regime,
    stack_scenarios,
)

#: A distribution with every older component switched on (the events' neighbours).
OLD = dict(
    duration=120.0,
    start_margin=5.0,
    outage_probability=0.7,
    outage_count=(0, 3),
    partial_probability=0.5,
    impulsive_probability=0.5,
    jamming_probability=0.6,
    outlier_probability=0.5,
    critical_probability=0.2,
    mask_deg=(5.0, 15.0),
)
#: The v2 events switched on.
EVENTS = dict(
    jamming_count=(1, 3),
    jamming_ramp=(1.0, 5.0),
    burst_probability=0.9,
    burst_count=(2, 4),
    burst_duration=(2.0, 10.0),
    burst_velocity_sigma=(0.5, 3.0),
    burst_yaw_rate_sigma=(0.05, 0.3),
    multipath_probability=0.9,
    multipath_count=(2, 4),
    multipath_duration=(5.0, 20.0),
    multipath_bias=(5.0, 30.0),
    multipath_sigma=(0.0, 3.0),
    multipath_rows=(0, 1, 2, 3),
    canyon_probability=0.8,
    canyon_count=(1, 2),
    canyon_duration=(5.0, 20.0),
    canyon_satellites=(3, 8),
    canyon_noise_scale=(2.0, 5.0),
    canyon_loss=(0.0, 0.5),
)


def _without_events(s: Scenario) -> Scenario:
    return dataclasses.replace(s, bursts=(), multipath=(), canyons=())


# ------------------------------------------------------------------------------ dataclasses
def test_events_default_to_none_and_scenarios_stay_hashable():
    s = Scenario()
    assert s.bursts == s.multipath == s.canyons == () and Jamming(0.0, 1.0).ramp == 0.0
    full = Scenario(
        duration=60.0,
        jamming=(Jamming(10.0, 20.0, 5.0, 0.1, 2.0),),
        bursts=[MotionBurst(5.0, 8.0, 2.0, 0.1)],
        multipath=[Multipath(5.0, 15.0, 0, 10.0)],
        canyons=[UrbanCanyon(20.0, 30.0, 5, 3.0, 0.2)],
    )
    assert isinstance(full.bursts, tuple) and hash(full) == hash(dataclasses.replace(full))
    with pytest.raises(dataclasses.FrozenInstanceError):
        full.bursts = ()  # type: ignore[misc]


@pytest.mark.parametrize(
    ("build", "name"),
    [
        (lambda: MotionBurst(0.0, 1.0, -1.0), "velocity_sigma"),
        (lambda: MotionBurst(0.0, 1.0, 1.0, float("nan")), "yaw_rate_sigma"),
        (lambda: Multipath(0.0, 1.0, -1, 5.0), "row"),
        (lambda: Multipath(0.0, 1.0, 1.5, 5.0), "row"),
        (lambda: Multipath(0.0, 1.0, 0, float("inf")), "bias"),
        (lambda: Multipath(0.0, 1.0, 0, 5.0, -1.0), "sigma"),
        (lambda: UrbanCanyon(0.0, 1.0, 4, 0.5), "noise_scale"),
        (lambda: UrbanCanyon(0.0, 1.0, 4, 2.0, 1.5), "loss_prob"),
        (lambda: UrbanCanyon(0.0, 1.0, -1), "max_satellites"),
        (lambda: Jamming(0.0, 1.0, 5.0, 0.0, -2.0), "ramp"),
        (lambda: MotionBurst(3.0, 1.0), "end"),
        (lambda: Scenario(duration=10.0, bursts=(MotionBurst(10.0, 12.0),)), "bursts"),
        (lambda: Scenario(multipath=(Outage(0.0, 1.0),)), "multipath"),
        (lambda: Scenario(canyons=(PartialOutage(0.0, 1.0, 3),)), "canyons"),
    ],
)
def test_bad_events_raise_naming_the_field(build, name):
    with pytest.raises(ValueError, match=name):
        build()


def test_jamming_ramp_profile_known_answers():
    j = Jamming(10.0, 30.0, 20.0, 0.4, ramp=5.0)
    t = [9.9, 10.0, 12.5, 15.0, 20.0, 25.0, 27.5, 29.0, 30.0]
    assert [j.profile(x) for x in t] == pytest.approx([0.0, 0.0, 0.5, 1.0, 1.0, 1.0, 0.5, 0.2, 0.0])
    step = Jamming(10.0, 30.0, 20.0, 0.4)
    assert [step.profile(x) for x in t] == [0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0]
    short = Jamming(10.0, 14.0, 20.0, ramp=5.0)  # 2 ramp > duration: a triangle up to 2 / 5
    assert short.profile(12.0) == pytest.approx(0.4) and short.profile(11.0) == pytest.approx(0.2)


# --------------------------------------------------------------------------------- batches
HAND = [
    Scenario(duration=60.0),
    Scenario(
        duration=60.0,
        jamming=(Jamming(10.0, 30.0, 20.0, 0.4, 5.0), Jamming(25.0, 40.0, 8.0, 0.1)),
        bursts=(MotionBurst(5.0, 8.0, 2.0, 0.1), MotionBurst(7.0, 12.0, 1.0, 0.3)),
        multipath=(
            Multipath(5.0, 15.0, 0, 10.0),
            Multipath(10.0, 20.0, 0, -4.0, 2.0),
            Multipath(30.0, 45.0, 3, 7.0, 1.0),
        ),
        canyons=(UrbanCanyon(20.0, 30.0, 5, 3.0, 0.2), UrbanCanyon(28.0, 35.0, 2, 1.5, 0.6)),
        partial_outages=(PartialOutage(0.0, 50.0, 7),),
    ),
]


def _reference(s: Scenario, t: float, m: int):
    """Per-episode, per-time evaluation in plain Python (the specification)."""

    def on(x):
        return x.start <= t < x.end

    bursts = [b for b in s.bursts if on(b)]
    canyons = [c for c in s.canyons if on(c)]
    caps = [p.max_satellites for p in (*s.partial_outages, *canyons) if on(p)]
    bias, var = [0.0] * m, [0.0] * m
    for x in s.multipath:
        if on(x):
            bias[x.row] += x.bias
            var[x.row] += x.sigma**2
    return (
        max([0.0] + [b.velocity_sigma for b in bursts]),
        max([0.0] + [b.yaw_rate_sigma for b in bursts]),
        max([1.0] + [c.noise_scale for c in canyons]),
        max([0.0] + [c.loss_prob for c in canyons]),
        min([s.max_satellites, *caps]),
        max([0.0] + [j.jam_sigma * j.profile(t) for j in s.jamming]),
        max([0.0] + [j.loss_prob * j.profile(t) for j in s.jamming]),
        bias,
        var,
    )


@pytest.mark.parametrize("source", ["hand", "sampled"])
def test_event_evaluators_match_the_per_episode_definition(source):
    m = 5
    if source == "hand":
        scenarios = HAND
    else:
        scenarios = list(ScenarioDistribution(**OLD, **EVENTS).sample_many(range(10)))
    batch = stack_scenarios(scenarios)
    t = np.linspace(0.0, 130.0, 1301)[None, :]
    v, y = motion_burst(batch, t)
    scale, loss = canyon_regime(batch, t)
    k = max_satellites(batch, t)
    reg = noise_regime(batch, t)
    bias, var = multipath_error(batch, t, m)
    for b, s in enumerate(scenarios):
        for j in range(0, t.shape[1], 3):
            if any(o.start <= t[0, j] < o.end for o in s.outages):
                continue  # a full outage: no satellites (tested in test_batch.py)
            ref = _reference(s, t[0, j], m)
            got = (
                v[b, j],
                y[b, j],
                scale[b, j],
                loss[b, j],
                k[b, j],
                reg.jam_sigma[b, j],
                reg.loss_prob[b, j],
            )
            np.testing.assert_allclose(got, ref[:7], rtol=1e-12, atol=1e-12, err_msg=f"{b} {t[0, j]}")
            np.testing.assert_allclose(bias[b, j], ref[7], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(var[b, j], ref[8], rtol=1e-12, atol=1e-12)


def test_event_flags_shapes_and_row_check():
    batch = stack_scenarios(HAND)
    flags = degradation_flags(batch, np.array([6.0, 6.0]))
    assert flags.tolist() == [0, BURST | MULTIPATH | PARTIAL_OUTAGE]
    assert degradation_flags(batch, 29.0)[1] == JAMMING | CANYON | PARTIAL_OUTAGE
    bias, var = multipath_error(batch, np.zeros((2, 7)), 4)
    assert bias.shape == var.shape == (2, 7, 4)
    with pytest.raises(ValueError, match="row 3"):
        multipath_error(batch, 0.0, 3)
    assert stack_scenarios(HAND, min_slots=5).multipath_row.shape == (2, 5)


# -------------------------------------------------------------------------------- sampling
def test_disabled_events_draw_nothing():
    """Without the events a distribution draws exactly what it drew before they existed."""
    plain = ScenarioDistribution(**OLD)
    with_events = ScenarioDistribution(
        **OLD, **{k: v for k, v in EVENTS.items() if not k.startswith("jamming")}
    )
    gens = [np.random.default_rng(i) for i in range(60)]
    refs = [np.random.default_rng(i) for i in range(60)]
    a = with_events.sample_many(gens)
    b = plain.sample_many(refs)
    assert [_without_events(s) for s in a] == list(b)  # the older components are unchanged
    assert [g.random() for g in gens] == [r.random() for r in refs]  # and nothing more is drawn
    assert any(s.bursts for s in a) and any(s.multipath for s in a) and any(s.canyons for s in a)
    assert not any(s.bursts or s.multipath or s.canyons for s in b)


def test_switching_one_event_on_leaves_the_others_unchanged():
    base = dict(OLD, **EVENTS)
    a = ScenarioDistribution(**base).sample_many(range(40))
    b = ScenarioDistribution(**{**base, "burst_probability": 0.0, "canyon_probability": 0.2}).sample_many(
        range(40)
    )
    assert [s.multipath for s in a] == [s.multipath for s in b]
    assert [s.outages for s in a] == [s.outages for s in b] and [s.jamming for s in a] == [
        s.jamming for s in b
    ]
    assert not any(s.bursts for s in b)


def test_event_sampling_is_deterministic_per_seed_and_respects_the_ranges():
    dist = ScenarioDistribution(**OLD, **EVENTS)
    scenarios = dist.sample_many(range(300))
    assert scenarios == dist.sample_many(range(300))
    assert dist.sample(7) == dist.sample(np.random.default_rng(7)) == scenarios[7]
    frac = lambda attr: np.mean([bool(getattr(s, attr)) for s in scenarios])  # noqa: E731
    assert frac("bursts") == pytest.approx(0.9, abs=0.06)
    assert frac("canyons") == pytest.approx(0.8, abs=0.07)
    signs = set()
    for s in scenarios:
        assert not s.bursts or 2 <= len(s.bursts) <= 4
        assert not s.multipath or 2 <= len(s.multipath) <= 4
        assert not s.jamming or 1 <= len(s.jamming) <= 3
        for b in s.bursts:
            assert 2.0 <= b.duration <= 10.0 and 0.5 <= b.velocity_sigma <= 3.0
            assert 0.05 <= b.yaw_rate_sigma <= 0.3 and b.start >= 5.0
        for x in s.multipath:
            assert x.row in (0, 1, 2, 3) and 5.0 <= abs(x.bias) <= 30.0 and 0.0 <= x.sigma <= 3.0
            signs.add(np.sign(x.bias))
        for c in s.canyons:
            assert 3 <= c.max_satellites <= 8 and 2.0 <= c.noise_scale <= 5.0 and 0.0 <= c.loss_prob <= 0.5
        assert all(1.0 <= j.ramp <= 5.0 for j in s.jamming)
    assert signs == {-1.0, 1.0}
    assert {x.row for s in scenarios for x in s.multipath} == {0, 1, 2, 3}


def test_a_single_value_range_draws_nothing_inside_jamming():
    """jamming_count=(1, 1) and jamming_ramp=(0, 0) are the old jamming draws; (2, 2) adds intervals."""
    one = ScenarioDistribution(jamming_probability=1.0).sample_many(range(20))
    ramped = ScenarioDistribution(jamming_probability=1.0, jamming_ramp=(3.0, 3.0)).sample_many(range(20))
    two = ScenarioDistribution(jamming_probability=1.0, jamming_count=(2, 2)).sample_many(range(20))
    assert all(len(s.jamming) == 1 and s.jamming[0].ramp == 0.0 for s in one)
    assert [dataclasses.replace(s.jamming[0], ramp=0.0) for s in ramped] == [s.jamming[0] for s in one]
    assert all(len(s.jamming) == 2 and s.jamming[0] == o.jamming[0] for s, o in zip(two, one, strict=True))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"burst_probability": 1.5}, "burst_probability"),
        ({"burst_count": (0, 2)}, "burst_count"),
        ({"burst_count": (1, 101)}, "burst_count"),
        ({"burst_velocity_sigma": (1.0, 1e3)}, "burst_velocity_sigma"),
        ({"burst_yaw_rate_sigma": (-1.0, 1.0)}, "burst_yaw_rate_sigma"),
        ({"burst_duration": (5.0, 1.0)}, "burst_duration"),
        ({"multipath_probability": 0.5}, "multipath_rows"),
        ({"multipath_rows": (0, 0)}, "multipath_rows"),
        ({"multipath_rows": (0, -1)}, "multipath_rows"),
        ({"multipath_rows": (0.5,)}, "multipath_rows"),
        ({"multipath_rows": (True,)}, "multipath_rows"),
        ({"multipath_bias": (-1.0, 5.0)}, "multipath_bias"),
        ({"multipath_sigma": (0.0, float("nan"))}, "multipath_sigma"),
        ({"canyon_satellites": (2, 40)}, "canyon_satellites"),
        ({"canyon_noise_scale": (0.5, 2.0)}, "canyon_noise_scale"),
        ({"canyon_loss": (0.0, 1.5)}, "canyon_loss"),
        ({"jamming_count": (1.0, 2)}, "jamming_count"),
        ({"jamming_ramp": (-1.0, 2.0)}, "jamming_ramp"),
        ({"canyon_probability": "0.5"}, "canyon_probability"),
    ],
)
def test_bad_event_parameters_raise_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ScenarioDistribution(**kwargs)


def test_event_parameters_are_stored_normalized():
    loose = ScenarioDistribution(
        multipath_probability=0.5, multipath_rows=[np.int64(0), 2], burst_count=[1, 3]
    )
    strict = ScenarioDistribution(multipath_probability=0.5, multipath_rows=(0, 2), burst_count=(1, 3))
    assert loose == strict and hash(loose) == hash(strict) and type(loose.multipath_rows[0]) is int


@pytest.mark.parametrize("times", ["scalar", "per_episode", "whole"])
def test_the_compiled_multipath_sums_equal_the_numpy_form_bit_for_bit(monkeypatch, times):
    """Overlapping segments on one row add in slot order on both paths; unused slots never act."""
    from filters.core.compiled import numpy_only
    from navgym.scenarios import multipath_kernel
    from tests.filters.compiled_paths import count_calls

    rng = np.random.default_rng(8)
    B, K, m = 6, 7, 4
    start = rng.uniform(0.0, 50.0, (B, K))
    start[:, -1] = np.inf  # an unused slot
    batch = stack_scenarios(HAND * 3)._replace(
        multipath_start=start,
        multipath_end=start + rng.uniform(1.0, 40.0, (B, K)),
        multipath_row=rng.integers(0, 2, (B, K)),  # two rows: many overlaps
        multipath_bias=rng.normal(0.0, 3.0, (B, K)),
        multipath_sigma=rng.uniform(0.1, 2.0, (B, K)),
    )
    t = {"scalar": 20.0, "per_episode": rng.uniform(0, 90, B), "whole": np.linspace(0, 90, 181)[None, :]}[
        times
    ]
    calls = count_calls(monkeypatch, multipath_kernel, ("multipath_pass",))
    bias, var = multipath_error(batch, t, m)
    with numpy_only():
        bias_ref, var_ref = multipath_error(batch, t, m)
    assert calls == {"multipath_pass": 1}
    assert bias.shape == bias_ref.shape and (bias != 0).any()
    np.testing.assert_array_equal(bias, bias_ref)
    np.testing.assert_array_equal(var, var_ref)
