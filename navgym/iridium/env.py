"""Iridium environments: the platform's declaration (:data:`IRIDIUM`, :data:`IRIDIUM_V2`) and its env card.

The estimation problem is :class:`navgym.iridium.platform.IridiumPlatform`; everything shared by
all platforms (keyword arguments, core, env shells, card paragraphs) comes from
:mod:`navgym.envs.platform`. The platform is registered at v2 only (``navgym/IridiumMixture-v2``,
``navgym/IridiumNoiseScale-v2``): within-episode events unknown to the filter and the true noise
kept for the clairvoyant reference. :data:`IRIDIUM` declares the keyword arguments every
platform's v0/v1 declaration has; :data:`IRIDIUM_V2`, the one the registered classes use, adds the
event ranges (:data:`V2_EVENT_KWARGS`).
"""

from __future__ import annotations

import textwrap
from dataclasses import replace
from typing import Any

from navgym.envs import arguments
from navgym.envs.cards import span
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.iridium.constellation import IRIDIUM_MASK_DEG
from navgym.iridium.platform import ROWS, IridiumPlatform
from navgym.iridium.sensors import IridiumFixNoise

#: Episodes: one hour of 10 s steps (Benzerrouk 2014, §2.7d: a fix every 10 s).
EPISODE_STEPS = 360
DT = 10.0
#: The within-episode events of the v2 ids (episodes of 3600 s; events start after 300 s, the
#: filter's convergence from a 1 km fix at rest): several per episode, unknown to the filter (its
#: ``Q`` and the CEP-derived ``R`` stay nominal). Ranges are drawn uniformly.
V2_EVENTS: dict[str, Any] = {
    "outage_probability": 0.7,
    "outage_count": (1, 3),
    "outage_duration": (60.0, 300.0),
    "impulsive_probability": 0.8,
    "impulsive_eps": (0.1, 0.4),
    "impulsive_var_ratio": (10.0, 100.0),
    "impulsive_duration": (300.0, 1200.0),
    "jamming_probability": 0.6,
    "jamming_count": (1, 2),
    "jamming_duration": (300.0, 900.0),
    "jamming_sigma": (500.0, 2500.0),
    "jamming_loss": (0.0, 0.3),
    "jamming_ramp": (60.0, 240.0),
    "burst_probability": 0.9,
    "burst_count": (2, 4),
    "burst_duration": (60.0, 300.0),
    "burst_velocity_sigma": (2.0, 6.0),
    "canyon_probability": 0.6,
    "canyon_count": (1, 2),
    "canyon_duration": (120.0, 600.0),
    "canyon_satellites": (0, 2),
    "canyon_noise_scale": (1.5, 3.0),
    "canyon_loss": (0.0, 0.5),
    "multipath_probability": 0.0,
    "multipath_count": (1, 2),
    "multipath_duration": (300.0, 900.0),
    "multipath_bias": (1000.0, 4000.0),
    "multipath_sigma": (0.0, 500.0),
    "multipath_rows": (0, 1),
}
#: The v2 ids' event keyword arguments: every key of :data:`V2_EVENTS` (its value the default).
V2_EVENT_KWARGS: tuple[str, ...] = tuple(V2_EVENTS)
#: The elevation mask of each episode, drawn uniformly [deg]: Iridium's 8.2 deg (continuous
#: coverage) to 15 deg (gaps of a few minutes where the constellation thins out).
MASK_DEG = (IRIDIUM_MASK_DEG, 15.0)
#: Scenario defaults per task (both tasks: the v2 events and the mask range).
TASK_SCENARIOS_V2: dict[str, dict[str, Any]] = {
    t: {**V2_EVENTS, "mask_deg": MASK_DEG} for t in ("mixture", "noisescale")
}
#: Scenario keyword arguments every platform's v0/v1 declaration takes.
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
#: Scenario keyword arguments of the v2 ids: the above and the event ranges (no name twice).
SCENARIO_KWARGS_V2: tuple[str, ...] = tuple(dict.fromkeys(SCENARIO_KWARGS + V2_EVENT_KWARGS))
#: Iridium's own keyword arguments: the :class:`IridiumFixNoise` field or platform field each
#: sets, and its range.
PLATFORM_KWARGS: dict[str, tuple[float, float]] = {
    "cep_zenith": (0.0, 1e5),  # [m], (0, high]
    "outlier_rate": (0.0, 1.0),
    "gross_rate": (0.0, 1.0),
    "accel_psd": (0.0, 1e3),  # [m^2/s^3], (0, high]
}


