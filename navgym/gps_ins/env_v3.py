"""GpsIns v3 environments: the v2 episodes with the receiver's and the IMU's context (:data:`GPS_INS_V3`).

The v3 variant runs the GpsIns platform on the v2 scenario defaults (the same events) with
``GpsInsPlatform(true_noise=True, bias_features=True, context=True)``: every pseudo-range row's
noise follows its C/N0 (elevation, satellite, NLOS and canyon losses, the jammer's J/S;
:mod:`navgym.gps_ins.context`), the manoeuvre bursts are vibration the IMU senses, and the
observation gains what a receiver and an IMU report besides the filter's own statistics. The
tasks are v2's plus RowScale (one R multiplier per row and a velocity process-noise scale).
Ids are registered centrally (not in :mod:`navgym.gps_ins.env_ids` yet); build cores with
``GPS_INS_V3.core(task, num_envs, kwargs)``.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs.cards import with_paragraph
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.gnss.receiver_report import cn0_offset_argument
from navgym.gps_ins import context as ctx
from navgym.gps_ins.env import GPS_INS_CARD, TASK_SCENARIOS_V2, V2_EVENTS
from navgym.gps_ins.env_v2 import GPS_INS_V2, build_platform_v2
from navgym.gps_ins.platform import GpsInsPlatform


def build_platform_v3(a: PlatformArgs) -> GpsInsPlatform:
    """:func:`~navgym.gps_ins.env_v2.build_platform_v2` with the context (``context=True``).

    ``cn0_offset_db`` (:data:`V3_PLATFORM_KWARGS`) shifts the receiver's C/N0 report
    (:mod:`navgym.gnss.receiver_report`); it lies in ``[-CN0_OFFSET_MAX_DB, CN0_OFFSET_MAX_DB]``.
    """
    return replace(build_platform_v2(a), context=True, cn0_offset_db=cn0_offset_argument(a.kwargs))


#: Tasks of the v3 variant: v2's and RowScale (one R multiplier per row and a process-noise scale).
TASK_SCENARIOS_V3 = {
    **TASK_SCENARIOS_V2,
    "rowscale": dict(V2_EVENTS),
}

#: GpsIns' own keyword arguments of the v3 ids: v2's and the report's C/N0 offset ``cn0_offset_db``.
V3_PLATFORM_KWARGS: tuple[str, ...] = (*(GPS_INS_V2.platform_arguments or ()), "cn0_offset_db")

#: GpsIns' v2 declaration with the context switched on (and ``cn0_offset_db``).
GPS_INS_V3: PlatformSpec = replace(
    GPS_INS_V2, build=build_platform_v3, tasks=TASK_SCENARIOS_V3, platform_arguments=V3_PLATFORM_KWARGS
)

CONTEXT_TEXT = (
    "**Context (v3)** (:mod:`navgym.gps_ins.context`, ``context=True``): simulated sensors, caused "
    "by the scenario's events through physics and with their own randomness, never by labels or "
    "truth. Each pseudo-range row's true C/N0 is the open-sky ``C/N0 = 32 + 16 sin(el)`` dB-Hz "
    "(``navgym.gnss.signal_quality.nominal_cn0_dbhz``; el from the true position) plus a "
    f"{ctx.SAT_OFFSET_DB:g} dB offset per satellite, less the row's attenuation: an urban canyon's "
    "diffraction loss ``20 log10(noise_scale)`` dB (6-12 dB for v2's 2-4; the canyon also caps "
    "the satellites, the highest stay, and loses rows) plus the losses of the multipath segments "
    f"on the satellite (NLOS {ctx.NLOS_LOSS_DB[0]:g}-{ctx.NLOS_LOSS_DB[1]:g} dB per segment, fading "
    f"{ctx.FADING_DB:g} dB per epoch; {ctx.LOS_MULTIPATH_PROBABILITY:.0%} of segments are "
    f"line-of-sight multipath, {ctx.LOS_LOSS_DB[0]:g}-{ctx.LOS_LOSS_DB[1]:g} dB: C/N0 stays "
    "normal while the bias acts), then the jammer on every row through ``J/S`` "
    "(``1/(C/N0)_eff = 1/(C/N0) + (J/S)/(Q R_c)``, Q = 2; Kaplan & Hegarty 2006, ch. 9), v2's "
    "``jam_sigma`` mapped to the J/S that raises the code noise at 45 deg by v2's variance "
    "(``context.jammer_to_signal_db``: 10-40 m is about 26-37 dB). The row's noise sigma is the "
    "non-coherent DLL thermal jitter at that C/N0 (B_L = 1 Hz, d = 1 chip, T = 20 ms; Kaplan & "
    "Hegarty 2006, ch. 5), scaled so that 45 deg open sky gives ``sigma_pr`` (5 m): "
    "``sigma^2 ∝ u (1 + 100 u)``, ``u = 10^(-C/N0/10)``, the SIGMA-epsilon law of Hartinger & "
    "Brunner 1999 at high C/N0; v2's impulsive ratio, multipath bias and outliers stay, v2's "
    "fixed canyon, jamming and multipath sigmas are replaced (the filter's R stays nominal). "
    "The IMU (10 Hz; Groves 2013, ch. 4) senses the track's along-track and centripetal "
    f"acceleration, gravity, a road vibration of {ctx.BASE_VIBRATION:g} m/s^2 per axis and, in a "
    "manoeuvre burst of v2's ``velocity_sigma`` b, a manoeuvre/vibration of "
    f"b / {ctx.MANOEUVRE_COUPLING:g} m/s^2 per axis (0.4-4 m/s^2: the INS's unmodelled error is "
    f"{ctx.MANOEUVRE_COUPLING:.0%} of it, scale-factor and misalignment), angular vibration of that "
    f"over {ctx.V_TURN:g} m/s, accelerometer / gyro noise {ctx.ACCEL_NOISE:g} m/s^2, "
    f"{ctx.GYRO_NOISE:g} rad/s. Features: ``row_cn0`` (m_max) [dB-Hz] in [0, 60], the reported "
    "C/N0 (1 dB estimator noise, 1 dB-Hz resolution), 0 on rows not received; ``row_elevation`` "
    "(m_max) [deg] in [0, 90] from the estimated position, 0 likewise; ``row_reported_sigma`` "
    "(m_max) [m] in [0, 100], the receiver's sigma from its reported C/N0 (the same jitter law; "
    "blind to multipath bias), 0 likewise; ``imu_activity`` [m/s^2] in [0, 10], the standard "
    "deviation of the specific-force magnitude over the last 1 s (about 0.05 outside bursts, "
    "0.3-4 inside); ``imu_force_mean`` [m/s^2] in [0, 30], ``imu_rate_mean`` and "
    "``imu_rate_spread`` [rad/s] in [0, 2], the window's mean |f|, mean and spread of |w|. "
    "``cn0_offset_db`` [dB] in [-10, 10] (default 0; v3 ids only) models a receiver other than "
    "the one trained on: it reports ``round(C/N0 + cn0_offset_db + n)`` per row, so "
    "``row_cn0`` shifts by the offset (clipped into its bounds; rows not received stay 0, and a "
    "row whose report is not above 0 reads as not received) and ``row_reported_sigma`` follows "
    "it (a higher report, a smaller sigma), while the true C/N0, the rows' noise and the episodes "
    "stay the same (no extra random draws). "
    "Values are clipped into their bounds; the episodes take about 2 kB per step and episode."
)

GPS_INS_V3_CARD = with_paragraph(GPS_INS_CARD, CONTEXT_TEXT)


class GpsInsEnv(PlatformEnv, spec=GPS_INS_V3):  # noqa: D101 - the card is GPS_INS_V3_CARD
    __doc__ = GPS_INS_V3_CARD


class GpsInsVectorEnv(PlatformVectorEnv, spec=GPS_INS_V3):
    """Native batched GpsIns v3 environment (see :class:`GpsInsEnv` for the card)."""
