"""Pedestrian environments: the declaration (:data:`PEDESTRIAN`, :data:`PEDESTRIAN_V2`) and its card.

The estimation problem is :class:`navgym.pedestrian.platform.PedestrianPlatform`; everything
shared by all platforms (keyword arguments, core, env shells, card paragraphs) comes from
:mod:`navgym.envs.platform`. The platform is registered at v2 only (``navgym/PedestrianFading-v2``,
``navgym/PedestrianNoiseScale-v2``, ``navgym/PedestrianMixture-v2``): within-episode events unknown
to the filter and the true noise kept for the clairvoyant reference. :data:`PEDESTRIAN` declares
the keyword arguments every platform's v0/v1 declaration has; :data:`PEDESTRIAN_V2`, the one the
registered classes use, adds the event ranges (:data:`V2_EVENT_KWARGS`).
"""

from __future__ import annotations

import textwrap
from dataclasses import replace
from typing import Any

from navgym.envs import arguments
from navgym.envs.cards import span
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.pedestrian.platform import FIX_ROWS, ROWS, PedestrianPlatform

#: Episodes: three minutes of one-second strides.
EPISODE_STEPS = 180
DT = 1.0
#: The within-episode events of the v2 ids (episodes of 180 s; none starts in the first 18 s),
#: several per episode, unknown to the filter (its ``Q`` and ``R`` stay nominal). Ranges are
#: drawn uniformly.
V2_EVENTS: dict[str, Any] = {
    "outage_probability": 0.7,
    "outage_count": (1, 3),
    "outage_duration": (5.0, 20.0),
    "impulsive_probability": 0.8,
    "impulsive_eps": (0.1, 0.4),
    "impulsive_var_ratio": (10.0, 100.0),
    "impulsive_duration": (30.0, 90.0),
    "jamming_probability": 0.6,
    "jamming_count": (1, 2),
    "jamming_duration": (20.0, 60.0),
    "jamming_sigma": (5.0, 30.0),
    "jamming_loss": (0.0, 0.3),
    "jamming_ramp": (5.0, 20.0),
    "burst_probability": 0.8,
    "burst_count": (1, 3),
    "burst_duration": (5.0, 20.0),
    "burst_velocity_sigma": (0.02, 0.1),
    "burst_yaw_rate_sigma": (0.001, 0.005),
    "multipath_probability": 0.9,
    "multipath_count": (2, 4),
    "multipath_duration": (10.0, 40.0),
    "multipath_bias": (10.0, 40.0),
    "multipath_sigma": (0.0, 5.0),
    "multipath_rows": FIX_ROWS,
    "canyon_probability": 0.7,
    "canyon_count": (1, 2),
    "canyon_duration": (20.0, 60.0),
    "canyon_satellites": (2, 8),
    "canyon_noise_scale": (2.0, 5.0),
    "canyon_loss": (0.0, 0.5),
}
#: The v2 ids' event keyword arguments: every key of :data:`V2_EVENTS` (its value the default).
V2_EVENT_KWARGS: tuple[str, ...] = tuple(V2_EVENTS)
#: Scenario defaults per task.
TASK_SCENARIOS_V2: dict[str, dict[str, Any]] = {
    t: dict(V2_EVENTS) for t in ("fading", "noisescale", "mixture")
}
#: Scenario keyword arguments every platform's v0/v1 declaration takes.
SCENARIO_KWARGS = (
    "outage_probability",
    "outage_count",
    "outage_duration",
    "impulsive_probability",
    "impulsive_eps",
    "impulsive_var_ratio",
    "impulsive_duration",
    "jamming_probability",
    "jamming_sigma",
    "jamming_loss",
    "jamming_duration",
    "start_margin",
)
#: Scenario keyword arguments of the v2 ids: the above and the event ranges (no name twice).
SCENARIO_KWARGS_V2: tuple[str, ...] = tuple(dict.fromkeys(SCENARIO_KWARGS + V2_EVENT_KWARGS))
#: Largest fading per second (as the Quadrotor): ``lambda_max = 10^0.5`` per 1 s step.
LAMBDA_MAX_PER_SECOND = 10.0**0.5
#: Pedestrian's own real keyword arguments and their ranges (the smallest noise keeps ``R`` well
#: conditioned).
REAL_KWARGS: dict[str, tuple[float, float]] = {"sigma_pos": (1e-3, 1000.0), "sigma_zupt": (1e-4, 10.0)}
#: Largest IMU rate [Hz] (samples per one-second stride).
MAX_IMU_RATE_HZ = 1000
PLATFORM_KWARGS = ("imu_rate_hz", *REAL_KWARGS)


