"""GpsIns environments: the platform's declaration (:data:`GPS_INS`) and its env card.

The estimation problem is :class:`navgym.gps_ins.platform.GpsInsPlatform`; everything shared
by all platforms (keyword arguments, core, env shells, card paragraphs) comes from
:mod:`navgym.envs.platform`. The v2 ids' declaration (:data:`TASK_SCENARIOS_V2`, the same
platform with within-episode events, the true noise kept and the bias features) is in
:mod:`navgym.gps_ins.env_v2`.
"""

from __future__ import annotations

import textwrap
from typing import Any

from navgym.envs import arguments
from navgym.envs.cards import span
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.gps_ins.platform import BIAS_BOUNDS, MULTIPATH_SLOTS, SIGMA_PR_M, GpsInsPlatform
from navgym.ins.error_model import InsErrorParams

#: Scenario defaults per task: the degradations that make the task's knob matter.
TASK_SCENARIOS: dict[str, dict[str, Any]] = {
    "fading": {"outage_probability": 0.6, "outage_duration": (20.0, 120.0), "jamming_probability": 0.3},
    "mixture": {"outage_probability": 0.2, "impulsive_probability": 0.8, "impulsive_eps": (0.05, 0.3)},
    "resample": {"outage_probability": 0.5, "outage_duration": (20.0, 120.0), "partial_probability": 0.3},
}
#: Elevation ranks a v2 multipath segment is drawn on (the lowest of the 12 rows: low elevation;
#: a rank beyond the satellites in view means the lowest one in view).
MULTIPATH_RANKS = (6, 7, 8, 9, 10, 11)
#: The within-episode events of the v2 ids (episodes of 300 s; events start after 30 s): several
#: per episode, unknown to the filter (its Q and R stay nominal). Ranges are drawn uniformly.
V2_EVENTS: dict[str, Any] = {
    "outage_probability": 0.6,
    "outage_count": (1, 3),
    "outage_duration": (5.0, 30.0),
    "jamming_probability": 0.7,
    "jamming_count": (1, 2),
    "jamming_duration": (20.0, 60.0),
    "jamming_sigma": (10.0, 40.0),
    "jamming_loss": (0.0, 0.3),
    "jamming_ramp": (5.0, 20.0),
    "burst_probability": 0.8,
    "burst_count": (2, 4),
    "burst_duration": (5.0, 30.0),
    "burst_velocity_sigma": (0.02, 0.2),
    "multipath_probability": 0.9,
    "multipath_count": (2, 5),
    "multipath_duration": (20.0, 120.0),
    "multipath_bias": (5.0, 30.0),
    "multipath_sigma": (0.0, 3.0),
    "multipath_rows": MULTIPATH_RANKS,
    "canyon_probability": 0.6,
    "canyon_count": (1, 2),
    "canyon_duration": (20.0, 60.0),
    "canyon_satellites": (4, 7),
    "canyon_noise_scale": (2.0, 4.0),
    "canyon_loss": (0.0, 0.4),
}
#: The v2 ids' event keyword arguments: every key of :data:`V2_EVENTS` (its value the default),
#: accepted by the v2 ids only (:mod:`navgym.gps_ins.env_v2`) to shift the event ranges.
V2_EVENT_KWARGS: tuple[str, ...] = tuple(V2_EVENTS)
#: Scenario defaults per task of the v2 ids (:mod:`navgym.gps_ins.env_v2`).
TASK_SCENARIOS_V2: dict[str, dict[str, Any]] = {
    t: dict(V2_EVENTS) for t in ("fading", "noisescale", "mixture", "resample")
}
SCENARIO_KWARGS = (
    "outage_probability",
    "outage_duration",
    "partial_probability",
    "partial_satellites",
    "impulsive_probability",
    "impulsive_eps",
    "impulsive_var_ratio",
    "jamming_probability",
    "jamming_sigma",
    "outlier_probability",
    "mask_deg",
)
#: Per-task model mismatch: range of the true IMU bias limit [ug], log-uniform per episode, while
#: the filter assumes ``imu_grade`` (the fading factor exists to absorb such mismatch).
TASK_MISMATCH: dict[str, tuple[float, float] | None] = {
    "fading": (10.0, 3000.0),
    "mixture": None,
    "resample": None,
}
#: IMU grades of the two-axis error model: bias limit [ug] (Carvalho et al. 1997: 10 ug, navigation grade).
IMU_GRADES = {"navigation": 10.0, "tactical": 100.0, "consumer": 2000.0}


