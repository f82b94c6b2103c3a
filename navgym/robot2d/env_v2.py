"""Robot2d v2 environments: the same platform with within-episode events (:data:`ROBOT2D_V2`).

The v2 ids (``navgym/Robot2dFading-v2``) run the Robot2d platform on the scenario defaults
:data:`~navgym.robot2d.env.TASK_SCENARIOS_V2` (wheel-slip bursts, multipath biases, jamming
ramps, urban canyons and several outages per episode, unknown to the filter) and keep the true
noise of every step (``Robot2dPlatform(true_noise=True)``, ``StepModels.truth``). Keyword
arguments, their checks and the card are Robot2d's (:mod:`navgym.robot2d.env`), plus the event
ranges: every key of :data:`~navgym.robot2d.env.V2_EVENTS` is a keyword argument of the v2 ids
(:data:`~navgym.robot2d.env.V2_EVENT_KWARGS`, e.g. ``burst_duration=(20.0, 60.0)`` for a shifted
distribution), checked by :class:`~navgym.scenarios.ScenarioDistribution`. Only the scenario
defaults and arguments and the truth differ. The classes keep Robot2d's names; the v2 entries
of :mod:`navgym.robot2d.env_ids` name this module.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs import arguments
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.robot2d.env import (
    ROBOT2D,
    ROBOT2D_CARD,
    SCENARIO_KWARGS,
    TASK_SCENARIOS_V2,
    V2_EVENT_KWARGS,
    build_platform,
)
from navgym.robot2d.platform import GNSS_ROWS, Robot2dPlatform

#: Scenario keyword arguments of the v2 ids: Robot2d's and the event ranges (no name twice).
SCENARIO_KWARGS_V2: tuple[str, ...] = tuple(dict.fromkeys(SCENARIO_KWARGS + V2_EVENT_KWARGS))


def build_platform_v2(a: PlatformArgs) -> Robot2dPlatform:
    """:func:`~navgym.robot2d.env.build_platform` keeping the true noise (``true_noise=True``).

    ``multipath_rows`` must be GNSS rows (``GNSS_ROWS``: GPS N/E, GLONASS N/E; the compass is
    not GNSS), checked here at ``make`` rather than at the reset that draws them.
    """
    arguments.multipath_rows(
        a.scenarios, GNSS_ROWS, "GNSS rows of Robot2d (GPS N/E, GLONASS N/E; the compass is not GNSS)"
    )
    return replace(build_platform(a), true_noise=True)


#: Robot2d's declaration with the v2 scenario defaults and event arguments and the true noise kept.
ROBOT2D_V2: PlatformSpec = replace(
    ROBOT2D, tasks=TASK_SCENARIOS_V2, build=build_platform_v2, scenario_arguments=SCENARIO_KWARGS_V2
)


class Robot2dEnv(PlatformEnv, spec=ROBOT2D_V2):  # noqa: D101 - the card is ROBOT2D_CARD
    __doc__ = ROBOT2D_CARD


class Robot2dVectorEnv(PlatformVectorEnv, spec=ROBOT2D_V2):
    """Native batched Robot2d v2 environment (see :class:`Robot2dEnv` for the card)."""
