"""Quadrotor environments: the platform's declaration (:data:`QUADROTOR`) and its env card.

The estimation problem is :class:`navgym.quadrotor.platform.QuadrotorPlatform`; everything
shared by all platforms (keyword arguments, core, env shells, card paragraphs) comes from
:mod:`navgym.envs.platform`. The v2 ids' declaration (:data:`TASK_SCENARIOS_V2`, the same
platform with within-episode events, the true noise kept and the bias features) is in
:mod:`navgym.quadrotor.env_v2`.
"""

from __future__ import annotations

import textwrap
from typing import Any

from navgym.envs import arguments
from navgym.envs.cards import span
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.quadrotor.flight import QuadrotorParams
from navgym.quadrotor.platform import (
    BIAS_BOUND,
    BIAS_RATE_BOUND,
    IMU_GRADES,
    MIN_FIX_SATELLITES,
    POSITION_ROWS,
    SIGMA_POS_M,
    SIGMA_VEL_MS,
    QuadrotorPlatform,
)

#: Scenario defaults per task (60 s episodes): the degradations that make the task's knob matter.
TASK_SCENARIOS: dict[str, dict[str, Any]] = {
    "fading": {
        "outage_probability": 0.6,
        "outage_duration": (5.0, 30.0),
        "jamming_probability": 0.3,
        "jamming_duration": (5.0, 20.0),
    },
    "mixture": {
        "outage_probability": 0.2,
        "outage_duration": (5.0, 20.0),
        "impulsive_probability": 0.8,
        "impulsive_eps": (0.05, 0.3),
        "impulsive_duration": (10.0, 45.0),
    },
}
#: The within-episode events of the v2 ids (episodes of 60 s; events start after 6 s): several
#: per episode, unknown to the filter (its Q and R stay nominal, and the true IMU is the grade the
#: filter assumes: no ``imu_mismatch``). Ranges are drawn uniformly. A burst is vibration: its
#: ``velocity_sigma`` is read as an accelerometer noise density [m/s/sqrt(s)], its
#: ``yaw_rate_sigma`` as a gyro noise density [rad/sqrt(s)] (the platform's module docstring).
V2_EVENTS: dict[str, Any] = {
    "outage_probability": 0.7,
    "outage_count": (1, 3),
    "outage_duration": (3.0, 10.0),
    "jamming_probability": 0.8,
    "jamming_count": (1, 2),
    "jamming_duration": (10.0, 25.0),
    "jamming_sigma": (5.0, 30.0),
    "jamming_loss": (0.0, 0.3),
    "jamming_ramp": (2.0, 8.0),
    "burst_probability": 0.9,
    "burst_count": (2, 4),
    "burst_duration": (2.0, 15.0),
    "burst_velocity_sigma": (0.05, 0.3),
    "burst_yaw_rate_sigma": (0.001, 0.005),
    "multipath_probability": 0.9,
    "multipath_count": (2, 4),
    "multipath_duration": (8.0, 25.0),
    "multipath_bias": (5.0, 30.0),
    "multipath_sigma": (0.0, 3.0),
    "multipath_rows": POSITION_ROWS,
    "canyon_probability": 0.6,
    "canyon_count": (1, 2),
    "canyon_duration": (5.0, 20.0),
    "canyon_satellites": (3, 8),
    "canyon_noise_scale": (2.0, 5.0),
    "canyon_loss": (0.0, 0.5),
}
#: The v2 ids' event keyword arguments: every key of :data:`V2_EVENTS` (its value the default),
#: accepted by the v2 ids only (:mod:`navgym.quadrotor.env_v2`) to shift the event ranges.
V2_EVENT_KWARGS: tuple[str, ...] = tuple(V2_EVENTS)
#: Scenario defaults per task of the v2 ids (:mod:`navgym.quadrotor.env_v2`).
TASK_SCENARIOS_V2: dict[str, dict[str, Any]] = {
    t: dict(V2_EVENTS) for t in ("fading", "noisescale", "mixture")
}
#: Largest fading per second (as Robot2d, also 10 Hz): ``lambda_max = LAMBDA_MAX_PER_SECOND ** dt``
#: per step, 1.122 at 10 Hz. Ten per 0.1 s step would inflate the weakly observable yaw and biases
#: by 1e10 per second, a runaway covariance within seconds.
LAMBDA_MAX_PER_SECOND = 10.0**0.5
#: Per-task model mismatch: range of the true IMU's error scale (biases, walks, noise densities),
#: log-uniform per episode, while the filter assumes ``imu_grade`` (fading exists to absorb it).
TASK_MISMATCH: dict[str, tuple[float, float] | None] = {"fading": (0.5, 4.0), "mixture": None}
#: Largest filter step ``dt`` [s] (a GNSS fix at least once a second).
MAX_DT_S = 1.0
#: Largest IMU rate ``imu_rate_hz`` [Hz] (so at most 2000 IMU samples a step).
MAX_IMU_RATE_HZ = 2000.0
#: Largest fix noise: ``sigma_pos`` [m] and ``sigma_vel`` [m/s].
MAX_SIGMA_POS_M = 1000.0
MAX_SIGMA_VEL_MS = 100.0
#: Smallest fix noise: ``sigma_pos`` [m] and ``sigma_vel`` [m/s]. Below these the fix covariance
#: ``sigma**2`` leaves the range where the filter's updates stay well conditioned (a denormal
#: ``5e-324`` squares to 0: a singular ``R``); the best RTK fixes are at the centimetre level.
MIN_SIGMA_POS_M = 1e-3
MIN_SIGMA_VEL_MS = 1e-4
#: Largest factor of ``imu_mismatch`` (true IMU errors over the filter's model).
MAX_IMU_MISMATCH = 100.0
#: Quadrotor's own keyword arguments (read by :func:`build_platform`).
PLATFORM_KWARGS = ("imu_rate_hz", "imu_grade", "imu_mismatch", "sigma_pos", "sigma_vel", "flight")
SCENARIO_KWARGS = (
    "outage_probability",
    "outage_count",
    "outage_duration",
    "outage_duration_choices",
    "impulsive_probability",
    "impulsive_eps",
    "impulsive_var_ratio",
    "impulsive_var_ratio_choices",
    "impulsive_duration",
    "jamming_probability",
    "jamming_sigma",
    "jamming_loss",
    "jamming_duration",
    "outlier_probability",
    "outlier_rate",
    "outlier_scale",
    "outlier_duration",
    "start_margin",
)


