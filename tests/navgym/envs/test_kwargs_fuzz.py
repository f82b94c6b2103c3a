"""Registry-wide keyword-argument fuzz: every bad value is refused at ``make``, naming the argument.

Table-driven from each platform's declared arguments (``PlatformSpec.keyword_arguments``: the
common ones, ``platform_arguments`` and ``scenario_arguments``): each argument has a kind and a
range here (:data:`ARGUMENTS`), from which the bad values are generated (strings, bools for
numbers, floats for integers, None, NaN, infinities, negative, out of range, huge, pairs of the
wrong length or type). Every registered id is made with each bad value and a small
``episode_steps`` (no reset): the constructor must raise ``TypeError`` or ``ValueError`` naming
the argument, within :data:`TIME_LIMIT_S`. A valid value of each argument must still construct.

``render_mode`` (single and vector env) and ``num_envs`` are fuzzed too. The task arguments
(``lambda_max``, ``eps_max``, ``filter``, ``n_particles``, ...) and the core's (``reward_clip``,
``divergence_penalty``, ...) are not in a table here: each is declared once, with its rule, in
its task's :class:`~navgym.envs.tasks.TaskSpec` (``arguments``) or in
:data:`navgym.envs.core.CORE_ARGUMENTS`, and :func:`declared` generates its valid and bad values
from the rule (plus the values the rule accepts but the task refuses, ``Argument.refused``), so
a new task's arguments are fuzzed as soon as it is registered.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
import pytest

from navgym.envs import ENVIRONMENTS, register_all
from navgym.envs.arguments import Argument, Choice, Flag, Integer, Interval, Real, Reals
from navgym.envs.core import CORE_ARGUMENTS
from navgym.envs.platform import MAX_EPISODE_STEPS, PlatformSpec
from navgym.envs.tasks import task_spec
from navgym.gps_ins.env import GPS_INS
from navgym.iridium.env import IRIDIUM
from navgym.jpa.env import JPA
from navgym.pedestrian.env import PEDESTRIAN
from navgym.quadrotor.env import QUADROTOR
from navgym.quadrotor.flight import QuadrotorParams
from navgym.recordings.env_v2 import REPLAY_V2
from navgym.robot2d.env import ROBOT2D
from navgym.scenarios.distribution import MAX_ERROR_M, MAX_OUTAGE_COUNT, MAX_VAR_RATIO
from navgym.scenarios.scenario import MAX_PRN
from navgym.signal_tracking.env import SIGNAL_TRACKING

#: Constructing an env with a bad argument must fail within this [s] (no simulation, no hang).
TIME_LIMIT_S = 2.0
#: Small horizon of the fuzzed envs (the scenarios' start margin and durations fit it).
STEPS = 50
NAN, INF = float("nan"), float("inf")
SPECS: dict[str, PlatformSpec] = {
    "GpsIns": GPS_INS,
    "Quadrotor": QUADROTOR,
    "Iridium": IRIDIUM,
    "Pedestrian": PEDESTRIAN,
    "Robot2d": ROBOT2D,
    # the replay ids' scenario arguments of this table (the other event ranges: tests/navgym/replay)
    "Replay": replace(
        REPLAY_V2,
        scenario_arguments=tuple(
            k
            for k in REPLAY_V2.scenario_arguments
            if k.startswith(("outage_", "jamming_", "start_"))
            and k != "jamming_count"
            and k != "jamming_ramp"
        ),
    ),
}


class Arg(NamedTuple):
    """An argument's valid value and the bad values it must refuse."""

    valid: Any
    bad: tuple[Any, ...]


def _not_numbers(valid: Any) -> list[Any]:
    return [str(valid), True, False, np.bool_(True), complex(1.0, 0.0), [valid], {"value": valid}]


def real(
    valid: float,
    low: float,
    high: float = INF,
    *,
    low_open: bool = False,
    high_open: bool = False,
    none_ok: bool = False,
    above: float | None = None,
) -> Arg:
    """A finite real number in ``[low, high]`` (open ends where given)."""
    bad = [*_not_numbers(valid), NAN, INF, -INF, np.float64(NAN), (valid, valid)]
    bad.append(low if low_open else low - 1.0)
    bad.append(-1e300)
    if math.isfinite(high):
        bad += [high if high_open else high * 1.5 + 1.0, 1e300]
    if above is not None:
        bad.append(above)
    if not none_ok:
        bad.append(None)
    return Arg(valid, tuple(bad))