def build_platform(a: PlatformArgs) -> PedestrianPlatform:
    """A :class:`PedestrianPlatform` from its keyword arguments (popped from ``a.kwargs``), true noise."""
    kw = a.kwargs
    arguments.multipath_rows(
        a.scenarios, FIX_ROWS, "rows of the GPS/GLONASS fix (N, E, D; rows 3-5 are the zero-velocity update)"
    )
    own: dict[str, Any] = {}
    if "imu_rate_hz" in kw:
        own["imu_rate_hz"] = float(
            arguments.integer("imu_rate_hz", kw.pop("imu_rate_hz"), 2, MAX_IMU_RATE_HZ)
        )
    for k, (lo, hi) in REAL_KWARGS.items():
        if k in kw:
            own[k] = arguments.real(k, kw.pop(k), lo, hi)
    return PedestrianPlatform(
        dt=a.dt,
        scenarios=a.scenarios,
        error_scale_m=a.error_scale_m,
        divergence_m=a.divergence_m,
        true_noise=True,
        **own,
    )


#: The Pedestrian platform's declaration with the scenario arguments of a v0/v1 declaration.
PEDESTRIAN = PlatformSpec(
    name="Pedestrian",
    build=build_platform,
    tasks=TASK_SCENARIOS_V2,
    scenario_arguments=SCENARIO_KWARGS,
    episode_steps=EPISODE_STEPS,
    dt=DT,
    dt_argument=False,
    error_scale_m=5.0,
    divergence_m=200.0,
    start_margin_s=20.0,
    lambda_max_per_second=LAMBDA_MAX_PER_SECOND,
    platform_arguments=PLATFORM_KWARGS,
)
#: The declaration of the registered (v2) classes: the event ranges are keyword arguments too.
PEDESTRIAN_V2: PlatformSpec = replace(PEDESTRIAN, scenario_arguments=SCENARIO_KWARGS_V2)


def v2_events_text(e: dict[str, Any]) -> str:
    """The card's paragraph on the v2 episodes, from their scenario defaults (:data:`V2_EVENTS`)."""
    pct = lambda r: span(tuple(100 * x for x in r))  # noqa: E731
    text = (
        "**v2 episodes** (the only ones; scenario defaults ``TASK_SCENARIOS_V2``) change the noise "
        "inside the episode, several times, without telling the filter (its ``Q`` and ``R`` stay "
        f"nominal): outages without fixes ({span(e['outage_count'])} with probability "
        f"{e['outage_probability']:g}, {span(e['outage_duration'], 's')} each: an underpass, a "
        f"building); an impulsive segment (probability {e['impulsive_probability']:g}, "
        f"{span(e['impulsive_duration'], 's')}: each fix an outlier with probability "
        f"{span(e['impulsive_eps'])}, its variance times {span(e['impulsive_var_ratio'])}, Benzerrouk "
        f"2014, eq. 71); interference that ramps up and down ({span(e['jamming_count'])} with "
        f"probability {e['jamming_probability']:g}, {span(e['jamming_duration'], 's')}, ramps of "
        f"{span(e['jamming_ramp'], 's')} to {span(e['jamming_sigma'], 'm')} of extra noise per position "
        f"row and {pct(e['jamming_loss'])} % lost fixes); multipath ({span(e['multipath_count'])} "
        f"segments with probability {e['multipath_probability']:g}, {span(e['multipath_duration'], 's')}: "
        f"a bias of {span(e['multipath_bias'], 'm')} and noise of {span(e['multipath_sigma'], 'm')} on "
        "one fix row, N, E or D); urban canyons "
        f"({span(e['canyon_count'])} with probability {e['canyon_probability']:g}, "
        f"{span(e['canyon_duration'], 's')}: at most {span(e['canyon_satellites'])} GPS/GLONASS "
        f"satellites, below 4 no fix, fix noise times {span(e['canyon_noise_scale'])}, "
        f"{pct(e['canyon_loss'])} % lost fixes); and shocks of the foot ({span(e['burst_count'])} "
        f"with probability {e['burst_probability']:g}, {span(e['burst_duration'], 's')}: running, "
        "stairs, rough pavement; extra white noise on every IMU sample of "
        f"{span(e['burst_velocity_sigma'], 'm/s/sqrt(s)')} per accelerometer axis and "
        f"{span(e['burst_yaw_rate_sigma'], 'rad/sqrt(s)')} per gyro axis, the Quadrotor's vibration "
        "model). The zero-velocity updates are never degraded. Each of these ranges, counts and "
        "probabilities is a scenario keyword argument (``V2_EVENT_KWARGS``, e.g. "
        "``burst_duration=(lo, hi)``; ``multipath_rows`` within the fix rows 0-2). Every step's "
        "true process noise, row variances and biases go to ``StepModels.truth`` (evaluation only, "
        "for the clairvoyant reference, never in the observation)."
    )
    return textwrap.fill(text, 96, subsequent_indent="    ", break_on_hyphens=False, break_long_words=False)


#: The Version History line of the v2 ids (figures from ``python -m experiments.headroom``).
V2_VERSION_HISTORY = (
    "* v2 (Fading, NoiseScale, Mixture): initial release, with the v2 episodes above, the memory "
    "features, ``penalize_remaining_steps=True`` and, for Mixture, one outlier weight per fix row "
    "(``per_row=True``). On 256 held-out episodes (``python -m experiments.headroom``, 256 "
    "tuning episodes) the plain filter's position RMSE is 12.3 m (multipath biases of 10-40 m "
    "dominate), the clairvoyant's 2.6 m; the best tuned baselines are the constant lambda = 1 "
    "(the plain filter; adaptive fading rules lose to it; the clairvoyant is 78.5 % lower) and "
    "constant scales s_q = s_r = 100 (8.7 m; 69.6 % lower) and, for Mixture, the constant "
    "eps = 0.05 (10.5 m; 74.8 % lower; the adaptive rules chi_square, innovation_avg and huber "
    "also beat plain)."
)

