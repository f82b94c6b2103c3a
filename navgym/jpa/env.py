"""Jpa environments: the platform's declaration (:data:`JPA`) and its env card.

The estimation problem is :class:`navgym.jpa.platform.JpaPlatform` (Belles et al. 2022, §5); the
skeleton (:mod:`navgym.envs.platform`) supplies the rest. Registered at v2 only
(``navgym/JpaRobust-v2``): cycle-slip and multipath zones inside the episode, unknown to the
filter, and the true noise kept for the clairvoyant reference.
"""

from __future__ import annotations

import textwrap
from typing import Any

from navgym.envs import arguments
from navgym.envs.cards import span
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.jpa.platform import PLATFORM_CONFIG, JpaPlatform

#: Episodes: two minutes of 1 s epochs.
EPISODE_STEPS = 120
DT = 1.0
#: The scenario's multipath segments (on the base-master code DDs; rows = DD satellite indices);
#: no outages by default.
V2_EVENTS: dict[str, Any] = {
    "outage_probability": 0.0,
    "multipath_probability": 0.7,
    "multipath_count": (1, 2),
    "multipath_duration": (10.0, 30.0),
    "multipath_bias": (1.0, 5.0),
    "multipath_sigma": (0.0, 1.0),
    "multipath_rows": tuple(range(PLATFORM_CONFIG.n_dd)),
}
#: Scenario keyword arguments of the Jpa ids.
SCENARIO_KWARGS: tuple[str, ...] = (
    *V2_EVENTS,
    "outage_count",
    "outage_duration",
    "start_margin",
)
#: Jpa's own keyword arguments and their ranges.
PLATFORM_KWARGS: dict[str, tuple[float, float]] = {
    "slip_probability": (0.0, 1.0),
    "attitude_weight": (0.0, 100.0),  # [m/deg]
}
#: Largest cycle slip [cycles] ``slip_max_cycles`` may set.
MAX_SLIP_CYCLES = 100


def build_platform(a: PlatformArgs) -> JpaPlatform:
    """A :class:`JpaPlatform` from its keyword arguments (popped from ``a.kwargs``), true noise kept."""
    kw = a.kwargs
    arguments.multipath_rows(a.scenarios, range(PLATFORM_CONFIG.n_dd), "double-difference satellite indices")
    own: dict[str, Any] = {}
    for k, (lo, hi) in PLATFORM_KWARGS.items():
        if k in kw:
            own[k] = arguments.real(k, kw.pop(k), lo, hi)
    if "slip_max_cycles" in kw:
        own["slip_max_cycles"] = arguments.integer(
            "slip_max_cycles", kw.pop("slip_max_cycles"), 1, MAX_SLIP_CYCLES
        )
    return JpaPlatform(
        dt=a.dt,
        scenarios=a.scenarios,
        error_scale_m=a.error_scale_m,
        divergence_m=a.divergence_m,
        true_noise=True,
        **own,
    )


#: The Jpa platform's declaration.
JPA = PlatformSpec(
    name="Jpa",
    build=build_platform,
    tasks={"robust": V2_EVENTS},
    scenario_arguments=SCENARIO_KWARGS,
    episode_steps=EPISODE_STEPS,
    dt=DT,
    dt_argument=False,
    error_scale_m=1.0,
    divergence_m=100.0,
    start_margin_s=10.0,
    platform_arguments=(*PLATFORM_KWARGS, "slip_max_cycles"),
)

#: The Version History line of the v2 id (figures from ``python -m experiments.headroom``).
V2_VERSION_HISTORY = (
    "* v2 (Robust): initial release (memory features, ``penalize_remaining_steps=True``). On 256 "
    "held-out episodes (``python -m experiments.headroom``) the plain iterated ESKF's horizontal "
    "RMSE is 0.163 m, the best tuned baseline (a constant c = 0.7, 256 tuning episodes) 0.114 m, "
    "the clairvoyant 0.013 m: headroom 88.6 % [87.0, 90.0], PASS. Most of it is out of the "
    "threshold's reach: the clairvoyant subtracts the slips and biases, while the robust weights "
    "act on residuals whitened with the full DD covariance, where a slipped row spreads into the "
    "others; a threshold set from the truth (0.5 inside the events, inf outside) gave 0.105 m "
    "against the constant's 0.107 m (64 episodes)."
)

