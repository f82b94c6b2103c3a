"""The v2 ids take their event ranges as keyword arguments (``V2_EVENT_KWARGS``); v0/v1 do not.

For one id per platform: a shifted range (every event kind on, with its own count, duration and
size) gives scenarios whose events lie in it, over several seeds, on the single and the vector
env; the defaults passed explicitly give the scenario and observation of no keyword argument; the
v0/v1 ids still refuse the event keys (``UnknownKeywordError``, a ``TypeError``); bad values are
refused at ``make`` with a ``ValueError`` naming the argument (:class:`ScenarioDistribution`'s
checks, and the platform's own for ``multipath_rows`` and GpsIns' ``multipath_count``); the v2
card lists the event arguments among the scenario arguments, the v1 card does not.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.envs.arguments import UnknownKeywordError
from navgym.envs.registration import ENVIRONMENTS, superseded_ids_quiet
from navgym.gps_ins import env as gps_ins
from navgym.gps_ins.env_v2 import GPS_INS_V2
from navgym.quadrotor import env as quadrotor
from navgym.quadrotor.env_v2 import QUADROTOR_V2
from navgym.robot2d import env as robot2d
from navgym.robot2d.env_v2 import ROBOT2D_V2
from navgym.scenarios import Scenario

#: One v2 id per platform, its platform's env module, the v2 spec and a v1 id of the platform.
PLATFORMS = {
    "GpsIns": ("navgym/GpsInsNoiseScale-v2", gps_ins, GPS_INS_V2, "navgym/GpsInsFading-v1"),
    "Quadrotor": ("navgym/QuadrotorFading-v2", quadrotor, QUADROTOR_V2, "navgym/QuadrotorFading-v1"),
    "Robot2d": ("navgym/Robot2dNoiseScale-v2", robot2d, ROBOT2D_V2, "navgym/Robot2dFading-v1"),
}
SEEDS = (3, 11, 2024)
ROUND = 1e-9  # end - start against the drawn duration [s]
#: Every event kind on, each range away from its default (episodes of 60 s or more).
SHIFTED: dict[str, Any] = {
    "burst_probability": 1.0,
    "burst_count": (1, 2),
    "burst_duration": (40.0, 50.0),
    "burst_velocity_sigma": (0.01, 0.015),
    "multipath_probability": 1.0,
    "multipath_count": (3, 3),
    "multipath_duration": (30.0, 31.0),
    "multipath_bias": (50.0, 60.0),
    "multipath_sigma": (0.5, 0.6),
    "jamming_probability": 1.0,
    "jamming_count": (2, 2),
    "jamming_duration": (30.0, 35.0),
    "jamming_ramp": (1.0, 1.5),
    "jamming_sigma": (60.0, 70.0),
    "jamming_loss": (0.6, 0.7),
    "canyon_probability": 1.0,
    "canyon_count": (1, 1),
    "canyon_duration": (12.0, 14.0),
    "canyon_satellites": (5, 5),
    "canyon_noise_scale": (6.0, 7.0),
    "canyon_loss": (0.1, 0.2),
    "outage_probability": 1.0,
    "outage_count": (2, 2),
    "outage_duration": (1.0, 2.0),
}
#: Multipath rows to draw on, per platform (a single row, to check it is the one used).
ROWS = {"GpsIns": (9,), "Quadrotor": (2,), "Robot2d": (3,)}


def _within(value: float, span: tuple[float, float], tol: float = 0.0) -> bool:
    return span[0] - tol <= value <= span[1] + tol


def _check_shifted(s: Scenario, rows: tuple[int, ...]) -> None:
    """Every event of ``s`` lies in :data:`SHIFTED`'s ranges (and every kind occurs)."""
    k = SHIFTED
    assert _within(len(s.bursts), k["burst_count"])
    for b in s.bursts:
        assert _within(b.end - b.start, k["burst_duration"], ROUND)
        assert _within(b.velocity_sigma, k["burst_velocity_sigma"])
    assert len(s.multipath) == 3
    for m in s.multipath:
        assert _within(m.end - m.start, k["multipath_duration"], ROUND)
        assert _within(abs(m.bias), k["multipath_bias"]) and _within(m.sigma, k["multipath_sigma"])
        assert m.row in rows
    assert len(s.jamming) == 2
    for j in s.jamming:
        assert _within(j.end - j.start, k["jamming_duration"], ROUND)
        assert _within(j.ramp, k["jamming_ramp"]) and _within(j.jam_sigma, k["jamming_sigma"])
        assert _within(j.loss_prob, k["jamming_loss"])
    assert len(s.canyons) == 1
    for c in s.canyons:
        assert _within(c.end - c.start, k["canyon_duration"], ROUND)
        assert c.max_satellites == 5 and _within(c.noise_scale, k["canyon_noise_scale"])
        assert _within(c.loss_prob, k["canyon_loss"])
    assert len(s.outages) == 2
    for o in s.outages:
        assert _within(o.end - o.start, k["outage_duration"], ROUND)


