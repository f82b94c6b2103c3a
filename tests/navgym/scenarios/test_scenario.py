import dataclasses

import pytest

from navgym.scenarios import (
    CRITICAL_DT_S,
    CRITICAL_DURATION_S,
    CRITICAL_MASK_DEG,
    ImpulsiveNoise,
    Jamming,
    Outage,
    OutlierSatellites,
    PartialOutage,
    Scenario,
    critical_scenario,
)


def test_scenario_is_frozen_hashable_and_normalizes_lists():
    s = Scenario(outages=[Outage(10.0, 60.0)], outliers=[OutlierSatellites(0.0, 5.0, [3, 7])])
    assert isinstance(s.outages, tuple) and s.outliers[0].prns == (3, 7)
    assert hash(s) == hash(
        Scenario(outages=(Outage(10.0, 60.0),), outliers=(OutlierSatellites(0.0, 5.0, (3, 7)),))
    )
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.mask_deg = 5.0
    assert s.outages[0].duration == 50.0


def test_critical_scenario_is_carvalho_1997_section_v():
    s = critical_scenario()
    assert (s.critical, s.mask_deg, s.duration) == (True, 50.0, 3600.0)
    assert (CRITICAL_MASK_DEG, CRITICAL_DURATION_S, CRITICAL_DT_S) == (50.0, 3600.0, 1.0)
    assert critical_scenario(impulsive=(ImpulsiveNoise(0.0, 10.0, 0.1, 100.0),)).impulsive


@pytest.mark.parametrize(
    ("build", "name"),
    [
        (lambda: Outage(10.0, 5.0), "end"),
        (lambda: Outage(-1.0, 5.0), "start"),
        (lambda: PartialOutage(0.0, 5.0, -1), "max_satellites"),
        (lambda: ImpulsiveNoise(0.0, 5.0, eps=1.5), "eps"),
        (lambda: ImpulsiveNoise(0.0, 5.0, var_ratio=0.5), "var_ratio"),
        (lambda: Jamming(0.0, 5.0, jam_sigma=-1.0), "jam_sigma"),
        (lambda: Jamming(0.0, 5.0, loss_prob=2.0), "loss_prob"),
        (lambda: OutlierSatellites(0.0, 5.0, (0,)), "prns"),
        (lambda: OutlierSatellites(0.0, 5.0, (1,), probability=-0.1), "probability"),
        (lambda: Scenario(mask_deg=90.0), "mask_deg"),
        (lambda: Scenario(mask_deg=-5.0), "mask_deg"),
        (lambda: Scenario(duration=0.0), "duration"),
        (lambda: Scenario(max_satellites=0), "max_satellites"),
        (lambda: Scenario(outages=(PartialOutage(0.0, 1.0, 2), "x")), "outages"),
    ],
)
def test_bad_input_raises_naming_argument(build, name):
    with pytest.raises(ValueError, match=name):
        build()


@pytest.mark.parametrize(
    ("field", "interval"),
    [("outages", Outage(300.0, 400.0)), ("jamming", Jamming(301.0, 310.0, 30.0, 0.5))],
)
def test_an_interval_starting_at_or_after_the_end_raises(field, interval):
    from navgym.scenarios import Scenario

    with pytest.raises(ValueError, match=rf"{field}\[0\] starts at .* not before the scenario's end 300"):
        Scenario(duration=300.0, **{field: (interval,)})


def test_an_interval_may_run_past_the_end_to_cover_the_last_epoch():
    """Intervals are [start, end) and the last epoch is at t = duration: 'to the end' ends after it."""
    from navgym.scenarios import Scenario, gnss_available, stack_scenarios

    batch = stack_scenarios([Scenario(duration=300.0, outages=(Outage(290.0, 400.0),))])
    assert not gnss_available(batch, [[299.0, 300.0]]).any()
    assert gnss_available(
        stack_scenarios([Scenario(duration=300.0, outages=(Outage(290.0, 300.0),))]), [[300.0]]
    ).all()