#: Carvalho et al. 1997's critical scenario as published: 3600 steps of 1 s.
CRITICAL_STEPS = 3600
#: Largest filter step ``dt`` [s] (GPS fixes at least once a minute).
MAX_DT_S = 60.0
#: Largest pseudo-range noise ``sigma_pr`` [m].
MAX_SIGMA_PR_M = 1000.0
#: Smallest ``sigma_pr`` [m] (below it ``R = sigma_pr**2`` leaves the well-conditioned range; a
#: denormal squares to 0).
MIN_SIGMA_PR_M = 1e-3
#: Largest true IMU bias limit of ``true_bias_limit_ug`` [ug] (0.1 g).
MAX_BIAS_LIMIT_UG = 1e5
#: GpsIns' own keyword arguments (read by :func:`build_platform` and :func:`prepare_arguments`).
PLATFORM_KWARGS = ("vehicle", "imu_grade", "m_max", "sigma_pr", "critical", "true_bias_limit_ug")


def prepare_arguments(
    task: str, kwargs: dict[str, Any], scenario_kwargs: tuple[str, ...] = SCENARIO_KWARGS
) -> None:
    """``critical=True`` runs the fixed published scenario; ``mask_deg`` is a fixed elevation mask.

    ``scenario_kwargs``: the scenario keyword arguments ``critical=True`` refuses (the ids' own:
    the v2 ids add :data:`V2_EVENT_KWARGS`).
    """
    if arguments.flag("critical", kwargs.get("critical", False)):
        given = sorted(k for k in scenario_kwargs if k in kwargs)
        if given:
            raise ValueError(
                "critical=True runs Carvalho et al. 1997's fixed scenario (50 deg mask, 3 -> 2 satellites); "
                f"the scenario keyword arguments {given} would be ignored: leave them out"
            )
        steps = arguments.integer("episode_steps", kwargs.get("episode_steps", CRITICAL_STEPS), 1)
        dt = arguments.real("dt", kwargs.get("dt", 1.0), 0.0, low_open=True)
        if steps != CRITICAL_STEPS or dt != 1.0:
            raise ValueError(
                "critical=True runs Carvalho et al. 1997's scenario as published (3600 s at dt = 1 s, the "
                f"3 -> 2 satellite drop at 1983 s); got episode_steps={steps}, dt={dt} (use "
                "max_episode_steps to stop earlier)"
            )
        kwargs["episode_steps"] = CRITICAL_STEPS
    if "mask_deg" in kwargs:
        m = arguments.real("mask_deg", kwargs["mask_deg"], 0.0, 90.0, high_open=True)
        kwargs["mask_deg"] = (m, m)


