"""GpsIns v2 environments: the same platform with within-episode events (:data:`GPS_INS_V2`).

The v2 ids (``navgym/GpsInsFading-v2``) run the GpsIns platform on the scenario defaults
:data:`~navgym.gps_ins.env.TASK_SCENARIOS_V2` (unmodelled manoeuvres, multipath biases on single
satellites, jamming ramps, urban canyons and several outages per episode, unknown to the
filter), keep the true noise of every step (``GpsInsPlatform(true_noise=True)``,
``StepModels.truth``) and observe the filter's bias estimates (``bias_features=True``). The true
IMU is the one the filter assumes (``true_bias_limit_ug=None`` unless given): between events the
plain filter's model is right. Keyword arguments, their checks and the card are GpsIns'
(:mod:`navgym.gps_ins.env`), plus the event ranges: every key of
:data:`~navgym.gps_ins.env.V2_EVENTS` is a keyword argument of the v2 ids
(:data:`~navgym.gps_ins.env.V2_EVENT_KWARGS`, e.g. ``burst_duration=(40.0, 50.0)`` for a shifted
distribution), checked by :class:`~navgym.scenarios.ScenarioDistribution`. The classes keep
GpsIns' names; the v2 entries of :mod:`navgym.gps_ins.env_ids` name this module.
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial

from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.gps_ins.env import (
    GPS_INS,
    GPS_INS_CARD,
    SCENARIO_KWARGS,
    TASK_SCENARIOS_V2,
    V2_EVENT_KWARGS,
    build_platform,
    prepare_arguments,
)
from navgym.gps_ins.platform import MULTIPATH_SLOTS, GpsInsPlatform

#: Scenario keyword arguments of the v2 ids: GpsIns' and the event ranges (no name twice).
SCENARIO_KWARGS_V2: tuple[str, ...] = tuple(dict.fromkeys(SCENARIO_KWARGS + V2_EVENT_KWARGS))


def build_platform_v2(a: PlatformArgs) -> GpsInsPlatform:
    """:func:`~navgym.gps_ins.env.build_platform` with the v2 defaults (module docstring).

    An episode holds at most ``MULTIPATH_SLOTS`` multipath segments: a ``multipath_count`` above
    it is refused here, at ``make``, rather than at the reset that draws that many.
    """
    hi = a.scenarios.multipath_count[1]
    if a.scenarios.multipath_probability > 0.0 and hi > MULTIPATH_SLOTS:
        raise ValueError(
            f"multipath_count must be a pair (low, high) of integers in [1, {MULTIPATH_SLOTS}] on "
            f"GpsIns (an episode holds at most {MULTIPATH_SLOTS} multipath segments); got "
            f"{a.scenarios.multipath_count!r}"
        )
    a.kwargs.setdefault("true_bias_limit_ug", None)
    return replace(build_platform(a), true_noise=True, bias_features=True)


#: GpsIns' declaration with the v2 scenario defaults and event arguments, the true noise kept and
#: the bias features.
GPS_INS_V2: PlatformSpec = replace(
    GPS_INS,
    tasks=TASK_SCENARIOS_V2,
    build=build_platform_v2,
    scenario_arguments=SCENARIO_KWARGS_V2,
    prepare=partial(prepare_arguments, scenario_kwargs=SCENARIO_KWARGS_V2),
)


class GpsInsEnv(PlatformEnv, spec=GPS_INS_V2):  # noqa: D101 - the card is GPS_INS_CARD
    __doc__ = GPS_INS_CARD


class GpsInsVectorEnv(PlatformVectorEnv, spec=GPS_INS_V2):
    """Native batched GpsIns v2 environment (see :class:`GpsInsEnv` for the card)."""