def build_platform(a: PlatformArgs) -> QuadrotorPlatform:
    """A :class:`QuadrotorPlatform` from its keyword arguments (popped from ``a.kwargs``)."""
    kw = a.kwargs
    grade = arguments.choice("imu_grade", kw.pop("imu_grade", "consumer"), IMU_GRADES)
    mismatch = kw.pop("imu_mismatch") if "imu_mismatch" in kw else TASK_MISMATCH[a.task]
    flight = arguments.instance("flight", kw.pop("flight", QuadrotorParams()), QuadrotorParams)
    rate = arguments.real("imu_rate_hz", kw.pop("imu_rate_hz", 200.0), 0.0, MAX_IMU_RATE_HZ, low_open=True)
    sigma_pos = kw.pop("sigma_pos", SIGMA_POS_M)
    sigma_vel = kw.pop("sigma_vel", SIGMA_VEL_MS)
    if mismatch is not None:
        mismatch = arguments.interval("imu_mismatch", mismatch, 0.0, MAX_IMU_MISMATCH, low_open=True)
    return QuadrotorPlatform(
        dt=a.dt,
        imu_rate_hz=rate,
        sigma_pos=arguments.real("sigma_pos", sigma_pos, MIN_SIGMA_POS_M, MAX_SIGMA_POS_M),
        sigma_vel=arguments.real("sigma_vel", sigma_vel, MIN_SIGMA_VEL_MS, MAX_SIGMA_VEL_MS),
        imu=IMU_GRADES[grade],
        imu_mismatch=mismatch,
        scenarios=a.scenarios,
        flight=flight,
        error_scale_m=a.error_scale_m,
        divergence_m=a.divergence_m,
    )


#: The Quadrotor platform's declaration: tasks, scenario defaults, horizon, reward scales.
QUADROTOR = PlatformSpec(
    name="Quadrotor",
    build=build_platform,
    tasks=TASK_SCENARIOS,
    scenario_arguments=SCENARIO_KWARGS,
    episode_steps=600,
    dt=0.1,
    dt_max=MAX_DT_S,
    error_scale_m=5.0,
    divergence_m=500.0,
    lambda_max_per_second=LAMBDA_MAX_PER_SECOND,
    platform_arguments=PLATFORM_KWARGS,
)