_CARD_TEMPLATE = """Pedestrian navigation (Benzerrouk 2014, §2.7c): foot IMU, ZUPTs, GPS/GLONASS fixes.

    ## Description
    A walker in a city (Benzerrouk 2014, §2.7c: the blind pedestrian's navigation system with a
    shoe-mounted MEMS IMU, zero-velocity updates and a GPS/GLONASS receiver) walks straight
    segments at a constant speed of 1.0-1.8 m/s and heading, turns street corners (+-90 deg) or
    bends, and stops at crossings (:mod:`navgym.pedestrian.gait`); one step is one stride of 1 s
    (the epochs at mid-stance, the foot at rest). A consumer MEMS IMU on the foot samples the
    stride's exact kinematics at 100 Hz (turn-on biases, white noise, bias random walks). The
    filter is the Quadrotor's loosely coupled INS/GNSS EKF (:mod:`navgym.quadrotor.models`,
    Benzerrouk 2014, eq. 3-7, 11, 12, 14): the direct 15-state filter ``x = [p, v, (roll, pitch,
    yaw), b_a, b_g]`` in the home's NED frame, the strapdown transition of a stride from the
    preintegrated IMU (Forster et al. 2017), and ``h(x) = [p, v]`` on six rows: the GPS/GLONASS
    fix (N, E, D; 5 m per horizontal axis, 7.5 m vertically), present when a fix arrives, and the
    zero-velocity update at mid-stance (``z = 0``, 0.02 m/s per axis; Foxlin 2005), present at
    every step. The agent controls the filter, not the walker: the fading factor
    (``PedestrianFading``), the scales of ``Q`` and ``R`` (``PedestrianNoiseScale``) or the outlier
    weight of each fix row in a per-row Gaussian-mixture update (``PedestrianMixture``, eq. 71-76).

    {v2_events}

    ## Action Space
    {action_space}
    The Mixture's outlier rows are the fix rows (N, E, D); the ZUPT rows are updated as Gaussian.

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter (innovations of the fix and ZUPT rows, covariances, rows used, the previous
    action, the memory features); no truth. ``time_since_gnss`` counts the fix rows.

    {observation_table}

    ## Rewards
    {rewards}

    ## Starting State
    The walker starts at rest at the origin of the home NED frame (latitude 35-60 deg N, height
    0-500 m, uniform) facing a uniform heading. The prior is the truth plus ``N(0, P0)``: 5 m
    (7.5 m vertically), 0.05 m/s, 1 deg of tilt, 10 deg of yaw (an electronic compass), zero
    biases with the grade's turn-on sigmas.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 180 strides = 3 min) or at the
    simulated horizon ``episode_steps`` (180). ``divergence_m = 200`` m, forty times the error
    scale of 5 m.
    {episode_end}

    ## Arguments
    Pedestrian's own: ``imu_rate_hz=100`` (an integer in [2, 1000]: IMU samples per stride),
    ``sigma_pos=5`` [m] in [0.001, 1000] (the fix's nominal noise per horizontal axis, 1.5 times
    vertically) and ``sigma_zupt=0.02`` [m/s] in [0.0001, 10] (the ZUPT's). The step is fixed at
    ``dt = 1`` s (one stride). Every argument is checked at ``make`` (type, finiteness, range: a
    ``TypeError`` or ``ValueError`` naming it), and so is the memory of a batch's episodes, about
    2.5 kB per step and episode plus 1.1 MB per episode for the IMU samples of 16 strides at a
    time (at 100 Hz; ``episode_bytes``): ``num_envs`` times that must stay within
    ``navgym.envs.build.MAX_EPISODE_BYTES`` (4 GiB).
    {common_arguments}

    ## Version History
    {v2_version}
"""
#: The Pedestrian env card (Gymnasium's sections) before the shared placeholders are filled.
PEDESTRIAN_CARD = _CARD_TEMPLATE.replace("{v2_events}", v2_events_text(V2_EVENTS)).replace(
    "{v2_version}", textwrap.fill(V2_VERSION_HISTORY, 96, subsequent_indent="      ")
)
#: Measurement rows (for the card and tests).
MEASUREMENT_ROWS = ROWS


class PedestrianEnv(PlatformEnv, spec=PEDESTRIAN_V2):  # noqa: D101 - the card is PEDESTRIAN_CARD
    __doc__ = PEDESTRIAN_CARD


class PedestrianVectorEnv(PlatformVectorEnv, spec=PEDESTRIAN_V2):
    """Native batched Pedestrian environment (see :class:`PedestrianEnv` for the card)."""
