"""Quadrotor v2 environments: the same platform with within-episode events (:data:`QUADROTOR_V2`).

The v2 ids (``navgym/QuadrotorFading-v2``) run the Quadrotor platform on the scenario defaults
:data:`~navgym.quadrotor.env.TASK_SCENARIOS_V2` (vibration bursts, multipath biases on the fix's
position rows, jamming ramps, urban canyons and several outages per episode, unknown to the
filter), with the true IMU the grade the filter assumes (no ``imu_mismatch`` unless given), keep
the true noise of every step (``QuadrotorPlatform(true_noise=True)``, ``StepModels.truth``) and
observe the filter's bias estimates and their rates (``bias_features=True``). Keyword arguments,
their checks and the card are Quadrotor's (:mod:`navgym.quadrotor.env`), plus the event ranges:
every key of :data:`~navgym.quadrotor.env.V2_EVENTS` is a keyword argument of the v2 ids
(:data:`~navgym.quadrotor.env.V2_EVENT_KWARGS`, e.g. ``burst_duration=(10.0, 20.0)`` for a
shifted distribution), checked by :class:`~navgym.scenarios.ScenarioDistribution`. Only the
scenario defaults and arguments, the IMU mismatch default, the truth and the bias features
differ. The classes keep Quadrotor's names; the v2 entries of
:mod:`navgym.quadrotor.env_ids` name this module.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs import arguments
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.quadrotor.env import (
    QUADROTOR,
    QUADROTOR_CARD,
    SCENARIO_KWARGS,
    TASK_SCENARIOS_V2,
    V2_EVENT_KWARGS,
    build_platform,
)
from navgym.quadrotor.models import M_ROWS
from navgym.quadrotor.platform import QuadrotorPlatform

#: Scenario keyword arguments of the v2 ids: Quadrotor's and the event ranges (no name twice).
SCENARIO_KWARGS_V2: tuple[str, ...] = tuple(dict.fromkeys(SCENARIO_KWARGS + V2_EVENT_KWARGS))


def build_platform_v2(a: PlatformArgs) -> QuadrotorPlatform:
    """:func:`~navgym.quadrotor.env.build_platform` with the v2 defaults.

    No IMU mismatch unless given, the true noise kept (``true_noise=True``) and the bias estimates
    observed (``bias_features=True``). ``multipath_rows`` must be rows of the fix (0-5: N, E, D
    position, then velocity), checked here at ``make`` rather than at the reset that draws them.
    """
    arguments.multipath_rows(a.scenarios, range(M_ROWS), "rows of the Quadrotor fix (position rows 0-2)")
    a.kwargs.setdefault("imu_mismatch", None)
    return replace(build_platform(a), true_noise=True, bias_features=True)


#: Quadrotor's declaration with the v2 scenario defaults and event arguments, the true noise and
#: the bias features.
QUADROTOR_V2: PlatformSpec = replace(
    QUADROTOR, tasks=TASK_SCENARIOS_V2, build=build_platform_v2, scenario_arguments=SCENARIO_KWARGS_V2
)


class QuadrotorEnv(PlatformEnv, spec=QUADROTOR_V2):  # noqa: D101 - the card is QUADROTOR_CARD
    __doc__ = QUADROTOR_CARD


class QuadrotorVectorEnv(PlatformVectorEnv, spec=QUADROTOR_V2):
    """Native batched Quadrotor v2 environment (see :class:`QuadrotorEnv` for the card)."""