def integer(valid: int, low: int, high: int | None = None, *, huge: tuple[int, ...] = ()) -> Arg:
    """An integer in ``[low, high]``: no floats (even integral ones), no bools, no strings."""
    bad = [
        *_not_numbers(valid),
        float(valid),
        valid + 0.5,
        np.float64(valid),
        NAN,
        INF,
        None,
        low - 1,
        -(10**9),
    ]
    if high is not None:
        bad += [high + 1, 10**18]
    return Arg(valid, tuple(bad) + huge)


def flag(valid: bool = False) -> Arg:
    """A bool: ``"no"``, 0, 1, NaN or None are not bools."""
    return Arg(valid, ("no", "False", "True", 0, 1, 1.0, NAN, None, [True], np.float64(1.0)))


def choice(valid: str) -> Arg:
    """One of a few strings."""
    return Arg(valid, ("bogus", "", valid.upper(), valid + " ", 1, 1.5, True, None, (valid,), [valid]))


def pair(
    valid: tuple[float, float],
    low: float,
    high: float = INF,
    *,
    low_open: bool = False,
    high_open: bool = False,
    none_ok: bool = False,
) -> Arg:
    """A pair ``(lo, hi)`` of finite reals with ``low <= lo <= hi <= high``."""
    lo, hi = valid
    below = low if low_open else low - 1.0
    bad = [
        "ab",
        str(valid),
        b"ab",
        lo,
        True,
        (lo,),
        (lo, hi, hi),
        ((lo, hi), (lo, hi)),
        {lo: hi},
        (str(lo), hi),
        (lo, str(hi)),
        (True, hi),
        (lo, np.bool_(True)),
        (None, hi),
        (NAN, hi),
        (lo, NAN),
        (lo, INF),
        (-INF, hi),
        (hi + 1.0, lo) if hi + 1.0 <= high else (hi, lo - 0.5),
        (below, hi),
        (below, below),
        (-1e300, hi),
        np.array([[lo, hi]]),
    ]
    if math.isfinite(high):
        top = high if high_open else high * 1.5 + 1.0
        bad += [(lo, top), (top, top), (lo, 1e300)]
    if not none_ok:
        bad.append(None)
    return Arg(valid, tuple(bad))


def count(valid: tuple[int, int], low: int, high: int) -> Arg:
    """A pair ``(lo, hi)`` of integers with ``low <= lo <= hi <= high``."""
    lo, hi = valid
    return Arg(
        valid,
        (
            "12",
            lo,
            None,
            (lo,),
            (lo, hi, hi),
            (lo + 0.5, hi),
            (float(lo), hi),
            (lo, float(hi)),
            (str(lo), hi),
            (True, hi),
            (lo, np.float64(hi)),
            (NAN, hi),
            (lo, INF),
            (hi + 1, lo) if hi + 1 <= high else (hi, lo - 1),
            (low - 1, hi),
            (lo, high + 1),
            (lo, 10**9),
            (lo, 10**18),
            (-(10**9), hi),
        ),
    )


def reals(valid: tuple[float, ...], low: float, high: float = INF) -> Arg:
    """A tuple (possibly empty) of finite reals in ``[low, high]``."""
    bad = ["ab", "1", 5.0, True, None, ("1",), (True,), (None,), (NAN,), (INF,), (low - 1.0,), ((1.0, 2.0),)]
    if math.isfinite(high):
        bad += [(high * 1.5 + 1.0,), (1e300,)]
    return Arg(valid, tuple(bad))


def instance(valid: Any) -> Arg:
    """An instance of a given class."""
    return Arg(valid, ("bogus", None, 1, 1.5, True, {}, (), [valid]))