def v2_events_text(events: dict[str, Any]) -> str:
    """The card's paragraph on the v2 episodes, from their scenario defaults (:data:`V2_EVENTS`)."""
    e = events
    text = (
        "**v2 episodes** (``QuadrotorFading-v2``, :mod:`navgym.quadrotor.env_v2`, scenario defaults "
        "``TASK_SCENARIOS_V2``) change the noise inside the episode, several times, without telling "
        "the filter (its ``Q`` and ``R`` stay nominal, and the true IMU is the grade the filter assumes): "
        f"vibration bursts ({span(e['burst_count'])} with probability {e['burst_probability']:g}, "
        f"{span(e['burst_duration'], 's')} each: extra white accelerometer noise of "
        f"{span(e['burst_velocity_sigma'], 'm/s/sqrt(s)')} and gyro noise of "
        f"{span(e['burst_yaw_rate_sigma'], 'rad/sqrt(s)')} per axis on every IMU sample, "
        "measured but not flown, which the strapdown solution integrates); "
        f"multipath/NLOS segments ({span(e['multipath_count'])} with probability "
        f"{e['multipath_probability']:g}, {span(e['multipath_duration'], 's')}: a bias of "
        f"{span(e['multipath_bias'], 'm')} (either sign) plus {span(e['multipath_sigma'], 'm')} "
        "of noise on one position row of the fix, N, E or D); "
        f"jamming that ramps up and down ({span(e['jamming_count'])} with probability "
        f"{e['jamming_probability']:g}, {span(e['jamming_duration'], 's')}, ramps of "
        f"{span(e['jamming_ramp'], 's')} to {span(e['jamming_sigma'], 'm')} of noise per position "
        "row, scaled by sigma_vel / sigma_pos on the velocity rows, and "
        f"{span(tuple(100 * x for x in e['jamming_loss']))} % lost fixes); "
        f"urban canyons ({span(e['canyon_count'])} with probability {e['canyon_probability']:g}, "
        f"{span(e['canyon_duration'], 's')}: {span(e['canyon_satellites'])} satellites, no fix "
        f"below {MIN_FIX_SATELLITES}, fix noise times {span(e['canyon_noise_scale'])}, "
        f"{span(tuple(100 * x for x in e['canyon_loss']))} % lost fixes); "
        f"and {span(e['outage_count'])} GNSS outages of {span(e['outage_duration'], 's')} "
        f"(probability {e['outage_probability']:g}). Each of these ranges, counts and "
        "probabilities is a scenario keyword argument of the v2 ids (``V2_EVENT_KWARGS``, e.g. "
        "``burst_duration=(lo, hi)``; ``multipath_rows`` within the fix rows 0-5; see Arguments), "
        "to shift the distribution. Every step's true process noise, measurement "
        "noise and multipath bias go to ``StepModels.truth`` (``true_noise=True``; evaluation only, "
        "for the clairvoyant reference, never in the observation); "
        ":class:`navgym.scenarios.MotionBurst`, ``Multipath``, ``UrbanCanyon`` and "
        "``Jamming(ramp=...)`` pin them with ``reset(options=...)`` on any Quadrotor id."
    )
    return textwrap.fill(text, 96, subsequent_indent="    ", break_on_hyphens=False, break_long_words=False)


#: The Version History line of the v2 ids (figures: ``experiments.headroom``, see its README).
V2_VERSION_HISTORY = (
    "* v2 (Fading, NoiseScale, Mixture): the v2 episodes above (``TASK_SCENARIOS_V2``, ``true_noise=True``, "
    "no ``imu_mismatch``), the memory features and the bias features (``bias_features=True``), "
    "``penalize_remaining_steps=True`` as v1. On 256 held-out episodes (``python -m experiments.headroom``, "
    "baselines tuned on 256 others) the plain EKF's position RMSE is 7.23 m on average, the clairvoyant "
    "EKF's (told every step's true Q, R and multipath bias: ``clairvoyant=True``) 1.57 m: 78 % below the "
    "best tuned Fading baseline (the constant lambda = 1) and 69 % below the best tuned NoiseScale one "
    "(Sage-Husa, 5.08 m). Most of the gap is the multipath bias; vibration costs the GNSS-aided filter "
    "little (the 10 Hz velocity fixes hold it) except across outages and canyons."
)

