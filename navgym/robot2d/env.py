"""Robot2d environments: the platform's declaration (:data:`ROBOT2D`) and its env card.

The estimation problem is :class:`navgym.robot2d.platform.Robot2dPlatform`; everything shared
by all platforms (keyword arguments, core, env shells, card paragraphs) comes from
:mod:`navgym.envs.platform`. The v2 ids' declaration (:data:`TASK_SCENARIOS_V2`, the same
platform with within-episode events and the true noise kept) is in :mod:`navgym.robot2d.env_v2`.
"""

from __future__ import annotations

import textwrap
from typing import Any

from navgym.envs import arguments
from navgym.envs.cards import span
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.robot2d.platform import GNSS_ROWS, Robot2dPlatform
from navgym.robot2d.robot import RobotParams
from navgym.robot2d.sensors import RobotSensorNoise

#: Scenario defaults per task (episodes last 60 s): the degradations that make the knob matter.
TASK_SCENARIOS: dict[str, dict[str, Any]] = {
    "fading": {
        "outage_probability": 0.6,
        "outage_duration": (5.0, 25.0),
        "jamming_probability": 0.3,
        "jamming_duration": (5.0, 20.0),
    },
    "mixture": {
        "outage_probability": 0.2,
        "outage_duration": (5.0, 20.0),
        "impulsive_probability": 0.8,
        "impulsive_eps": (0.05, 0.3),
        "impulsive_duration": (10.0, 40.0),
    },
    "resample": {"outage_probability": 0.5, "outage_duration": (5.0, 25.0)},
}
#: The within-episode events of the v2 ids (episodes of 60 s; events start after 6 s): several
#: per episode, unknown to the filter (its Q and R stay nominal). Ranges are drawn uniformly.
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
    "burst_velocity_sigma": (0.5, 3.0),
    "burst_yaw_rate_sigma": (0.05, 0.3),
    "multipath_probability": 0.9,
    "multipath_count": (2, 4),
    "multipath_duration": (8.0, 25.0),
    "multipath_bias": (5.0, 30.0),
    "multipath_sigma": (0.0, 3.0),
    "multipath_rows": GNSS_ROWS,
    "canyon_probability": 0.6,
    "canyon_count": (1, 2),
    "canyon_duration": (5.0, 20.0),
    "canyon_satellites": (3, 8),
    "canyon_noise_scale": (2.0, 5.0),
    "canyon_loss": (0.0, 0.5),
}
#: The v2 ids' event keyword arguments: every key of :data:`V2_EVENTS` (its value the default),
#: accepted by the v2 ids only (:mod:`navgym.robot2d.env_v2`) to shift the event ranges.
V2_EVENT_KWARGS: tuple[str, ...] = tuple(V2_EVENTS)
#: Scenario defaults per task of the v2 ids (:mod:`navgym.robot2d.env_v2`).
TASK_SCENARIOS_V2: dict[str, dict[str, Any]] = {
    t: dict(V2_EVENTS) for t in ("fading", "noisescale", "mixture", "resample")
}
SCENARIO_KWARGS = (
    "outage_probability",
    "outage_count",
    "outage_duration",
    "partial_probability",
    "partial_satellites",
    "partial_duration",
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
#: Sensor keyword arguments, the :class:`RobotSensorNoise` field they set, their largest and
#: their smallest value (each lies in ``[smallest, largest]``: below the smallest the noise's
#: square leaves the range where the filter's ``R`` and updates stay well conditioned).
SENSOR_KWARGS = {
    "sigma_gps": "gps",
    "sigma_glonass": "glonass",
    "sigma_compass_deg": "compass_deg",
    "sigma_encoder": "encoder",
    "sigma_steering_deg": "steering_deg",
}
SENSOR_MAX = {
    "sigma_gps": 1000.0,  # [m]
    "sigma_glonass": 1000.0,  # [m]
    "sigma_compass_deg": 180.0,  # [deg]
    "sigma_encoder": 10.0,  # [m/s]
    "sigma_steering_deg": 90.0,  # [deg]
}
SENSOR_MIN = {
    "sigma_gps": 1e-3,  # [m]
    "sigma_glonass": 1e-3,  # [m]
    "sigma_compass_deg": 1e-3,  # [deg]
    "sigma_encoder": 1e-4,  # [m/s]
    "sigma_steering_deg": 1e-3,  # [deg]
}
#: Default largest fading factor, per second of filtering: ``lambda_max = 3.16 ** dt`` = 1.122 per
#: 0.1 s step. Ten per step at 10 Hz (GpsInsFading's 10 at 1 Hz) would inflate P by 1e10 per
#: second: a sustained a = 1 makes P ~ 1e17 m^2 within 2 s of outage, where the duplicated
#: GPS/GLONASS rows make S numerically singular. At 3.16 per second, P stays below ~1e12 m^2
#: through the longest default outage (25 s).
LAMBDA_MAX_PER_SECOND = 10.0**0.5
#: Unmodelled-motion keyword arguments of the filter (see :class:`Robot2dPlatform`) and their
#: largest value (each lies in ``[0, largest]``).
MOTION_KWARGS = ("encoder_scale_sigma", "slip_sigma", "yaw_sigma")
MOTION_MAX = {"encoder_scale_sigma": 1.0, "slip_sigma": 100.0, "yaw_sigma": 10.0}
#: Robot2d's own keyword arguments (read by :func:`build_platform`).
PLATFORM_KWARGS = (*SENSOR_KWARGS, *MOTION_KWARGS)


def build_platform(a: PlatformArgs) -> Robot2dPlatform:
    """A :class:`Robot2dPlatform` from its keyword arguments (popped from ``a.kwargs``)."""
    kw = a.kwargs
    sensors = RobotSensorNoise(
        **{
            f: arguments.real(k, kw.pop(k), SENSOR_MIN[k], SENSOR_MAX[k])
            for k, f in SENSOR_KWARGS.items()
            if k in kw
        }
    )
    motion = {k: arguments.real(k, kw.pop(k), 0.0, MOTION_MAX[k]) for k in MOTION_KWARGS if k in kw}
    return Robot2dPlatform(
        dt=a.dt,
        sensors=sensors,
        robot=RobotParams(duration=max(a.steps * a.dt, 1.0)),
        scenarios=a.scenarios,
        error_scale_m=a.error_scale_m,
        divergence_m=a.divergence_m,
        **motion,
    )


#: The Robot2d platform's declaration: tasks, scenario defaults, horizon, reward scales.
ROBOT2D = PlatformSpec(
    name="Robot2d",
    build=build_platform,
    tasks=TASK_SCENARIOS,
    scenario_arguments=SCENARIO_KWARGS,
    episode_steps=600,
    dt=0.1,
    dt_argument=False,
    error_scale_m=2.0,
    divergence_m=200.0,
    lambda_max_per_second=LAMBDA_MAX_PER_SECOND,
    platform_arguments=PLATFORM_KWARGS,
)


def v2_events_text(events: dict[str, Any]) -> str:
    """The card's paragraph on the v2 episodes, from their scenario defaults (:data:`V2_EVENTS`)."""
    e = events
    text = (
        "**v2 episodes** (``Robot2dFading-v2``, :mod:`navgym.robot2d.env_v2`, scenario defaults "
        "``TASK_SCENARIOS_V2``) change the noise inside the episode, several times, without telling "
        "the filter (its ``Q`` and ``R`` stay nominal): "
        f"wheel-slip bursts ({span(e['burst_count'])} with probability {e['burst_probability']:g}, "
        f"{span(e['burst_duration'], 's')} each: a white horizontal velocity error of "
        f"{span(e['burst_velocity_sigma'], 'm/s')} per axis and a yaw-rate error of "
        f"{span(e['burst_yaw_rate_sigma'], 'rad/s')}, which turns the rest of the path; the encoder "
        "and steering do not see it); "
        f"multipath/NLOS segments ({span(e['multipath_count'])} with probability "
        f"{e['multipath_probability']:g}, {span(e['multipath_duration'], 's')}: a bias of "
        f"{span(e['multipath_bias'], 'm')} (either sign) plus {span(e['multipath_sigma'], 'm')} "
        "of noise on one GNSS row, GPS N/E or GLONASS N/E); "
        f"jamming that ramps up and down ({span(e['jamming_count'])} with probability "
        f"{e['jamming_probability']:g}, {span(e['jamming_duration'], 's')}, ramps of "
        f"{span(e['jamming_ramp'], 's')} to {span(e['jamming_sigma'], 'm')} of noise per axis and "
        f"{span(tuple(100 * x for x in e['jamming_loss']))} % lost fixes); "
        f"urban canyons ({span(e['canyon_count'])} with probability {e['canyon_probability']:g}, "
        f"{span(e['canyon_duration'], 's')}: {span(e['canyon_satellites'])} satellites, no fix "
        f"below 4, fix noise times {span(e['canyon_noise_scale'])}, "
        f"{span(tuple(100 * x for x in e['canyon_loss']))} % lost fixes); "
        f"and {span(e['outage_count'])} GNSS outages of {span(e['outage_duration'], 's')} "
        f"(probability {e['outage_probability']:g}). Each of these ranges, counts and "
        "probabilities is a scenario keyword argument of the v2 ids (``V2_EVENT_KWARGS``, e.g. "
        "``burst_duration=(lo, hi)``; ``multipath_rows`` within the GNSS rows 0-3; see Arguments), "
        "to shift the distribution. Every step's true process noise, measurement "
        "noise and multipath bias go to ``StepModels.truth`` (``true_noise=True``; evaluation only, "
        "for the clairvoyant reference, never in the observation); "
        ":class:`navgym.scenarios.MotionBurst`, ``Multipath``, ``UrbanCanyon`` and "
        "``Jamming(ramp=...)`` pin them with ``reset(options=...)`` on any Robot2d id."
    )
    return textwrap.fill(text, 96, subsequent_indent="    ", break_on_hyphens=False, break_long_words=False)


#: The Version History line of the v2 ids.
V2_VERSION_HISTORY = (
    "* v2 (Fading, NoiseScale, Mixture, Resample): the v2 episodes above (``TASK_SCENARIOS_V2``, "
    "``true_noise=True``) and the memory features, ``penalize_remaining_steps=True`` as v1 (Resample "
    "also keeps v1's roughening and log10 ESS/N). On 256 episodes (``make_vec``, ``reset(seed=0)``, "
    "a = -1 throughout) the plain EKF's "
    "position RMSE is 5.81 m on average (median 5.26 m), the clairvoyant EKF's (told every step's "
    "true Q, R and multipath bias: ``clairvoyant=True``) 1.10 m (median 1.01 m), 81 % lower. With "
    "one kind of event alone (128 episodes) it is 91 % lower under multipath, 33 % under bursts or "
    "jamming, 14 % under canyons and equal under outages."
)

_CARD_TEMPLATE = """Benzerrouk 2014's car-like robot (eq. 77), with an agent steering its navigation filter.

    ## Description
    A car-like robot (Benzerrouk 2014, §2.7b-c; kinematics eq. 77, geometry of the
    Victoria Park car of Guivant & Nebot 2001) drives piecewise-constant speed (0.5-3 m/s) and
    steering (+-25 deg) commands. A three-state filter ``x = [x_N, y_E, phi]`` (north/east
    position of the tracked point L [m], heading from north [rad]) predicts with the exact
    discrete eq. 77 driven by the rear-right wheel encoder (Benzerrouk 2014's "back left", named
    in Guivant & Nebot's mirrored frame, :mod:`navgym.robot2d.robot`) and the steering sensor
    (held over the step; process noise from their noise plus unmodelled motion), and updates
    with GPS fixes at 10 Hz, GLONASS fixes at 5 Hz and an electronic compass at 5 Hz (the rates
    of Benzerrouk 2014). Sensor noise (assumed; Benzerrouk 2014 gives none): GPS 3 m and
    GLONASS 5 m per axis, compass 2 deg, encoder 0.05 m/s, steering 0.5 deg. The truth carries
    what the filter does not model: an encoder scale error ``N(0, 2 %)`` per episode (wheel
    radius) and commands changing inside a step, the model error a fading factor is for. Episodes
    bring GNSS outages, jamming (extra fix noise ``jam_sigma`` per axis and lost fixes), impulsive
    noise on the fixes (Benzerrouk 2014, eq. 71: with probability ``eps`` a fix's variance is
    multiplied by ``var_ratio``) and partial outages (fewer than 4 satellites: no fix), drawn from
    a seeded scenario distribution; the compass is not GNSS and never degrades. The agent controls
    the filter, not the robot: the fading factor (``Robot2dFading``), the outlier weight of a
    Gaussian-sum filter (``Robot2dMixture``) or a particle filter's resampling (``Robot2dResample``).

    {v2_events}

    ## Action Space
    {action_space}
    ``lambda_max`` defaults to ``10 ** 0.05 = 1.122`` per 0.1 s step (up to 3.16-fold per second,
    ``LAMBDA_MAX_PER_SECOND``; ten per step at 10 Hz would make P numerically singular within
    seconds of an outage). The Mixture's outlier rows are the four GNSS rows (GPS and GLONASS
    N/E); the compass row keeps ``N(0, R)``.

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter and the sensors (innovations, covariances, rows used, fix age, the previous
    action); no truth. ``time_since_gnss`` counts only the GNSS rows (a compass reading does not
    reset it), so it equals ``time_since_fix``.

    {observation_table}

    ## Rewards
    {rewards}

    ## Starting State
    The robot starts at the origin of its local north/east frame with a uniform heading. The
    filter starts from the first GPS fix and compass reading, ``P0 = diag(3 m, 3 m, 2 deg)^2``.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 600 steps of 0.1 s = 60 s) or at the
    simulated horizon ``episode_steps`` (600). ``divergence_m = 200`` m is a hundred times the
    error scale and far beyond any outage drift of a 60 s episode.
    {episode_end}

    ## Arguments
    Robot2d's own: ``sigma_gps=3.0``, ``sigma_glonass=5.0`` [m per axis] in [0.001, 1000],
    ``sigma_compass_deg=2.0`` in [0.001, 180], ``sigma_encoder=0.05`` [m/s] in [0.0001, 10],
    ``sigma_steering_deg=0.5`` in [0.001, 90] set both the simulated sensors and the filter's ``R``
    and control noise; ``encoder_scale_sigma=0.02`` in [0, 1] is the spread of the true encoder
    scale error (unmodelled); ``slip_sigma=0.3`` [m/s] in [0, 100] and ``yaw_sigma=0.02`` [rad/s]
    in [0, 10] are the filter's unmodelled-motion noise (scale error, commands changing inside a
    step). The step is fixed at ``dt = 0.1`` s (the GPS period). Every argument is checked at
    ``make`` (type, finiteness, range: a ``TypeError`` or ``ValueError`` naming it), and so is
    the memory of a batch's episodes, about 510 bytes per step and episode here
    (``episode_bytes``): ``num_envs`` times that must stay within
    ``navgym.envs.build.MAX_EPISODE_BYTES`` (4 GiB).
    {common_arguments}

    ## Version History
    {v2_version}
    {version_history}
"""
#: The Robot2d env card (Gymnasium's sections) with the v2 paragraph, before the shared
#: placeholders are filled (:func:`navgym.envs.cards.fill_card`); the v0/v1 classes and the v2
#: classes (:mod:`navgym.robot2d.env_v2`) share it.
ROBOT2D_CARD = _CARD_TEMPLATE.replace("{v2_events}", v2_events_text(V2_EVENTS)).replace(
    "{v2_version}", textwrap.fill(V2_VERSION_HISTORY, 96, subsequent_indent="      ")
)


class Robot2dEnv(PlatformEnv, spec=ROBOT2D):  # noqa: D101 - the card is ROBOT2D_CARD
    __doc__ = ROBOT2D_CARD


class Robot2dVectorEnv(PlatformVectorEnv, spec=ROBOT2D):
    """Native batched Robot2d environment (see :class:`Robot2dEnv` for the card)."""
