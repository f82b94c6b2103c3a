"""Quadrotor v3 environments: the v2 episodes with context (:data:`QUADROTOR_V3`).

The v3 variant runs the Quadrotor platform on the v2 scenario defaults (the same events) with
``QuadrotorPlatform(true_noise=True, bias_features=True, context=True)``: the GNSS fix's noise
follows the receiver's satellites, HDOP and C/N0 (:mod:`navgym.quadrotor.context`), and the
observation gains what a real receiver and IMU report besides the filter's own statistics: the
fix's mean C/N0 and accuracy estimate per row, the satellites used and HDOP, and the window
statistics of the 200 Hz IMU samples. Ids are registered centrally (not in
:mod:`navgym.quadrotor.env_ids` yet); build cores with ``QUADROTOR_V3.core(task, num_envs, kwargs)``.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs.cards import with_paragraph
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.gnss.receiver_report import cn0_offset_argument
from navgym.quadrotor.env import QUADROTOR_CARD, TASK_SCENARIOS_V2, V2_EVENTS
from navgym.quadrotor.env_v2 import QUADROTOR_V2, build_platform_v2
from navgym.quadrotor.platform import QuadrotorPlatform


def build_platform_v3(a: PlatformArgs) -> QuadrotorPlatform:
    """:func:`~navgym.quadrotor.env_v2.build_platform_v2` with the context (``context=True``).

    ``cn0_offset_db`` (:data:`V3_PLATFORM_KWARGS`) shifts the receiver's C/N0 report
    (:mod:`navgym.gnss.receiver_report`); it lies in ``[-CN0_OFFSET_MAX_DB, CN0_OFFSET_MAX_DB]``.
    """
    return replace(build_platform_v2(a), context=True, cn0_offset_db=cn0_offset_argument(a.kwargs))


#: Tasks of the v3 variant: v2's and RowScale (one R multiplier per row and a process-noise scale).
TASK_SCENARIOS_V3 = {
    **TASK_SCENARIOS_V2,
    "rowscale": dict(V2_EVENTS),
}

#: Quadrotor's own keyword arguments of the v3 ids: v2's and the report's C/N0 offset ``cn0_offset_db``.
V3_PLATFORM_KWARGS: tuple[str, ...] = (*(QUADROTOR_V2.platform_arguments or ()), "cn0_offset_db")

#: Quadrotor's v2 declaration with the context switched on (and ``cn0_offset_db``).
QUADROTOR_V3: PlatformSpec = replace(
    QUADROTOR_V2, build=build_platform_v3, tasks=TASK_SCENARIOS_V3, platform_arguments=V3_PLATFORM_KWARGS
)

CONTEXT_TEXT = (
    "**Context (v3)** (:mod:`navgym.quadrotor.context`, ``context=True``): simulated sensors, caused "
    "by the scenario's events through physics and with their own randomness, never by labels or "
    "truth. The GNSS receiver sees a slowly varying number of satellites (7-12 per episode, +-1.5 "
    "over minutes, at least 5, 12 channels), capped by an urban canyon (none in an outage); "
    "``HDOP = k_geo / sqrt(n_sv - 3)`` with ``k_geo`` uniform in 1.5-2.5 per episode, VDOP = 1.5 "
    "HDOP (Kaplan & Hegarty 2006, 7.1); per-satellite C/N0 from elevation (32-48 dB-Hz, "
    "``navgym.gnss.signal_quality.nominal_cn0_dbhz``) with a 1.5 dB offset per satellite, lowered "
    "by a canyon's diffraction loss ``20 log10(noise_scale)`` dB (6-14 dB) and by NLOS multipath "
    "segments (4-12 dB, fading 2 dB per epoch; 30 % of segments are line-of-sight multipath, "
    "0-1 dB: C/N0 stays normal while the bias acts), then by the jammer through ``J/S`` "
    "(``effective_cn0_dbhz``, Q = 2; v2's jamming of ``jam_sigma`` maps to "
    "``J/S = Q R_c / C/N0_ref (jam_sigma / sigma_pos)^2``, 44.6 dB at 30 m, so that the variance "
    "at 42 dB-Hz grows as v2's). The fix noise per row is ``HDOP sigma_nom sqrt(u)``, ``u`` the "
    "mean SIGMA-epsilon variance ``10^(-(C/N0 - 42)/10)`` of the satellites used (Hartinger & "
    "Brunner 1999; the Doppler velocity by the same 1/(C/N0) law of the FLL jitter, Kaplan & "
    "Hegarty 2006, ch. 5), ``sigma_nom`` the nominal 2, 2, 3 m and 0.1, 0.1, 0.15 m/s; v2's "
    "multipath bias and noise and outliers are added. Features: ``row_cn0`` (6 rows) [dB-Hz] in "
    "[0, 60], the mean reported C/N0 (1 dB estimator noise, 1 dB-Hz resolution) of the fix on "
    "each of its rows, 0 where no fix arrived; ``row_reported_sigma`` (6) [m, m/s] in [0, 100], "
    "the receiver's own accuracy estimate ``HDOP sigma_nom sqrt(u_rep)`` from the reported C/N0, "
    "blind to multipath bias, 0 likewise; ``gnss_n_sv`` in [0, 12] and ``gnss_hdop`` in [0, 20], "
    "the last fix's report held, with ``gnss_report_age`` [s] in [0, 60]. From the simulated "
    "200 Hz IMU samples (truth, bias, white noise and v2's vibration: the bursts are measured by "
    "the accelerometer and gyro, so they show here) over the last 1 s: ``imu_activity`` "
    "[m/s^2] in [0, 20], the RMS deviation of the specific-force vector from its window mean "
    "(about 0.02 m/s^2 for the consumer grade's 70 ug/sqrt(Hz), a few 0.01 more in manoeuvres, "
    "1.2-7.3 m/s^2 in a burst of 0.05-0.3 m/s/sqrt(s); Groves 2013, 4.4); ``imu_gyro_activity`` "
    "[rad/s] in [0, 2], the same of the angular rate (1.6e-3 nominal, 0.02-0.12 in a burst, up "
    "to 0.13 in a yaw turn); "
    "``imu_specific_force`` (3) [m/s^2] in [-40, 40] and ``imu_angular_rate`` (3) [rad/s] in "
    "[-5, 5], the window means (body axes). ``cn0_offset_db`` [dB] in [-10, 10] (default 0; v3 "
    "ids only) models a receiver other than the one trained on: it reports "
    "``round(C/N0 + cn0_offset_db + n)`` per satellite, so ``row_cn0`` "
    "shifts by the offset (clipped into its bounds; rows not delivered stay 0) and "
    "``row_reported_sigma`` follows it (a higher report, a smaller sigma), while the true C/N0, the "
    "fix noise and the episodes stay the same (no extra random draws). "
    "Values are clipped into their bounds. RowScale's "
    "process-noise scale acts on position and velocity (``process_noise_states`` 0-5), where the "
    "accelerometer's noise enters ``Q``."
)

QUADROTOR_V3_CARD = with_paragraph(QUADROTOR_CARD, CONTEXT_TEXT)


class QuadrotorEnv(PlatformEnv, spec=QUADROTOR_V3):  # noqa: D101 - the card is QUADROTOR_V3_CARD
    __doc__ = QUADROTOR_V3_CARD


class QuadrotorVectorEnv(PlatformVectorEnv, spec=QUADROTOR_V3):
    """Native batched Quadrotor v3 environment (see :class:`QuadrotorEnv` for the card)."""
