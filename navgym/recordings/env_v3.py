"""Replay v3 environments: the real walk with the v3 context and the RowScale knob (:data:`REPLAY_V3`).

The v3 variant replays the recording as the v2 ids do (the same injected events,
:data:`~navgym.recordings.env_v2.REPLAY_EVENTS`) with ``ReplayPlatform(context=True)``: the IMU
statistics of the observation come from the *recorded* IMU, the receiver's report (satellites,
HDOP, per-row C/N0 and accuracy figures) from the Quadrotor's receiver chain under the injected
events (the recording's RTKLIB solution reports no C/N0), so the observation has the
``navgym/QuadrotorRowScale-v3`` layout and its agents run on the walk untouched. It is an
evaluation id (real data; nothing is trained on it). See :mod:`navgym.recordings.platform`.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs.cards import with_paragraph
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.gnss.receiver_report import cn0_offset_argument
from navgym.recordings.env_v2 import (
    REPLAY_CARD,
    REPLAY_EVENTS,
    REPLAY_PLATFORM_KWARGS,
    REPLAY_V2,
    build_replay,
)
from navgym.recordings.platform import ReplayPlatform


def build_replay_v3(a: PlatformArgs) -> ReplayPlatform:
    """:func:`~navgym.recordings.env_v2.build_replay` with the context (``context=True``).

    ``cn0_offset_db`` shifts the receiver's C/N0 report (as on the Quadrotor v3 ids), in
    ``[-CN0_OFFSET_MAX_DB, CN0_OFFSET_MAX_DB]``.
    """
    return replace(build_replay(a), context=True, cn0_offset_db=cn0_offset_argument(a.kwargs))


#: The replay's v2 declaration with the context, the RowScale task only, and ``cn0_offset_db``.
REPLAY_V3: PlatformSpec = replace(
    REPLAY_V2,
    build=build_replay_v3,
    tasks={"rowscale": dict(REPLAY_EVENTS)},
    platform_arguments=(*REPLAY_PLATFORM_KWARGS, "cn0_offset_db"),
)

CONTEXT_TEXT = (
    "**Context (v3)** (:mod:`navgym.quadrotor.context`, ``context=True``): the observation has the "
    "``navgym/QuadrotorRowScale-v3`` layout, so the Quadrotor's v3 agents run here untouched. The IMU "
    "statistics (``imu_activity``, ``imu_gyro_activity``, ``imu_specific_force``, "
    "``imu_angular_rate``: spreads and means over the last 1 s) come from the recorded IMU samples "
    "of the walk (plus the injected vibration): a walker's steps give an ``imu_activity`` of a few "
    "m/s^2, far above a quadrotor's in flight. The recording's solution file reports no C/N0, and the "
    "events are injected, so the receiver's report (``row_cn0``, ``row_reported_sigma``, "
    "``gnss_n_sv``, ``gnss_hdop``, ``gnss_report_age``) is the Quadrotor v3's simulated receiver "
    "under the episode's canyons, multipath and jammers (J/S referred to the nominal 0.1 m fix), and "
    "the injected fix noise follows it (``sigma^2 HDOP^2 u`` per row, the recording's own error the "
    "nominal part). ``cn0_offset_db`` [dB] in [-10, 10] offsets the C/N0 report. An evaluation id: "
    "real data, nothing is trained or gated on it."
)

_V3_HISTORY = (
    "    * v3: the context above and the RowScale knob (one noise multiplier per fix row and a "
    "process-noise\n      scale on position and velocity); the v2 events, memory and bias features.\n"
)

REPLAY_V3_CARD = with_paragraph(REPLAY_CARD, CONTEXT_TEXT).rstrip("\n") + "\n" + _V3_HISTORY


class ReplayEnv(PlatformEnv, spec=REPLAY_V3):  # noqa: D101 - the card is REPLAY_V3_CARD
    __doc__ = REPLAY_V3_CARD


class ReplayVectorEnv(PlatformVectorEnv, spec=REPLAY_V3):
    """Native batched replay v3 environment (see :class:`ReplayEnv` for the card)."""