def build_platform(a: PlatformArgs) -> GpsInsPlatform:
    """A :class:`GpsInsPlatform` from its keyword arguments (popped from ``a.kwargs``)."""
    kw = a.kwargs
    grade = arguments.choice("imu_grade", kw.pop("imu_grade", "navigation"), IMU_GRADES)
    limit = IMU_GRADES[grade] * 1e-6 * 9.80665
    ins = InsErrorParams(
        sigma_x=limit / 120.0, sigma_y=limit / 120.0, bias_limit=limit, sigma_bias0=limit / 2.0
    )
    mismatch = kw.pop("true_bias_limit_ug", TASK_MISMATCH.get(a.task))
    if mismatch is not None:
        mismatch = arguments.interval("true_bias_limit_ug", mismatch, 0.0, MAX_BIAS_LIMIT_UG, low_open=True)
    return GpsInsPlatform(
        vehicle=arguments.choice("vehicle", kw.pop("vehicle", "land"), ("land", "ship")),
        dt=a.dt,
        m_max=arguments.integer("m_max", kw.pop("m_max", 12), 4, 16),
        sigma_pr=arguments.real("sigma_pr", kw.pop("sigma_pr", SIGMA_PR_M), MIN_SIGMA_PR_M, MAX_SIGMA_PR_M),
        ins=ins,
        scenarios=a.scenarios,
        critical=arguments.flag("critical", kw.pop("critical", False)),
        true_bias_limit_ug=mismatch,
        error_scale_m=a.error_scale_m,
        divergence_m=a.divergence_m,
    )


#: The GpsIns platform's declaration: tasks, scenario defaults, horizon, reward scales.
GPS_INS = PlatformSpec(
    name="GpsIns",
    build=build_platform,
    tasks=TASK_SCENARIOS,
    scenario_arguments=SCENARIO_KWARGS,
    episode_steps=300,
    dt=1.0,
    dt_max=MAX_DT_S,
    error_scale_m=10.0,
    divergence_m=2000.0,
    start_margin_s=30.0,
    prepare=prepare_arguments,
    platform_arguments=PLATFORM_KWARGS,
)


def v2_events_text(events: dict[str, Any]) -> str:
    """The card's paragraph on the v2 episodes, from their scenario defaults (:data:`V2_EVENTS`)."""
    e = events
    b = BIAS_BOUNDS
    text = (
        "**v2 episodes** (``GpsInsFading-v2``, :mod:`navgym.gps_ins.env_v2`, scenario defaults "
        "``TASK_SCENARIOS_V2``) change the noise inside the episode, several times, without telling "
        "the filter (its ``Q`` and ``R`` stay nominal, and the true IMU is the assumed one: "
        "``true_bias_limit_ug=None``): "
        f"unmodelled manoeuvres ({span(e['burst_count'])} with probability {e['burst_probability']:g}, "
        f"{span(e['burst_duration'], 's')} each: a white horizontal acceleration error of "
        f"{span(e['burst_velocity_sigma'], 'm/s^2')} per axis in the INS, "
        "``MotionBurst.velocity_sigma`` read in m/s^2); "
        f"multipath/NLOS on single satellites ({span(e['multipath_count'])} with probability "
        f"{e['multipath_probability']:g}, {span(e['multipath_duration'], 's')}: a bias of "
        f"{span(e['multipath_bias'], 'm')} (either sign) plus {span(e['multipath_sigma'], 'm')} "
        "of noise on the pseudo-range of the satellite ranked "
        f"{span((min(e['multipath_rows']), max(e['multipath_rows'])))} by elevation (of 12; the "
        "lowest in view where fewer) at the segment's start, which it follows while tracked); "
        f"jamming that ramps up and down ({span(e['jamming_count'])} with probability "
        f"{e['jamming_probability']:g}, {span(e['jamming_duration'], 's')}, ramps of "
        f"{span(e['jamming_ramp'], 's')} to {span(e['jamming_sigma'], 'm')} of noise per "
        f"pseudo-range and {span(tuple(100 * x for x in e['jamming_loss']))} % lost); "
        f"urban canyons ({span(e['canyon_count'])} with probability {e['canyon_probability']:g}, "
        f"{span(e['canyon_duration'], 's')}: the {span(e['canyon_satellites'])} highest satellites "
        f"only, their noise times {span(e['canyon_noise_scale'])}, "
        f"{span(tuple(100 * x for x in e['canyon_loss']))} % lost); "
        f"and {span(e['outage_count'])} GNSS outages of {span(e['outage_duration'], 's')} "
        f"(probability {e['outage_probability']:g}). Each of these ranges, counts and "
        "probabilities is a scenario keyword argument of the v2 ids (``V2_EVENT_KWARGS``, e.g. "
        f"``burst_duration=(lo, hi)``; ``multipath_count`` at most {MULTIPATH_SLOTS}; see Arguments), "
        "to shift the distribution. Every step's true process noise, pseudo-range "
        "variances (troposphere-model error included) and biases go to ``StepModels.truth`` in the "
        "filter's row order (``true_noise=True``; evaluation only, for the clairvoyant reference, "
        "never in the observation); :class:`navgym.scenarios.MotionBurst`, ``Multipath`` (``row`` "
        "an elevation rank), ``UrbanCanyon`` and ``Jamming(ramp=...)`` pin them with "
        "``reset(options=...)`` on any GpsIns id. The v2 observation adds the filter's own bias "
        "estimates and their rates (``bias_features=True``): ``accel_bias`` (x, y accelerometer "
        f"biases [mg] within +-{b['accel_bias']:g}), ``accel_bias_rate`` (their change over the step "
        f"/ dt [mg/s] within +-{b['accel_bias_rate']:g}), ``clock_drift`` [m/s] within "
        f"+-{b['clock_drift']:g} and ``clock_drift_rate`` [m/s^2] within +-{b['clock_drift_rate']:g} "
        "(clipped beyond)."
    )
    return textwrap.fill(text, 96, subsequent_indent="    ", break_on_hyphens=False, break_long_words=False)


