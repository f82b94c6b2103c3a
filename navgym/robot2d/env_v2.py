"""Robot2d v2 environments: the same platform with within-episode events (:data:`ROBOT2D_V2`).

The v2 ids (``navgym/Robot2dFading-v2``) run the Robot2d platform on the scenario defaults
:data:`~navgym.robot2d.env.TASK_SCENARIOS_V2` (wheel-slip bursts, multipath biases, jamming
ramps, urban canyons and several outages per episode, unknown to the filter) and keep the true
noise of every step (``Robot2dPlatform(true_noise=True)``, ``StepModels.truth``). Keyword
arguments, their checks and the card are Robot2d's (:mod:`navgym.robot2d.env`); only the
scenario defaults and the truth differ. The classes keep Robot2d's names so that the registry
entry ``(id, "navgym.robot2d.env_v2", "Robot2d", ...)`` finds them.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.robot2d.env import ROBOT2D, ROBOT2D_CARD, TASK_SCENARIOS_V2, build_platform
from navgym.robot2d.platform import Robot2dPlatform


def build_platform_v2(a: PlatformArgs) -> Robot2dPlatform:
    """:func:`~navgym.robot2d.env.build_platform` keeping the true noise (``true_noise=True``)."""
    return replace(build_platform(a), true_noise=True)


#: Robot2d's declaration with the v2 scenario defaults and the true noise kept.
ROBOT2D_V2: PlatformSpec = replace(ROBOT2D, tasks=TASK_SCENARIOS_V2, build=build_platform_v2)


class Robot2dEnv(PlatformEnv, spec=ROBOT2D_V2):  # noqa: D101 - the card is ROBOT2D_CARD
    __doc__ = ROBOT2D_CARD


class Robot2dVectorEnv(PlatformVectorEnv, spec=ROBOT2D_V2):
    """Native batched Robot2d v2 environment (see :class:`Robot2dEnv` for the card)."""
