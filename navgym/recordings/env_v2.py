"""Replay environments: a real recording with injected v2 degradations (``navgym/Replay*-v2``).

The platform is :class:`navgym.recordings.platform.ReplayPlatform` (the Quadrotor's loosely
coupled INS/GNSS problem fed with a recording's IMU and fixes); the tasks are the shared
Fading and NoiseScale; the events are the v2 scenario processes (:mod:`navgym.scenarios`) with
ranges scaled to a walk with RTK fixes (:data:`REPLAY_EVENTS`). ``recording=DIR`` replays any
directory in the format of :mod:`navgym.recordings.loader`.
"""

from __future__ import annotations

import os
import textwrap
from typing import Any

from navgym.envs import arguments
from navgym.envs.cards import span
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.quadrotor.env import (
    LAMBDA_MAX_PER_SECOND,
    MAX_SIGMA_POS_M,
    MAX_SIGMA_VEL_MS,
    MIN_SIGMA_POS_M,
    MIN_SIGMA_VEL_MS,
)
from navgym.quadrotor.models import M_ROWS
from navgym.recordings.platform import (
    SIGMA_POS_REPLAY_M,
    SIGMA_VEL_REPLAY_MS,
    ReplayPlatform,
    replay_platform,
)

#: The injected events of the replay ids (60 s windows; events start after 6 s), scaled to a
#: walk whose fixes are RTK (centimetres): outages, jamming ramps (noise and lost fixes),
#: multipath biases on the position rows, urban canyons, vibration of the IMU.
REPLAY_EVENTS: dict[str, Any] = {
    "outage_probability": 0.8,
    "outage_count": (1, 2),
    "outage_duration": (5.0, 15.0),
    "jamming_probability": 0.6,
    "jamming_count": (1, 2),
    "jamming_duration": (5.0, 15.0),
    "jamming_sigma": (0.5, 3.0),
    "jamming_loss": (0.0, 0.3),
    "jamming_ramp": (1.0, 4.0),
    "burst_probability": 0.5,
    "burst_count": (1, 2),
    "burst_duration": (2.0, 8.0),
    "burst_velocity_sigma": (0.01, 0.05),
    "burst_yaw_rate_sigma": (0.0005, 0.002),
    "multipath_probability": 0.8,
    "multipath_count": (1, 3),
    "multipath_duration": (4.0, 12.0),
    "multipath_bias": (0.5, 3.0),
    "multipath_sigma": (0.0, 0.3),
    "multipath_rows": (0, 1, 2),
    "canyon_probability": 0.4,
    "canyon_count": (1, 1),
    "canyon_duration": (4.0, 10.0),
    "canyon_satellites": (3, 8),
    "canyon_noise_scale": (2.0, 5.0),
    "canyon_loss": (0.0, 0.5),
}
#: Scenario keyword arguments of the replay ids: the event ranges and the start margin.
REPLAY_SCENARIO_KWARGS: tuple[str, ...] = (*REPLAY_EVENTS, "start_margin")
#: The replay ids' tasks and their scenario defaults.
REPLAY_TASKS: dict[str, dict[str, Any]] = {t: dict(REPLAY_EVENTS) for t in ("fading", "noisescale")}
#: The replay platform's own keyword arguments.
REPLAY_PLATFORM_KWARGS = ("recording", "sigma_pos", "sigma_vel")
#: Default episode: 240 steps of 0.25 s (the walk's 4 Hz fixes) = 60 s.
REPLAY_STEPS = 240
REPLAY_DT = 0.25