@pytest.mark.parametrize("platform", PLATFORMS)
def test_every_event_default_is_a_keyword_argument_of_the_v2_ids_only(platform):
    env_id, module, spec_v2, v1_id = PLATFORMS[platform]
    assert module.V2_EVENT_KWARGS == tuple(module.V2_EVENTS)
    v1 = module.SCENARIO_KWARGS
    assert spec_v2.scenario_arguments[: len(v1)] == v1  # v1's first, in their order
    assert set(spec_v2.scenario_arguments) == set(v1) | set(module.V2_EVENT_KWARGS)
    assert len(set(spec_v2.scenario_arguments)) == len(spec_v2.scenario_arguments)  # no duplicates
    assert type(gym.make(env_id).unwrapped).platform_spec is spec_v2
    # the v0/v1 declaration keeps its argument set
    with superseded_ids_quiet():
        spec_v1 = type(gym.make(v1_id).unwrapped).platform_spec
    assert spec_v1.scenario_arguments == v1


@pytest.mark.parametrize("platform", PLATFORMS)
def test_a_shifted_range_draws_events_in_it(platform):
    env_id, _module, _spec, _ = PLATFORMS[platform]
    rows = ROWS[platform]
    env = gym.make(env_id, multipath_rows=rows, **SHIFTED)
    for seed in SEEDS:
        _, info = env.reset(seed=seed)
        _check_shifted(info["scenario"], rows)
    _, *_, info = env.step(env.action_space.sample())
    _check_shifted(info["scenario"], rows)
    env.close()
    # the vector env takes them too: sub-env i is the single env seeded s + i
    venv = gym.make_vec(
        env_id, num_envs=2, vectorization_mode="vector_entry_point", multipath_rows=rows, **SHIFTED
    )
    _, info = venv.reset(seed=SEEDS[0])
    for s in info["scenario"]:
        _check_shifted(s, rows)
    single = gym.make(env_id, multipath_rows=rows, **SHIFTED)
    assert info["scenario"][1] == single.reset(seed=SEEDS[0] + 1)[1]["scenario"]
    venv.close()


@pytest.mark.parametrize("platform", PLATFORMS)
def test_one_shifted_range_moves_only_its_events(platform):
    """``burst_duration`` alone: the bursts' lengths move, every other event of the seed stays."""
    env_id, module, _spec, _ = PLATFORMS[platform]
    base = gym.make(env_id).reset(seed=SEEDS[1])[1]["scenario"]
    shifted = gym.make(env_id, burst_duration=(40.0, 50.0), burst_probability=1.0)
    s = shifted.reset(seed=SEEDS[1])[1]["scenario"]
    assert s.bursts and all(_within(b.end - b.start, (40.0, 50.0), ROUND) for b in s.bursts)
    assert (s.multipath, s.jamming, s.canyons, s.outages) == (
        base.multipath,
        base.jamming,
        base.canyons,
        base.outages,
    )


@pytest.mark.parametrize("platform", PLATFORMS)
def test_the_defaults_passed_explicitly_change_nothing(platform):
    env_id, module, _spec, _ = PLATFORMS[platform]
    plain, explicit = gym.make(env_id), gym.make(env_id, **module.V2_EVENTS)
    for seed in SEEDS[:2]:
        o1, i1 = plain.reset(seed=seed)
        o2, i2 = explicit.reset(seed=seed)
        assert i1["scenario"] == i2["scenario"]
        np.testing.assert_array_equal(o1, o2)
    a = plain.action_space.sample()
    np.testing.assert_array_equal(plain.step(a)[0], explicit.step(a)[0])