#: The Version History line of the v2 ids.
V2_VERSION_HISTORY = (
    "* v2 (Fading, NoiseScale, Mixture, Resample): the v2 episodes above (``TASK_SCENARIOS_V2``, "
    "``true_noise=True``, ``bias_features=True``, ``true_bias_limit_ug=None``), "
    "``penalize_remaining_steps=True`` as v1, and the memory features. On 256 held-out episodes "
    "(``python -m experiments.headroom``) the clairvoyant EKF/CKF (told every step's true Q, R and "
    "bias) reaches 2.23 m RMSE against 7.35 m for the best tuned constant fading factor, 9.58 m for "
    "the best constant noise scales and 13.36 m for the plain GS-CKF (on every GpsIns v2 id the "
    "best tuned baseline is a constant knob: no adaptive rule tuned better)."
)

_CARD_TEMPLATE = """Carvalho et al. 1997's tightly coupled GPS/INS, with an agent steering the navigation filter.

    ## Description
    A land vehicle (or ship) navigates with a navigation-grade INS whose errors follow the two-axis
    model of Carvalho et al. 1997 (eq. 12-14) and a GPS receiver tracking up to
    ``m_max`` satellites of a real almanac (GPS week 2086) at 1 Hz: pseudo-ranges of eq. 10/15
    with receiver clock (eq. 11), troposphere and switchable noise regimes. An eight-state
    error filter (eq. 13) fuses them. Episodes bring GNSS outages, partial outages, impulsive noise
    (Benzerrouk 2014, eq. 71) and jamming, drawn from a seeded scenario distribution; the critical
    scenario of Carvalho et al. 1997 (50 deg mask, 3 -> 2 satellites over 3600 s) is
    ``critical=True``. The agent controls the filter, not the vehicle: the fading factor
    (``GpsInsFading``), the outlier weight of a Gaussian-sum filter (``GpsInsMixture``) or a
    particle filter's resampling (``GpsInsResample``).

    {v2_events}

    ## Action Space
    {action_space}
    The Mixture's outlier rows are all the pseudo-ranges.

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter (innovations, covariances, satellites used, the previous action); no truth.

    {observation_table}

    In the Fading ids ``log_tr_HQH`` stays at its floor -8: the process noise of the model of
    Carvalho et al. 1997 drives only the accelerometer biases and the clock drift, which no
    pseudo-range sees within one step, so ``tr(H Q H^T) = 0`` (the column is kept so every Fading
    env publishes the same traces of Benzerrouk 2014, eq. 67-70).

    ## Rewards
    {rewards}

    ## Starting State
    The filter starts from its prior ``N(0, P0)`` (10 m, 0.05 m/s, bias ``imu_grade``'s limit / 2
    = 5 ug for the navigation grade, 30 m, 0.3 m/s). The true clock and INS errors are drawn from
    it too, except the IMU biases where ``true_bias_limit_ug = (lo, hi)`` is set (the default of
    ``GpsInsFading``: ``(10, 3000)``): each episode's true IMU then has a bias limit ``L`` drawn
    log-uniformly in ``[lo, hi]`` ug, its initial bias sigma (``L / 2``) and bias random walk
    scaled by ``L`` over the assumed limit, while the filter keeps ``imu_grade``'s model (the
    model mismatch the fading factor is for: true biases of hundreds of ug against a prior sigma
    of 5 ug). ``GpsInsMixture`` and ``GpsInsResample`` default to ``None`` (true IMU = assumed
    IMU). Vehicle start within 35-60 N, 10 W-30 E, GPS time within +-2 days of the almanac.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 300; pass 3600 for the full critical
    run) or at the simulated horizon ``episode_steps`` (300 s; 3600 s with ``critical=True``).
    {episode_end}

    ## Arguments
    GpsIns' own: ``dt=1.0`` [s] in (0, 60], ``vehicle="land"|"ship"``,
    ``imu_grade="navigation"|"tactical"|"consumer"`` (bias limit 10, 100, 2000 ug), ``m_max=12``
    satellites (an integer 4-16; the Resample ids are registered with 8: the particle likelihood
    costs N x m per step), ``sigma_pr=5.0`` [m] in [0.001, 1000] (the simulated nominal noise and the
    filter's), ``mask_deg`` (a fixed elevation mask [deg] in [0, 90) instead of the
    distribution's), ``critical=False`` (a bool; True: Carvalho et al. 1997's fixed critical
    scenario over 3600 s; takes no scenario arguments) and ``true_bias_limit_ug=(10.0, 3000.0)``
    (Fading) or ``None`` (Mixture, Resample): the model mismatch between the IMU the filter assumes
    (``imu_grade``) and the true one, the range [ug] within (0, 1e5] of the true bias limit drawn
    log-uniformly per episode (see Starting State). With
    ``particle_dtype="float32"`` the pseudo-ranges are weighed "observed minus computed", so the
    float32 cloud loses no innovation precision (without resampling the two precisions agree to
    2e-4 m over 60 steps). Every argument is checked at ``make`` (type, finiteness, range: a
    ``TypeError`` or ``ValueError`` naming it), and so is the memory of a batch's episodes,
    about 800 bytes per step and episode here (``episode_bytes``): ``num_envs`` times that must
    stay within ``navgym.envs.build.MAX_EPISODE_BYTES`` (4 GiB).
    {common_arguments}

    ## Version History
    {v2_version}
    {version_history}
"""  # noqa: E501 - the title line
#: The GpsIns env card (Gymnasium's sections) with the v2 paragraph, before the shared
#: placeholders are filled (:func:`navgym.envs.cards.fill_card`); the v0/v1 classes and the v2
#: classes (:mod:`navgym.gps_ins.env_v2`) share it.
GPS_INS_CARD = _CARD_TEMPLATE.replace("{v2_events}", v2_events_text(V2_EVENTS)).replace(
    "{v2_version}", textwrap.fill(V2_VERSION_HISTORY, 96, subsequent_indent="      ")
)


class GpsInsEnv(PlatformEnv, spec=GPS_INS):  # noqa: D101 - the card is GPS_INS_CARD
    __doc__ = GPS_INS_CARD


class GpsInsVectorEnv(PlatformVectorEnv, spec=GPS_INS):
    """Native batched GpsIns environment (see :class:`GpsInsEnv` for the card)."""
