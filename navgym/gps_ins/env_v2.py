"""GpsIns v2 environments: the same platform with within-episode events (:data:`GPS_INS_V2`).

The v2 ids (``navgym/GpsInsFading-v2``) run the GpsIns platform on the scenario defaults
:data:`~navgym.gps_ins.env.TASK_SCENARIOS_V2` (unmodelled manoeuvres, multipath biases on single
satellites, jamming ramps, urban canyons and several outages per episode, unknown to the
filter), keep the true noise of every step (``GpsInsPlatform(true_noise=True)``,
``StepModels.truth``) and observe the filter's bias estimates (``bias_features=True``). The true
IMU is the one the filter assumes (``true_bias_limit_ug=None`` unless given): between events the
plain filter's model is right. Keyword arguments, their checks and the card are GpsIns'
(:mod:`navgym.gps_ins.env`); only these defaults differ. The classes keep GpsIns' names so that
the registry entry ``(id, "navgym.gps_ins.env_v2", "GpsIns", ...)`` finds them.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.gps_ins.env import GPS_INS, GPS_INS_CARD, TASK_SCENARIOS_V2, build_platform
from navgym.gps_ins.platform import GpsInsPlatform


def build_platform_v2(a: PlatformArgs) -> GpsInsPlatform:
    """:func:`~navgym.gps_ins.env.build_platform` with the v2 defaults (module docstring)."""
    a.kwargs.setdefault("true_bias_limit_ug", None)
    return replace(build_platform(a), true_noise=True, bias_features=True)


#: GpsIns' declaration with the v2 scenario defaults, the true noise kept and the bias features.
GPS_INS_V2: PlatformSpec = replace(GPS_INS, tasks=TASK_SCENARIOS_V2, build=build_platform_v2)


class GpsInsEnv(PlatformEnv, spec=GPS_INS_V2):  # noqa: D101 - the card is GPS_INS_CARD
    __doc__ = GPS_INS_CARD


class GpsInsVectorEnv(PlatformVectorEnv, spec=GPS_INS_V2):
    """Native batched GpsIns v2 environment (see :class:`GpsInsEnv` for the card)."""