def build_replay(a: PlatformArgs) -> ReplayPlatform:
    """The replay platform of ``recording`` (None: the packaged walk) from the keyword arguments.

    ``recording`` must be a directory in the format of :mod:`navgym.recordings.loader` (checked
    here, at ``make``, with the loader's errors), ``dt`` its GNSS epoch interval, and
    ``episode_steps`` must fit in its truth span; ``multipath_rows`` must be fix rows (0-5).
    """
    kw = a.kwargs
    rec = kw.pop("recording", None)
    if rec is not None and (not isinstance(rec, str | os.PathLike) or isinstance(os.fspath(rec), bytes)):
        raise arguments.ArgumentTypeError(
            f"recording must be a directory path (str or os.PathLike of str) or None; got {rec!r} "
            f"({type(rec).__name__})"
        )
    arguments.multipath_rows(a.scenarios, range(M_ROWS), "rows of the fix (position rows 0-2)")
    platform = replay_platform(
        rec,
        dt=a.dt,
        sigma_pos=arguments.real(
            "sigma_pos", kw.pop("sigma_pos", SIGMA_POS_REPLAY_M), MIN_SIGMA_POS_M, MAX_SIGMA_POS_M
        ),
        sigma_vel=arguments.real(
            "sigma_vel", kw.pop("sigma_vel", SIGMA_VEL_REPLAY_MS), MIN_SIGMA_VEL_MS, MAX_SIGMA_VEL_MS
        ),
        scenarios=a.scenarios,
        error_scale_m=a.error_scale_m,
        divergence_m=a.divergence_m,
        true_noise=True,
        bias_features=True,
    )
    platform.check_horizon(a.steps)
    return platform


#: The replay platform's declaration.
REPLAY_V2 = PlatformSpec(
    name="Replay",
    build=build_replay,
    tasks=REPLAY_TASKS,
    scenario_arguments=REPLAY_SCENARIO_KWARGS,
    episode_steps=REPLAY_STEPS,
    dt=REPLAY_DT,
    dt_max=1.0,
    error_scale_m=1.0,
    divergence_m=100.0,
    start_margin_s=6.0,
    lambda_max_per_second=LAMBDA_MAX_PER_SECOND,
    platform_arguments=REPLAY_PLATFORM_KWARGS,
)


def _events_text(e: dict[str, Any]) -> str:
    text = (
        "**Injected events** (scenario defaults ``REPLAY_EVENTS``, the v2 processes of "
        ":mod:`navgym.scenarios` as on the Quadrotor v2 ids, ranges scaled to a walk with RTK "
        "fixes; the filter's ``Q`` and ``R`` stay nominal): "
        f"{span(e['outage_count'])} GNSS outages of {span(e['outage_duration'], 's')} "
        f"(probability {e['outage_probability']:g}; the fixes are withheld, the epochs still scored); "
        f"jamming that ramps up and down ({span(e['jamming_count'])} with probability "
        f"{e['jamming_probability']:g}, {span(e['jamming_duration'], 's')}, ramps of "
        f"{span(e['jamming_ramp'], 's')} to {span(e['jamming_sigma'], 'm')} of added noise per position "
        "row, scaled by sigma_vel / sigma_pos on the velocity rows, and "
        f"{span(tuple(100 * x for x in e['jamming_loss']))} % lost fixes); "
        f"multipath biases ({span(e['multipath_count'])} with probability {e['multipath_probability']:g}, "
        f"{span(e['multipath_duration'], 's')}: {span(e['multipath_bias'], 'm')} (either sign) plus "
        f"{span(e['multipath_sigma'], 'm')} of noise on one position row N, E or D); "
        f"urban canyons ({span(e['canyon_count'])} with probability {e['canyon_probability']:g}, "
        f"{span(e['canyon_duration'], 's')}: nominal noise times {span(e['canyon_noise_scale'])}, "
        f"{span(tuple(100 * x for x in e['canyon_loss']))} % lost fixes, none below 4 satellites "
        f"of {span(e['canyon_satellites'])}); vibration of the IMU ({span(e['burst_count'])} with "
        f"probability {e['burst_probability']:g}, {span(e['burst_duration'], 's')}: white noise of "
        f"{span(e['burst_velocity_sigma'], 'm/s/sqrt(s)')} and "
        f"{span(e['burst_yaw_rate_sigma'], 'rad/sqrt(s)')} "
        "per axis on the recorded samples). Every range is a keyword argument; "
        ":class:`navgym.scenarios.Outage`, ``Jamming(ramp=...)``, ``Multipath``, ``UrbanCanyon`` and "
        "``MotionBurst`` in a ``Scenario(duration=episode_steps * dt)`` pin an episode's events with "
        "``reset(options={'scenario': s})``."
    )
    return textwrap.fill(text, 96, subsequent_indent="    ", break_on_hyphens=False, break_long_words=False)


