import numpy as np
import pytest

from navgym.gnss import make_regime
from navgym.gnss.noise import MAX_PRN as GNSS_MAX_PRN
from navgym.scenarios import (
    IMPULSIVE,
    JAMMING,
    MAX_PRN,
    OUTAGE,
    OUTLIERS,
    PARTIAL_OUTAGE,
    ImpulsiveNoise,
    Jamming,
    Outage,
    OutlierSatellites,
    PartialOutage,
    Scenario,
    ScenarioDistribution,
    degradation_flags,
    gnss_available,
    max_satellites,
    noise_regime,
    satellite_row_mask,
    stack_scenarios,
)

HAND = [
    Scenario(),
    Scenario(
        outages=(Outage(10.0, 20.0), Outage(50.0, 60.0)),
        partial_outages=(PartialOutage(0.0, 100.0, 4), PartialOutage(30.0, 40.0, 2)),
    ),
    Scenario(
        max_satellites=8,
        impulsive=(ImpulsiveNoise(5.0, 15.0, 0.1, 200.0),),
        jamming=(Jamming(12.0, 30.0, 25.0, 0.3),),
        outliers=(OutlierSatellites(0.0, 40.0, (3, 17), 0.2, 150.0),),
    ),
]


def _in(iv, t):
    return iv.start <= t < iv.end


def _reference(s: Scenario, t: float):
    """Per-episode, per-time evaluation in plain Python (the specification)."""
    out = any(_in(o, t) for o in s.outages)
    caps = [p.max_satellites for p in s.partial_outages if _in(p, t)]
    k = 0 if out else min([s.max_satellites, *caps])
    imp = [i for i in s.impulsive if _in(i, t)]
    jam = [j for j in s.jamming if _in(j, t)]
    outl = [q for q in s.outliers if _in(q, t)]
    prns = {p for q in outl for p in q.prns}
    return (
        not out,
        k,
        max([0.0] + [i.eps for i in imp]),
        max([1.0] + [i.var_ratio for i in imp]),
        max([0.0] + [j.jam_sigma for j in jam]),
        max([0.0] + [j.loss_prob for j in jam]),
        max([0.0] + [q.probability for q in outl]),
        max([0.0] + [q.scale for q in outl]),
        prns,
    )


@pytest.mark.parametrize("source", ["hand", "sampled"])
def test_evaluators_match_the_per_episode_definition(source):
    if source == "hand":
        scenarios = HAND
    else:
        dist = ScenarioDistribution(
            outage_probability=0.8,
            outage_count=(0, 3),
            partial_probability=0.6,
            impulsive_probability=0.6,
            jamming_probability=0.6,
            outlier_probability=0.6,
        )
        scenarios = list(dist.sample_many(range(12)))
    batch = stack_scenarios(scenarios)
    t = np.linspace(0.0, 320.0, 641)[None, :]
    avail = gnss_available(batch, t)
    k = max_satellites(batch, t)
    reg = noise_regime(batch, t)
    for b, s in enumerate(scenarios):
        for j in range(0, t.shape[1], 7):
            ref = _reference(s, t[0, j])
            got = (
                avail[b, j],
                k[b, j],
                reg.eps[b, j],
                reg.var_ratio[b, j],
                reg.jam_sigma[b, j],
                reg.loss_prob[b, j],
                reg.outlier_prob[b, j],
                reg.outlier_scale[b, j],
                set(np.flatnonzero(reg.outlier_prns[b, j]).tolist()),
            )
            assert got == ref


def test_time_shapes_scalar_per_episode_and_series():
    batch = stack_scenarios(HAND)
    assert gnss_available(batch, 15.0).tolist() == [True, False, True]
    per = np.array([15.0, 35.0, 13.0])
    assert max_satellites(batch, per).tolist() == [12, 2, 8]
    assert max_satellites(batch, np.zeros((3, 4))).shape == (3, 4)
    assert noise_regime(batch, per).outlier_prns.shape == (3, MAX_PRN + 1)
    rows = satellite_row_mask(batch, per, 12)
    assert rows.shape == (3, 12) and rows.sum(axis=1).tolist() == [12, 2, 8]
    flags = degradation_flags(batch, per)
    assert flags.tolist() == [0, PARTIAL_OUTAGE, IMPULSIVE | JAMMING | OUTLIERS]
    assert degradation_flags(batch, 15.0)[1] == OUTAGE | PARTIAL_OUTAGE
    with pytest.raises(ValueError, match="t must"):
        gnss_available(batch, np.zeros(5))
    with pytest.raises(ValueError, match="m_max"):
        satellite_row_mask(batch, 0.0, 0)


def test_noise_regime_feeds_the_gnss_noise_model():
    assert MAX_PRN == GNSS_MAX_PRN
    batch = stack_scenarios(HAND)
    params = noise_regime(batch, np.array([0.0, 0.0, 13.0]))
    regime = make_regime(3, sigma=5.0, **params._asdict())
    assert regime.eps.tolist() == [0.0, 0.0, 0.1]
    assert regime.jam_sigma[2] == 25.0 and regime.outlier_prns[2, [3, 17]].all()


def test_padding_to_fixed_slots():
    batch = stack_scenarios(HAND, min_slots=4)
    assert batch.outage_start.shape == (3, 4) and batch.outlier_prns.shape == (3, 4, MAX_PRN + 1)
    with pytest.raises(ValueError, match="scenarios"):
        stack_scenarios([])