_CARD_TEMPLATE = """Benzerrouk 2014's quadrotor "return to home" INS/GNSS, with an agent steering the filter.

    ## Description
    A quadrotor flies closed triangles with legs of 100-500 m, climbing, hovering and turning at
    the vertices (Benzerrouk 2014, §2.7a, "return to home" of an AR.Drone 2.0), through
    GNSS outages, jamming and impulsive noise. A 15-state *direct* filter (eq. 11:
    position, velocity, Euler angles, accelerometer and gyro biases) integrates a consumer-MEMS
    IMU at 200 Hz through the strapdown equations (eq. 3-7; Earth rate and Coriolis kept, in the
    home's Earth-fixed NED frame) and fuses a GNSS position/velocity fix at 10 Hz (eq. 12, 14)
    whenever one is delivered. One step is one GNSS epoch (0.1 s, 20 IMU samples). The agent
    controls the filter, not the vehicle: the fading factor of an EKF (``QuadrotorFading``,
    eq. 63-70) or the outlier weight of a Gaussian-sum CKF (``QuadrotorMixture``,
    eq. 71-76). See :mod:`navgym.quadrotor.env` for the models.

    {v2_events}

    ## Action Space
    {action_space}
    ``lambda_max`` defaults to ``10 ** 0.05 = 1.122`` per step, i.e. up to 3.16-fold per second
    (``LAMBDA_MAX_PER_SECOND``, as Robot2d): ten per step would inflate the weakly observable yaw
    and biases by 1e10 per second. The Mixture's outlier rows are the whole fix (all six rows).

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter (innovations, NIS, covariances, whether a fix arrived, the previous action);
    no truth. The v2 ids add the memory features (:mod:`navgym.envs.memory`) and the filter's
    own bias estimates and their rates (``bias_features``: ``accel_bias``, ``gyro_bias`` in units
    of the grade's turn-on sigma, within +-{bias_bound:g}; ``accel_bias_rate``, ``gyro_bias_rate``
    per second, within +-{bias_rate_bound:g}; estimator side).

    {observation_table}

    ## Rewards
    {rewards}
    The scale is about twice the nominal fix noise: a GNSS-aided filter stays well inside it, a
    30 s outage on consumer MEMS does not.

    ## Starting State
    A time drawn uniformly within the flight (take-off to landing minus the episode length);
    the filter starts from ``N(truth, P0)`` for position (fix noise: 2, 2, 3 m), velocity
    (0.2 m/s), roll/pitch (1 deg), yaw (5 deg), and zero biases with the IMU grade's turn-on
    sigmas (the true turn-on biases are drawn from them). ``QuadrotorFading``'s true IMU errors
    are the grade's times a factor drawn log-uniformly in ``imu_mismatch = (0.5, 4)`` per episode
    (the filter keeps the grade's model); ``QuadrotorMixture``'s match it. Home within 43-61 N,
    5 W-40 E.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 600 steps of 0.1 s = 60 s) or at the
    simulated horizon ``episode_steps`` (600; it sets the flight window and the IMU too).
    {episode_end}
    The covariance also runs away when any state variance exceeds ``RUNAWAY_VARIANCE = 1e12`` or
    is non-finite: it is reported as an infinite ``info["cov_ne"]``, which ends the episode by the
    sigma rule.

    ## Arguments
    Quadrotor's own: ``dt=0.1`` [s] in (0, 1], ``imu_rate_hz=200.0`` in (0, 2000] (``dt *
    imu_rate_hz`` samples per step must be an integer), ``imu_grade="consumer"|"tactical"``,
    ``imu_mismatch=(0.5, 4.0)`` (Fading) or ``None`` (Mixture; a range within (0, 100]),
    ``sigma_pos=2.0`` [m] in [0.001, 1000] and ``sigma_vel=0.1`` [m/s] in [0.0001, 100] (horizontal fix
    noise; vertical 1.5 times), ``flight`` (a :class:`navgym.quadrotor.flight.QuadrotorParams`).
    The IMU samples count towards the episode memory bound (``MAX_EPISODE_BYTES``): 48 bytes
    each, ``dt * imu_rate_hz`` a step. Every argument is checked at ``make`` (type, finiteness,
    range: a ``TypeError`` or ``ValueError`` naming it), and so is the memory of a batch's
    episodes, about 1,700 + 48 ``dt * imu_rate_hz`` bytes per step and episode here
    (``episode_bytes``): ``num_envs`` times that must stay within
    ``navgym.envs.build.MAX_EPISODE_BYTES`` (4 GiB).
    {common_arguments}

    ## Version History
    {v2_version}
    {version_history}
"""
#: The Quadrotor env card (Gymnasium's sections) with the v2 paragraph, before the shared
#: placeholders are filled (:func:`navgym.envs.cards.fill_card`); the v0/v1 classes and the v2
#: classes (:mod:`navgym.quadrotor.env_v2`) share it.
QUADROTOR_CARD = (
    _CARD_TEMPLATE.replace("{v2_events}", v2_events_text(V2_EVENTS))
    .replace("{v2_version}", textwrap.fill(V2_VERSION_HISTORY, 96, subsequent_indent="      "))
    .replace("{bias_bound:g}", f"{BIAS_BOUND:g}")
    .replace("{bias_rate_bound:g}", f"{BIAS_RATE_BOUND:g}")
)


class QuadrotorEnv(PlatformEnv, spec=QUADROTOR):  # noqa: D101 - the card is QUADROTOR_CARD
    __doc__ = QUADROTOR_CARD


class QuadrotorVectorEnv(PlatformVectorEnv, spec=QUADROTOR):
    """Native batched Quadrotor environment (see :class:`QuadrotorEnv` for the card)."""