@pytest.mark.parametrize("platform", PLATFORMS)
def test_the_v0_v1_ids_still_refuse_the_event_keys(platform):
    _env_id, module, _spec, _v1_id = PLATFORMS[platform]
    prefix = platform
    old = [e[0] for e in ENVIRONMENTS if e[2] == prefix and e[0].endswith(("-v0", "-v1"))]
    assert old
    new_keys = [k for k in module.V2_EVENT_KWARGS if k not in module.SCENARIO_KWARGS]
    with superseded_ids_quiet():
        for env_id in old:
            for key in ("burst_duration", "multipath_bias", new_keys[-1]):
                with pytest.raises(UnknownKeywordError, match=key):
                    gym.make(env_id, **{key: module.V2_EVENTS[key]})
    assert issubclass(UnknownKeywordError, TypeError)


#: Bad values of the event arguments, refused by ScenarioDistribution.
BAD: list[tuple[str, Any]] = [
    ("burst_duration", (30.0, 10.0)),  # low > high
    ("burst_duration", (-5.0, 10.0)),  # a negative duration
    ("multipath_duration", (float("nan"), 10.0)),
    ("jamming_ramp", (-1.0, 2.0)),
    ("multipath_probability", 1.5),
    ("canyon_probability", -0.1),
    ("burst_count", (-1, 2)),
    ("canyon_count", (3, 2)),
    ("multipath_bias", (-1.0, 5.0)),
    ("canyon_loss", (0.0, 1.5)),
    ("canyon_noise_scale", (0.5, 2.0)),
    ("burst_velocity_sigma", (0.0, 1e9)),
]


@pytest.mark.parametrize("platform", PLATFORMS)
@pytest.mark.parametrize(("key", "value"), BAD)
def test_bad_event_values_are_refused_naming_the_argument(platform, key, value):
    env_id = PLATFORMS[platform][0]
    with pytest.raises(ValueError, match=key):
        gym.make(env_id, **{key: value})


@pytest.mark.parametrize(
    ("platform", "key", "value", "harmless_when_off"),
    [
        ("GpsIns", "multipath_count", (2, 9), True),  # more than MULTIPATH_SLOTS (8)
        ("Quadrotor", "multipath_rows", (2, 6), True),  # beyond the 6 fix rows
        ("Robot2d", "multipath_rows", (4,), True),  # the compass is not GNSS
        ("Robot2d", "multipath_rows", (), True),  # no row, with multipath on
        ("GpsIns", "multipath_rows", (1, 1), False),  # a row twice (ScenarioDistribution)
        ("Quadrotor", "multipath_rows", (-1,), False),
    ],
)
def test_the_platform_refuses_events_it_cannot_hold(platform, key, value, harmless_when_off):
    """Refused at ``make``, not at the reset that would draw them; harmless with multipath off."""
    env_id = PLATFORMS[platform][0]
    with pytest.raises(ValueError, match=key):
        gym.make(env_id, **{key: value})
    if harmless_when_off:
        gym.make(env_id, multipath_probability=0.0, **{key: value}).close()


def test_gps_ins_critical_refuses_the_event_arguments_too():
    with pytest.raises(ValueError, match="burst_duration.*would be ignored"):
        gym.make("navgym/GpsInsFading-v2", critical=True, burst_duration=(40.0, 50.0))


@pytest.mark.parametrize("platform", PLATFORMS)
def test_the_v2_card_lists_the_event_arguments(platform):
    env_id, module, _spec, v1_id = PLATFORMS[platform]

    def scenario_arguments(doc: str) -> str:
        flat = " ".join(doc.split())
        return flat[flat.index("Scenario arguments") : flat.index("task defaults")]

    with superseded_ids_quiet():
        v1_doc = type(gym.make(v1_id).unwrapped).__doc__
    v2_doc = type(gym.make(env_id).unwrapped).__doc__
    v2_args, v1_args = scenario_arguments(v2_doc), scenario_arguments(v1_doc)
    for key in module.V2_EVENT_KWARGS:
        assert f"``{key}``" in v2_args
        assert (f"``{key}``" in v1_args) == (key in module.SCENARIO_KWARGS)
    flat = " ".join(v2_doc.split())
    # one list of defaults for the tasks that share them
    assert flat.count("``multipath_duration=") == 1 and "each ``outage_probability=" in flat
    assert "``V2_EVENT_KWARGS``" in flat