def build_platform(a: PlatformArgs) -> IridiumPlatform:
    """An :class:`IridiumPlatform` from its keyword arguments (popped from ``a.kwargs``), true noise kept."""
    kw = a.kwargs
    arguments.multipath_rows(a.scenarios, (0, 1), "rows of the Iridium fix (N, E)")
    own = {}
    for k, (lo, hi) in PLATFORM_KWARGS.items():
        if k in kw:
            own[k] = arguments.real(k, kw.pop(k), lo, hi, low_open=k in ("cep_zenith", "accel_psd"))
    noise = {k: own.pop(k) for k in ("cep_zenith", "outlier_rate", "gross_rate") if k in own}
    fixes = IridiumFixNoise(**noise)
    if fixes.cep_zenith > fixes.cep_max:
        fixes = replace(fixes, cep_max=fixes.cep_zenith)
    return IridiumPlatform(
        dt=a.dt,
        fixes=fixes,
        scenarios=a.scenarios,
        error_scale_m=a.error_scale_m,
        divergence_m=a.divergence_m,
        true_noise=True,
        **own,
    )


#: The Iridium platform's declaration with the scenario arguments of a v0/v1 declaration.
IRIDIUM = PlatformSpec(
    name="Iridium",
    build=build_platform,
    tasks=TASK_SCENARIOS_V2,
    scenario_arguments=SCENARIO_KWARGS,
    episode_steps=EPISODE_STEPS,
    dt=DT,
    dt_argument=False,
    error_scale_m=1000.0,
    divergence_m=50e3,
    start_margin_s=300.0,
    platform_arguments=tuple(PLATFORM_KWARGS),
)
#: The declaration of the registered (v2) classes: the event ranges are keyword arguments too.
IRIDIUM_V2: PlatformSpec = replace(IRIDIUM, scenario_arguments=SCENARIO_KWARGS_V2)


def v2_events_text(e: dict[str, Any]) -> str:
    """The card's paragraph on the v2 episodes, from their scenario defaults (:data:`V2_EVENTS`)."""
    text = (
        "**v2 episodes** (the only ones: ``IridiumMixture-v2``, ``IridiumNoiseScale-v2``, scenario "
        "defaults ``TASK_SCENARIOS_V2``) change the noise inside the episode, several times, "
        "without telling the filter (its ``Q`` and the CEP-derived ``R`` stay nominal): "
        f"outages without fixes ({span(e['outage_count'])} with probability {e['outage_probability']:g}, "
        f"{span(e['outage_duration'], 's')} each); an impulsive segment (probability "
        f"{e['impulsive_probability']:g}, {span(e['impulsive_duration'], 's')}: each fix is an outlier "
        f"with probability {span(e['impulsive_eps'])}, its variance times {span(e['impulsive_var_ratio'])}, "
        "Benzerrouk 2014, eq. 71); "
        f"interference that ramps up and down ({span(e['jamming_count'])} with probability "
        f"{e['jamming_probability']:g}, {span(e['jamming_duration'], 's')}, ramps of "
        f"{span(e['jamming_ramp'], 's')} to {span(e['jamming_sigma'], 'm')} of extra noise per axis and "
        f"{span(tuple(100 * x for x in e['jamming_loss']))} % lost fixes); "
        f"masked segments ({span(e['canyon_count'])} with probability {e['canyon_probability']:g}, "
        f"{span(e['canyon_duration'], 's')}: at most {span(e['canyon_satellites'])} usable satellites, "
        f"none at 0, fix noise times {span(e['canyon_noise_scale'])}, "
        f"{span(tuple(100 * x for x in e['canyon_loss']))} % lost fixes); and manoeuvre bursts "
        f"({span(e['burst_count'])} with probability {e['burst_probability']:g}, "
        f"{span(e['burst_duration'], 's')}: the velocity changes by {span(e['burst_velocity_sigma'], 'm/s')} "
        "rms per 10 s step and axis beyond the nominal 0.5 m/s, the acceleration PSD the filter's "
        "``Q`` does not hold). Biased segments (the scenario's multipath on a fix row: "
        f"{span(e['multipath_bias'], 'm')} of bias) are off by default (``multipath_probability=0``). "
        "Each of these ranges, counts and probabilities is a scenario keyword argument "
        "(``V2_EVENT_KWARGS``, e.g. ``burst_duration=(lo, hi)``; ``multipath_rows`` within the fix "
        "rows 0-1). Every step's true process noise, fix variance and bias go to "
        "``StepModels.truth`` (evaluation only, for the clairvoyant reference, never in the "
        "observation)."
    )
    return textwrap.fill(text, 96, subsequent_indent="    ", break_on_hyphens=False, break_long_words=False)


#: The Version History line of the v2 ids (figures from ``python -m experiments.headroom``).
V2_VERSION_HISTORY = (
    "* v2 (Mixture, NoiseScale): initial release, with the v2 episodes above, the memory "
    "features, ``penalize_remaining_steps=True`` and, for Mixture, one outlier weight per fix "
    "row (``per_row=True``). On 256 held-out episodes (``python -m experiments.headroom``) the "
    "plain filter's position RMSE is 2142 m on average (3.5 % of the episodes diverge on a gross "
    "outlier), the clairvoyant's 723 m; the best tuned baselines (256 tuning episodes) are a "
    "constant outlier weight eps = 0.01 per row (1310 m; the clairvoyant is 44.8 % lower) and "
    "constant scales s_q = s_r = 30 (1831 m; 60.5 % lower)."
)