#: Scenario arguments (shared by the platforms; :class:`ScenarioDistribution`'s ranges).
SCENARIO: dict[str, Arg] = {
    **{
        name: real(0.5, 0.0, 1.0)
        for name in (
            "outage_probability",
            "partial_probability",
            "impulsive_probability",
            "jamming_probability",
            "outlier_probability",
        )
    },
    **{
        name: pair((1.0, 2.0), 0.0)
        for name in (
            "outage_duration",
            "partial_duration",
            "impulsive_duration",
            "jamming_duration",
            "outlier_duration",
        )
    },
    **{name: pair((0.1, 0.3), 0.0, 1.0) for name in ("impulsive_eps", "jamming_loss", "outlier_rate")},
    "jamming_sigma": pair((10.0, 50.0), 0.0, MAX_ERROR_M),
    "outlier_scale": pair((50.0, 300.0), 0.0, MAX_ERROR_M),
    "impulsive_var_ratio": pair((50.0, 2000.0), 1.0, MAX_VAR_RATIO),
    "outage_count": count((1, 3), 0, MAX_OUTAGE_COUNT),
    "partial_satellites": count((2, 4), 0, MAX_PRN),
    "outage_duration_choices": reals((1.0, 2.0), 0.0),
    "impulsive_var_ratio_choices": reals((50.0, 100.0), 1.0, MAX_VAR_RATIO),
    # below the episode's length (STEPS dt); 1e9 s is beyond it
    "start_margin": real(0.5, 0.0, above=1e9),
    # GpsIns: one fixed mask instead of the distribution's range
    "mask_deg": real(15.0, 0.0, 90.0, high_open=True),
}
#: Arguments every platform reads through the skeleton.
COMMON: dict[str, Arg] = {
    "episode_steps": integer(STEPS, 1, None, huge=(MAX_EPISODE_STEPS + 1, 10**7, 10**9, 10**30)),
    "error_scale_m": real(3.0, 0.0, low_open=True),
    "divergence_m": real(300.0, 0.0, low_open=True),
}
#: Each platform's own arguments (``PlatformSpec.platform_arguments``) and its ``dt``.
PLATFORM: dict[str, dict[str, Arg]] = {
    "GpsIns": {
        "dt": real(2.0, 0.0, 60.0, low_open=True),
        "vehicle": choice("ship"),
        "imu_grade": choice("tactical"),
        "m_max": integer(6, 4, 16),
        "sigma_pr": real(3.0, 0.0, 1000.0, low_open=True),
        "critical": flag(False),
        "true_bias_limit_ug": pair((10.0, 100.0), 0.0, 1e5, low_open=True, none_ok=True),
    },
    "Quadrotor": {
        "dt": real(0.05, 0.0, 1.0, low_open=True),
        "imu_rate_hz": Arg(100.0, (*real(100.0, 0.0, 2000.0, low_open=True).bad, 123.0, 1e-3)),
        "imu_grade": choice("tactical"),
        "imu_mismatch": pair((1.0, 2.0), 0.0, 100.0, low_open=True, none_ok=True),
        "sigma_pos": real(3.0, 0.0, 1000.0, low_open=True),
        "sigma_vel": real(0.2, 0.0, 100.0, low_open=True),
        "flight": instance(QuadrotorParams()),
    },
    "Iridium": {
        "cep_zenith": real(650.0, 0.0, 1e5, low_open=True),
        "outlier_rate": real(0.03, 0.0, 1.0),
        "gross_rate": real(0.001, 0.0, 1.0),
        "accel_psd": real(0.025, 0.0, 1e3, low_open=True),
    },
    "Pedestrian": {
        "imu_rate_hz": integer(50, 2, 1000),
        "sigma_pos": real(3.0, 0.0, 1000.0, low_open=True),
        "sigma_zupt": real(0.05, 0.0, 10.0, low_open=True),
    },
    "Replay": {
        "dt": Arg(0.25, (*real(0.25, 0.0, 1.0, low_open=True).bad, 0.1)),  # the recording's epochs
        "recording": Arg(None, (1, True, 2.5, "/nonexistent/recording", ["a"])),
        "sigma_pos": real(0.2, 0.0, 1000.0, low_open=True),
        "sigma_vel": real(0.1, 0.0, 100.0, low_open=True),
    },
    "Robot2d": {
        "sigma_gps": real(2.0, 0.0, 1000.0, low_open=True),
        "sigma_glonass": real(4.0, 0.0, 1000.0, low_open=True),
        "sigma_compass_deg": real(1.0, 0.0, 180.0, low_open=True),
        "sigma_encoder": real(0.1, 0.0, 10.0, low_open=True),
        "sigma_steering_deg": real(1.0, 0.0, 90.0, low_open=True),
        "encoder_scale_sigma": real(0.05, 0.0, 1.0),
        "slip_sigma": real(0.5, 0.0, 100.0),
        "yaw_sigma": real(0.05, 0.0, 10.0),
    },
}
# Jpa: its own arguments; its scenario table here the outages and start margin (the multipath ranges are
# ScenarioDistribution's, fuzzed on the other v2 ids; multipath_rows: tests/navgym/jpa)
SPECS["Jpa"] = replace(
    JPA, scenario_arguments=("outage_probability", "outage_count", "outage_duration", "start_margin")
)
PLATFORM["Jpa"] = {
    "slip_probability": real(0.9, 0.0, 1.0),
    "slip_max_cycles": integer(5, 1, 100),
    "attitude_weight": real(0.1, 0.0, 100.0),
}
# SignalTracking: its own arguments; its scenario arguments are the outages (signal blockages; the
# start margin is fuzzed on the other ids: its valid 0.5 s is the whole of a 50-step, 10 ms episode)
SPECS["SignalTracking"] = replace(
    SIGNAL_TRACKING, scenario_arguments=("outage_probability", "outage_count", "outage_duration")
)
PLATFORM["SignalTracking"] = {
    "snr_db": real(0.0, -10.0, 20.0),
    "jump_rate": real(2.0, 0.0, 50.0),
    "jump_max_g": real(10.0, 0.0, 50.0),
    "doppler_weight": real(0.1, 0.0, 100.0),
    "codes_per_step": integer(10, 1, 100),
}
#: Arguments of the vector env only (through ``gym.make_vec``).
VECTOR: dict[str, Arg] = {
    "num_envs": integer(2, 1, None),
    "render_mode": Arg(None, ("bogus", "rgb_array", "human", "ansi", "", 1, True, ["rgb_array"])),
}
#: Arguments of the single env only. Strings only: ``gym.make`` itself calls
#: ``render_mode.endswith`` (an AttributeError for 1 or True, before the env is called) and turns
#: ``"human"`` and ``"rgb_array_list"`` into ``"rgb_array"`` with a wrapper.
SINGLE: dict[str, Arg] = {"render_mode": Arg("rgb_array", ("bogus", "ansi", "depth_array", ""))}