_CARD = """A real IMU + GNSS recording replayed as a loosely coupled INS/GNSS, an agent steering the filter.

    ## Description
    The packaged recording is GNSS_IMU walk_0827 (rtklibexplorer, BSD 3-clause; a handheld
    receiver and MEMS IMU walked in tight turns, 134 s, 4 Hz RTKLIB solution); ``recording=DIR``
    replays any directory of the format of :mod:`navgym.recordings.loader` (IMU CSV, RTKLIB
    ``.pos``, ``recording.toml`` sidecar). The real IMU drives the Quadrotor's 15-state direct
    filter (Benzerrouk 2014, eq. 3-7 and 11: position, velocity, Euler angles, accelerometer and
    gyro biases; strapdown transition of one GNSS epoch from the preintegrated samples, Forster
    et al. 2017) and the real position/velocity fixes are its measurements (eq. 12, 14; lever arm
    from the sidecar, Groves 2013, §14.2). Truth is the RTK-fixed solution (the sidecar's
    ``truth_q``), interpolated over the other epochs of its span. An episode is a window of the
    recording whose start is drawn by the seed. The observation layout is the Quadrotor v2's, so
    an agent trained in simulation runs here untouched. See :mod:`navgym.recordings.platform`.

    {events}

    ## Action Space
    {action_space}

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter (innovations, NIS, covariances, bias estimates, whether a fix arrived, the
    previous action, the memory features); no truth.

    {observation_table}

    ## Rewards
    {rewards}

    ## Starting State
    A window start drawn uniformly among the epochs whose window lies in the truth span and the
    IMU's, on a delivered fix. The filter starts from the first fix (position, velocity; the
    nominal fix noise and 0.2 m/s), roll and pitch levelled from the first step's specific force
    (3 deg), yaw from the fix's velocity heading when faster than 0.5 m/s (20 deg), else the
    sidecar's ``initial_yaw_deg`` (60 deg), zero biases with the sidecar's turn-on sigmas.

    ## Episode End
    Truncation after ``max_episode_steps`` (default 240 steps of 0.25 s = 60 s) or at the horizon
    ``episode_steps`` (at most the recording's truth span: 87 s on the walk).
    {episode_end}

    ## Arguments
    The replay's own: ``recording=None`` (a directory; None: the packaged walk), ``dt=0.25`` [s]
    (must be the recording's epoch interval), ``sigma_pos=0.1`` [m] in [0.001, 1000] and
    ``sigma_vel=0.05`` [m/s] in [0.0001, 100] (the filter's nominal horizontal fix noise; vertical 1.5
    times). Every argument is checked at ``make`` (a ``TypeError`` or ``ValueError`` naming it; a
    malformed recording with the loader's error naming the file).
    {common_arguments}

    ## Version History
    * v2: initial release (issue 25), Fading and NoiseScale, the memory and bias features. On 64
      held-out windows of the walk (``navgym eval``, baselines tuned on 64 others) the plain EKF's
      position RMSE is 1.83 m, the clairvoyant's (told the injected noise and biases; the
      recording's own noise stays unknown) 1.63 m, the best tuned baselines (constant lambda
      1.02: 1.89 m; constant scales (100, 30): 1.78 m) tie the plain filter, every adaptive rule
      and the simulation-trained QuadrotorNoiseScale-v2 agent (3.51 m) lose to it. Without
      injected events the plain EKF stays 0.091 m RMS from the RTK-fixed epochs
      (``python -m experiments.replay``).
"""
REPLAY_CARD = _CARD.replace("{events}", _events_text(REPLAY_EVENTS))


class ReplayEnv(PlatformEnv, spec=REPLAY_V2):  # noqa: D101 - the card is REPLAY_CARD
    __doc__ = REPLAY_CARD


class ReplayVectorEnv(PlatformVectorEnv, spec=REPLAY_V2):
    """Native batched replay environment (see :class:`ReplayEnv` for the card)."""