_CARD_TEMPLATE = """Iridium-only positioning (Benzerrouk 2014, §2.7d, eq. 83), an agent steering its filter.

    ## Description
    A road vehicle loses GPS (Benzerrouk 2014, §2.7d: the dynamic test from Belgium through
    France to Spain) and is positioned by Iridium geolocation fixes alone, each used as a virtual
    beacon (eq. 83): a four-state filter ``x = [x_N, y_E, v_N, v_E]`` (north/east position [m] and
    velocity [m/s] in a local plane) predicts with the white-noise-acceleration model (Bar-Shalom
    et al. 2001, §6.2.2; nominal PSD 0.025 m^2/s^3) and updates every 10 s step with the fix,
    ``z = [x_N, y_E] + e`` (the innovation's norm is eq. 83's range to the beacon), whose ``R =
    sigma^2 I`` comes from the CEP radius the fix reports (``sigma = CEP / 1.1774``). **The
    Iridium constellation decides when a fix arrives** (:mod:`navgym.iridium.constellation`: 66
    satellites in 6 circular planes, 86.4 deg, 780 km, period 100 min 28 s, the source's
    figures; a fix needs a satellite above the episode's elevation mask, drawn in
    {mask_lo:g}-{mask_hi:g} deg, at the vehicle's place in the Belgium-France-Spain corridor),
    and the serving satellite's elevation sets the reported CEP (650 m overhead, 1.7 km at 8.2
    deg; ~0.9 km on average: the source's "average error of 1 km"). The errors are those the
    source reports: Gaussian with the CEP's sigma, outliers of 2-10 km (3 % of the fixes) and
    rare ones above 100 km (0.1 %: seven in the source's day-long trip), which the reported CEP
    does not show (:mod:`navgym.iridium.sensors`). The agent controls the filter, not the
    vehicle: the outlier weight of each fix row in a per-row Gaussian-mixture update
    (``IridiumMixture``, eq. 71-76) or the scales of ``Q`` and ``R`` (``IridiumNoiseScale``).

    {v2_events}

    ## Action Space
    {action_space}
    The Mixture's outlier rows are both fix rows (N, E).

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter and the modem (innovations, covariances, rows used, the fix's reported CEP,
    fix age, the previous action, the memory features); no truth. ``time_since_gnss`` counts the
    Iridium fix rows (Iridium stands in for GNSS here), so it equals ``time_since_fix``.

    {observation_table}

    ## Rewards
    {rewards}

    ## Starting State
    The vehicle starts at the origin of its local north/east frame at 20-35 m/s in a uniform
    direction, at a uniform place of latitude 41-51 deg N and longitude 4 deg W - 5 deg E, the
    constellation in a uniform phase. The filter starts from the first fix (nominal noise) at
    rest: ``P0 = diag(sigma_0^2, sigma_0^2, 20^2, 20^2)`` with ``sigma_0`` from that fix's CEP.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 360 steps of 10 s = 1 h) or at the
    simulated horizon ``episode_steps`` (360). ``divergence_m = 50`` km is fifty times the error
    scale: a gross outlier (> 100 km) taken at full weight moves the plain filter by some 10-40
    km.
    {episode_end}

    ## Arguments
    Iridium's own: ``cep_zenith=650`` [m] in (0, 1e5] (the CEP with the serving satellite
    overhead), ``outlier_rate=0.03`` and ``gross_rate=0.001`` in [0, 1] (the fix error model of
    :class:`navgym.iridium.sensors.IridiumFixNoise`), ``accel_psd=0.025`` [m^2/s^3] in (0, 1000]
    (the truth's nominal acceleration PSD and the filter's ``Q``). The step is fixed at ``dt =
    10`` s (the fix period). Every argument is checked at ``make`` (type, finiteness, range: a
    ``TypeError`` or ``ValueError`` naming it), and so is the memory of a batch's episodes, about
    440 bytes per step and episode here plus 500 kB of satellite geometry (``episode_bytes``):
    ``num_envs`` times that must stay within ``navgym.envs.build.MAX_EPISODE_BYTES`` (4 GiB).
    {common_arguments}

    ## Version History
    {v2_version}
"""
#: The Iridium env card (Gymnasium's sections) before the shared placeholders are filled
#: (:func:`navgym.envs.cards.fill_card`).
IRIDIUM_CARD = (
    _CARD_TEMPLATE.replace("{v2_events}", v2_events_text(V2_EVENTS))
    .replace("{v2_version}", textwrap.fill(V2_VERSION_HISTORY, 96, subsequent_indent="      "))
    .replace("{mask_lo:g}", f"{MASK_DEG[0]:g}")
    .replace("{mask_hi:g}", f"{MASK_DEG[1]:g}")
)
#: Measurement rows (for the card and tests).
FIX_ROWS = ROWS


class IridiumEnv(PlatformEnv, spec=IRIDIUM_V2):  # noqa: D101 - the card is IRIDIUM_CARD
    __doc__ = IRIDIUM_CARD


class IridiumVectorEnv(PlatformVectorEnv, spec=IRIDIUM_V2):
    """Native batched Iridium environment (see :class:`IridiumEnv` for the card)."""
