"""Robot2d v3 environments: the v2 episodes with context (:data:`ROBOT2D_V3`).

The v3 variant runs the Robot2d platform on the v2 scenario defaults (the same events) with
``Robot2dPlatform(true_noise=True, context=True)``: the GNSS fixes' noise follows each receiver's
satellites, HDOP and C/N0 (:mod:`navgym.robot2d.context`), and the observation gains what a real
receiver and IMU report besides the filter's own statistics: each fix's C/N0 and accuracy
estimate, the satellites used and HDOP of each receiver, and the odometry-IMU consistency of a
simulated gyro. Ids are registered centrally (not in :mod:`navgym.robot2d.env_ids` yet); build
cores with ``ROBOT2D_V3.core(task, num_envs, kwargs)``.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs.cards import with_paragraph
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.gnss.receiver_report import cn0_offset_argument
from navgym.robot2d.env import ROBOT2D_CARD, TASK_SCENARIOS_V2, V2_EVENTS
from navgym.robot2d.env_v2 import ROBOT2D_V2, build_platform_v2
from navgym.robot2d.platform import Robot2dPlatform


def build_platform_v3(a: PlatformArgs) -> Robot2dPlatform:
    """:func:`~navgym.robot2d.env_v2.build_platform_v2` with the context (``context=True``).

    ``cn0_offset_db`` (:data:`V3_PLATFORM_KWARGS`) shifts the receiver's C/N0 report
    (:mod:`navgym.gnss.receiver_report`); it lies in ``[-CN0_OFFSET_MAX_DB, CN0_OFFSET_MAX_DB]``.
    """
    return replace(build_platform_v2(a), context=True, cn0_offset_db=cn0_offset_argument(a.kwargs))


#: Tasks of the v3 variant: v2's and RowScale (one R multiplier per row and a process-noise scale).
TASK_SCENARIOS_V3 = {
    **TASK_SCENARIOS_V2,
    "rowscale": dict(V2_EVENTS),
}

#: Robot2d's own keyword arguments of the v3 ids: v2's and the report's C/N0 offset ``cn0_offset_db``.
V3_PLATFORM_KWARGS: tuple[str, ...] = (*(ROBOT2D_V2.platform_arguments or ()), "cn0_offset_db")

#: Robot2d's v2 declaration with the context switched on (and ``cn0_offset_db``).
ROBOT2D_V3: PlatformSpec = replace(
    ROBOT2D_V2, build=build_platform_v3, tasks=TASK_SCENARIOS_V3, platform_arguments=V3_PLATFORM_KWARGS
)

CONTEXT_TEXT = (
    "**Context (v3)** (:mod:`navgym.robot2d.context`, ``context=True``): simulated sensors, caused "
    "by the scenario's events through physics and with their own randomness, never by labels or "
    "truth. Each receiver (GPS, GLONASS) sees a slowly varying number of satellites (GPS 7-12, "
    "GLONASS 5-10 per episode, +-1.5 over minutes, at least 5), capped by an urban canyon or "
    "outage; ``HDOP = k_geo / sqrt(n_sv - 3)`` with ``k_geo`` uniform in 1.5-2.5 per episode "
    "(Kaplan & Hegarty 2006, 7.1); per-satellite C/N0 from elevation (32-48 dB-Hz, "
    "``navgym.gnss.signal_quality.nominal_cn0_dbhz``) with a 1.5 dB offset per satellite, lowered "
    "by a canyon's diffraction loss ``20 log10(noise_scale)`` dB and by NLOS multipath segments "
    "(4-12 dB, fading 2 dB per epoch; 30 % of segments are line-of-sight multipath, 0-1 dB: C/N0 "
    "stays normal while the bias acts), then by the jammer through ``J/S`` "
    "(``effective_cn0_dbhz``, Q = 2; v2's jamming of ``jam_sigma`` maps to "
    "``J/S = Q R_c / C/N0_ref (jam_sigma / 3 m)^2``, 38 dB at 30 m). The fix noise per axis is "
    "``HDOP sigma_UERE``, ``sigma_UERE^2`` the mean SIGMA-epsilon variance "
    "``C_i 10^(-C/N0/10)`` of the satellites used (Hartinger & Brunner 1999), ``C_i`` such that "
    "HDOP 1 at 42 dB-Hz gives the nominal 3 m (GPS) and 5 m (GLONASS); v2's multipath bias and "
    "noise and impulsive outliers are added. A MEMS gyro (BMI088 figures, Groves 2013 Table 4.1: "
    "0.014 deg/s/sqrt(Hz), bias 0.1 deg/s walking 0.001 deg/s/sqrt(s)) sees the true yaw rate, "
    "slip included. Features: ``row_cn0`` (5 rows) [dB-Hz] in [0, 60], the mean reported C/N0 "
    "(1 dB estimator noise, 1 dB-Hz resolution) of the row's receiver, 0 on rows not delivered "
    "and the compass; ``row_reported_sigma`` (5) [m] in [0, 100], the receiver's own accuracy "
    "estimate ``HDOP sqrt(mean C_i 10^(-C/N0_rep/10))`` per axis, blind to multipath bias, 0 "
    "likewise; ``gnss_n_sv`` (GPS, GLONASS) in [0, 12] and ``gnss_hdop`` (2) in [0, 20], the "
    "last fix's report held, with ``gnss_report_age`` (2) [s] in [0, 60]; ``imu_activity`` "
    "[rad/s] in [0, 2], the RMS over the last 1 s of the odometry yaw rate "
    "``v_c tan(alpha) / L`` (measured encoder and steering, eq. 77) minus the gyro rate, which "
    "rises under wheel slip. ``cn0_offset_db`` [dB] in [-10, 10] (default 0; v3 ids only) models "
    "a receiver other than the one trained on: both receivers report "
    "``round(C/N0 + cn0_offset_db + n)`` per satellite, so ``row_cn0`` "
    "shifts by the offset (clipped into its bounds; rows not delivered stay 0) and "
    "``row_reported_sigma`` follows it (a higher report, a smaller sigma), while the true C/N0, the "
    "fix noise and the episodes stay the same (no extra random draws). "
    "Values are clipped into their bounds."
)

ROBOT2D_V3_CARD = with_paragraph(ROBOT2D_CARD, CONTEXT_TEXT)


class Robot2dEnv(PlatformEnv, spec=ROBOT2D_V3):  # noqa: D101 - the card is ROBOT2D_V3_CARD
    __doc__ = ROBOT2D_V3_CARD


class Robot2dVectorEnv(PlatformVectorEnv, spec=ROBOT2D_V3):
    """Native batched Robot2d v3 environment (see :class:`Robot2dEnv` for the card)."""