def table(platform: str) -> dict[str, Arg]:
    """Every keyword argument of the platform with its valid and bad values."""
    spec = SPECS[platform]
    own = {**COMMON, **PLATFORM[platform], **{k: SCENARIO[k] for k in spec.scenario_arguments}}
    return {k: own[k] for k in spec.keyword_arguments}


class Outcome(NamedTuple):
    argument: str
    value: Any
    error: BaseException | None  # None: accepted
    seconds: float

    @property
    def named(self) -> bool:
        """Refused with a TypeError or ValueError whose message names the argument."""
        return isinstance(self.error, (TypeError, ValueError)) and self.argument in str(self.error)


def _entry(env_id: str) -> tuple[str, str, dict[str, Any]]:
    for eid, _module, prefix, _task, _steps, defaults in ENVIRONMENTS:
        if eid == env_id:
            return prefix, eid, defaults
    raise KeyError(env_id)


def attempt(make: Callable[..., Any], env_id: str, argument: str, value: Any, **extra: Any) -> Outcome:
    kwargs = {"episode_steps": STEPS, **extra, argument: value}
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # gymnasium's notices (render modes, -v0 ids)
            env = make(env_id, **kwargs)
        env.close()
        error = None
    except Exception as exc:
        error = exc
    return Outcome(argument, value, error, time.perf_counter() - t0)


def fuzz(env_id: str) -> list[Outcome]:
    """Make ``env_id`` with every bad value of every argument of its platform (no reset)."""
    register_all()
    platform, _, _ = _entry(env_id)
    out = [attempt(gym.make, env_id, k, v) for k, arg in table(platform).items() for v in arg.bad]
    out += [attempt(gym.make, env_id, k, v) for k, arg in SINGLE.items() for v in arg.bad]
    out += [
        attempt(gym.make_vec, env_id, k, v, **({"num_envs": 2} if k != "num_envs" else {}))
        for k, arg in VECTOR.items()
        for v in arg.bad
    ]
    return out


IDS = [e[0] for e in ENVIRONMENTS]