_CARD_TEMPLATE = """GNSS joint position and attitude (Belles et al. 2022, §5): an agent steers a robust ESKF.

    ## Description
    A vehicle with a master and two slave GNSS antennas (1 m along the body x and y axes)
    estimates its position and attitude from double-differenced (DD) code and carrier phases of
    7 satellites against a base station 5 km away (Belles et al. 2022, eq. 11-12; the model of
    ``experiments.robust_jpa``, :mod:`navgym.jpa.models`), every 1 s, with an iterated error-state
    KF on the attitude manifold (eq. 13-17): attitude, 18 float DD ambiguities, position,
    velocity and gyro bias (30 error states, 36 DDs; the gyro drives the attitude). The filter's
    mean keeps the nominal attitude as a rotation vector; the update runs on the error state and
    is reset into it. The satellites are the 7 highest of the packaged almanac over one of 12
    windows of the day, drawn per episode; the DD noise has exactly the filter's covariance
    (``sigma_zenith / sin el`` per undifferenced observation, Table 1: 3 mm phase, 0.3 m code).
    The agent controls the filter, not the vehicle: the threshold ``c`` of the Huber (or Tukey)
    weights of the robust iterated update (Algorithm 1, eq. 20), every step.

    **v2 episodes** (the only ones) carry events the filter is not told about (its ``Q`` and
    ``R`` stay nominal): **cycle slips** (Belles et al. 2022, §5): with probability
    ``slip_probability=0.9`` 1-2 zones of 10-30 s, each on 1-2 non-reference satellites, an
    integer of 1 to ``slip_max_cycles=5`` cycles (random sign) at every vehicle antenna, removed at
    the end of the zone; it cancels in the master-slave DDs and biases the base-master phase DDs
    of those satellites by ``lambda x cycles`` (19-95 cm, 30-150 sigma). **Multipath** (the
    scenario's segments): {multipath}. Every step's true ``R`` (multipath noise included) and row
    biases go to ``StepModels.truth`` (evaluation only, for the clairvoyant reference). GNSS
    outages (the scenario's ``outage_*``, off by default) remove every DD: the filter predicts on
    the gyro alone.

    ## Action Space
    {action_space}

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter and the receiver (DD innovations, covariances, the lowest elevation, the
    applied threshold and the robust weights, the previous action, the memory features); no truth.

    {observation_table}

    ## Rewards
    {rewards} The error adds the attitude error: ``pos_err_m + attitude_weight x |Log(R_true^T
    R_est)|`` [deg] with ``attitude_weight=0.1`` m/deg (``info["extra_err"]``), so 1 deg of
    attitude error costs as much as 10 cm of horizontal position error (the horizontal error of
    the master antenna alone is ``info["pos_err_m"]``, the RMSE of ``experiments.headroom``).

    ## Starting State
    The vehicle starts 5 km from the base station in a uniform direction, level, with a uniform
    heading and a velocity of 5 m/s rms per horizontal axis; integer ambiguities in [-20, 20]
    cycles. The filter starts from a converged float solution: truth plus errors of its prior
    sigmas, 1 deg attitude, 0.05 cycles per ambiguity, 5 cm position, 0.1 m/s velocity, Table 1's
    gyro bias.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 120 steps of 1 s) or at the
    simulated horizon ``episode_steps`` (120). ``divergence_m = 100`` m.
    {episode_end}

    ## Arguments
    Jpa's own: ``slip_probability=0.9`` in [0, 1], ``slip_max_cycles=5`` (integer in [1, 100]),
    ``attitude_weight=0.1`` [m/deg] in [0, 100]. The step is fixed at ``dt = 1`` s.
    ``multipath_rows`` are DD satellite indices (0-5). Every argument is checked at ``make`` (type,
    finiteness, range: a ``TypeError`` or ``ValueError`` naming it), and so is the memory of a
    batch's episodes, about 4 kB per step and episode here (``episode_bytes``): ``num_envs`` times
    that must stay within ``navgym.envs.build.MAX_EPISODE_BYTES`` (4 GiB).
    {common_arguments}

    ## Version History
    {v2_version}
"""


def _multipath_text(e: dict[str, Any]) -> str:
    return (
        f"with probability {e['multipath_probability']:g}, {span(e['multipath_count'])} segments of "
        f"{span(e['multipath_duration'], 's')}, each on the base-master code DD of one satellite: a "
        f"bias of {span(e['multipath_bias'], 'm')} (random sign) and {span(e['multipath_sigma'], 'm')} "
        "of extra noise"
    )


#: The Jpa env card (Gymnasium's sections) before the shared placeholders are filled.
JPA_CARD = _CARD_TEMPLATE.replace("{multipath}", _multipath_text(V2_EVENTS)).replace(
    "{v2_version}", textwrap.fill(V2_VERSION_HISTORY, 96, subsequent_indent="      ")
)


class JpaEnv(PlatformEnv, spec=JPA):  # noqa: D101 - the card is JPA_CARD
    __doc__ = JPA_CARD


class JpaVectorEnv(PlatformVectorEnv, spec=JPA):
    """Native batched Jpa environment (see :class:`JpaEnv` for the card)."""