def test_the_table_covers_every_declared_argument():
    for name, spec in SPECS.items():
        assert spec.platform_arguments, f"{name} declares no platform_arguments"
        missing = set(spec.keyword_arguments) - set(table(name))
        assert not missing, f"{name}: no fuzz entry for {sorted(missing)}"
        assert set(PLATFORM[name]) - {"dt"} == set(spec.platform_arguments)


@pytest.mark.parametrize("env_id", IDS)
def test_every_bad_keyword_argument_is_refused_at_make_naming_it(env_id):
    outcomes = fuzz(env_id)
    wrong = [o for o in outcomes if not o.named]
    assert not wrong, "\n".join(
        f"{o.argument}={o.value!r}: "
        + ("accepted" if o.error is None else f"{type(o.error).__name__}: {str(o.error)[:150]}")
        for o in wrong
    )
    slow = [o for o in outcomes if o.seconds > TIME_LIMIT_S]
    assert not slow, [(o.argument, o.value, round(o.seconds, 2)) for o in slow]


@pytest.mark.parametrize("env_id", IDS)
def test_every_valid_keyword_argument_still_constructs(env_id):
    register_all()
    platform, _, _ = _entry(env_id)
    for k, arg in {**table(platform), **SINGLE}.items():
        o = attempt(gym.make, env_id, k, arg.valid)
        assert o.error is None, f"{k}={arg.valid!r}: {o.error!r}"
    for k, arg in VECTOR.items():
        o = attempt(gym.make_vec, env_id, k, arg.valid, **({"num_envs": 2} if k != "num_envs" else {}))
        assert o.error is None, f"{k}={arg.valid!r}: {o.error!r}"


def declared(argument: Argument) -> Arg:
    """The valid value (the default) and bad values of a declared argument, from its rule."""
    rule = argument.rule
    if isinstance(rule, Real):
        arg = real(argument.default, rule.low, rule.high, low_open=rule.low_open, high_open=rule.high_open)
    elif isinstance(rule, Integer):
        arg = integer(argument.default, rule.low, rule.high)
    elif isinstance(rule, Flag):
        arg = flag(argument.default)
    elif isinstance(rule, Choice):
        arg = choice(argument.default)
    elif isinstance(rule, Interval):
        arg = pair(argument.default, rule.low, rule.high, low_open=rule.low_open, high_open=rule.high_open)
    elif isinstance(rule, Reals):  # an optional table of reals (None: off)
        bad = ("table", (1.0,) * (rule.size - 1), (float("nan"),) * rule.size, (rule.low,) * rule.size)
        arg = Arg(argument.default, bad if rule.low_open else bad[:3])
    else:  # pragma: no cover - a new kind of rule needs its generator here
        raise TypeError(f"no fuzz values for the rule {rule!r} of {argument.name}")
    return Arg(arg.valid, arg.bad + argument.refused)


def task_table(task: str) -> dict[str, Arg]:
    """Every keyword argument of ``task`` (its spec's) with its valid and bad values."""
    return {a.name: declared(a) for a in task_spec(task).arguments}


#: The core's keyword arguments (``max_episode_steps``: :func:`test_task_and_core_arguments`).
CORE: dict[str, Arg] = {a.name: declared(a) for a in CORE_ARGUMENTS if a.name != "max_episode_steps"}


@pytest.mark.parametrize("env_id", IDS)
def test_task_and_core_arguments(env_id):
    """Bad task and core arguments (their declared rules, the v2 options included) refused, named."""
    register_all()
    task = gym.spec(env_id).kwargs["task"]
    table = {**task_table(task), **CORE}
    outcomes = [attempt(gym.make, env_id, k, v) for k, arg in table.items() for v in arg.bad]
    outcomes += [
        attempt(gym.make_vec, env_id, "max_episode_steps", v, num_envs=2) for v in (1.5, "600", True, 0, -1)
    ]
    slow = [(o.argument, o.value, round(o.seconds, 2)) for o in outcomes if o.seconds > TIME_LIMIT_S]
    assert not slow, slow
    wrong = [f"{o.argument}={o.value!r}: {o.error!r}" for o in outcomes if not o.named]
    assert not wrong, wrong
    for k, arg in table.items():  # the declared defaults construct
        o = attempt(gym.make, env_id, k, arg.valid)
        assert o.error is None, f"{k}={arg.valid!r}: {o.error!r}"
