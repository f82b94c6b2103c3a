"""Pedestrian v3 environments: the v2 episodes with context (:data:`PEDESTRIAN_V3`).

The v3 variant runs the Pedestrian platform on the v2 scenario defaults (the same events) with
``PedestrianPlatform(true_noise=True, context=True)``: the GPS/GLONASS fix's noise follows the
receiver's satellites, HDOP and C/N0 (:mod:`navgym.pedestrian.context`), and the observation
gains what a real receiver and a foot IMU's stance detector report besides the filter's own
statistics: the fix's mean C/N0 and accuracy estimate per row, the satellites used and HDOP,
and the SHOE statistic and specific-force spread of the stance window. Ids are not registered
here (not in :mod:`navgym.pedestrian.env_ids`); build cores with
``PEDESTRIAN_V3.core(task, num_envs, kwargs)``.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs.cards import with_paragraph
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.gnss.receiver_report import cn0_offset_argument
from navgym.pedestrian.env import PEDESTRIAN_CARD, PEDESTRIAN_V2, TASK_SCENARIOS_V2, V2_EVENTS, build_platform
from navgym.pedestrian.platform import PedestrianPlatform


def build_platform_v3(a: PlatformArgs) -> PedestrianPlatform:
    """:func:`~navgym.pedestrian.env.build_platform` with the context (``context=True``).

    ``cn0_offset_db`` (:data:`V3_PLATFORM_KWARGS`) shifts the receiver's C/N0 report
    (:mod:`navgym.gnss.receiver_report`); it lies in ``[-CN0_OFFSET_MAX_DB, CN0_OFFSET_MAX_DB]``.
    """
    return replace(build_platform(a), context=True, cn0_offset_db=cn0_offset_argument(a.kwargs))


#: Tasks of the v3 variant: v2's and RowScale (one R multiplier per row and a process-noise scale).
TASK_SCENARIOS_V3 = {
    **TASK_SCENARIOS_V2,
    "rowscale": dict(V2_EVENTS),
}

#: Pedestrian's own keyword arguments of the v3 ids: v2's and the report's C/N0 offset ``cn0_offset_db``.
V3_PLATFORM_KWARGS: tuple[str, ...] = (*(PEDESTRIAN_V2.platform_arguments or ()), "cn0_offset_db")

#: Pedestrian's v2 declaration with the context switched on (and ``cn0_offset_db``).
PEDESTRIAN_V3: PlatformSpec = replace(
    PEDESTRIAN_V2, build=build_platform_v3, tasks=TASK_SCENARIOS_V3, platform_arguments=V3_PLATFORM_KWARGS
)

CONTEXT_TEXT = (
    "**Context (v3)** (:mod:`navgym.pedestrian.context`, ``context=True``): simulated sensors, "
    "caused by the scenario's events through physics and with their own randomness, never by "
    "labels or truth. The GPS/GLONASS receiver (body-worn, in a street) sees a slowly varying "
    "number of satellites (6-12 per episode, +-1.5 over minutes, at least 5, 12 channels), capped "
    "by an urban canyon (none in an outage); ``HDOP = k_geo / sqrt(n_sv - 3)`` with ``k_geo`` "
    "uniform in 2-3 per episode (a street's one-sided sky; Kaplan & Hegarty 2006, 7.1), VDOP = "
    "1.5 HDOP; per-satellite C/N0 from elevation (15-90 deg: 28-45 dB-Hz, a small body-worn "
    "antenna, ``navgym.gnss.signal_quality.nominal_cn0_dbhz``) with a 2 dB offset per satellite "
    "(antenna pattern, body shadowing), lowered by a canyon's diffraction loss "
    "``20 log10(noise_scale)`` dB (6-14 dB) and by NLOS multipath segments (4-12 dB, fading "
    "2 dB per epoch; 30 % of segments are line-of-sight multipath, 0-1 dB: C/N0 stays normal "
    "while the bias acts), then by the jammer through ``J/S`` (``effective_cn0_dbhz``, Q = 2; "
    "v2's jamming of ``jam_sigma`` maps to ``J/S = Q R_c / C/N0_ref (jam_sigma / 5 m)^2``, "
    "40.7 dB at 30 m, so that the variance at 38 dB-Hz grows as v2's). The fix noise per row is "
    "``HDOP sigma_nom sqrt(u)``, ``u`` the mean SIGMA-epsilon variance ``10^(-(C/N0 - 38)/10)`` "
    "of the satellites used (Hartinger & Brunner 1999), ``sigma_nom`` the nominal 5, 5, 7.5 m; "
    "v2's impulsive ratio, multipath bias and noise and outliers are added. Features: "
    "``row_cn0`` (6 rows) [dB-Hz] in [0, 60], the mean reported C/N0 (1 dB estimator noise, "
    "1 dB-Hz resolution) of the fix on its rows 0-2, 0 on the ZUPT rows and where no fix "
    "arrived; ``row_reported_sigma`` (6) [m] in [0, 100], the receiver's own accuracy estimate "
    "``HDOP sigma_nom sqrt(u_rep)`` from the reported C/N0, blind to multipath bias, 0 likewise; "
    "``gnss_n_sv`` in [0, 12] and ``gnss_hdop`` in [0, 20], the last fix's report held, with "
    "``gnss_report_age`` [s] in [0, 60]. From the simulated foot IMU samples (truth, biases, "
    "white noise and v2's shocks: the shocks are measured by the accelerometer and gyro, so they "
    "show here) of the stance window before each epoch (the stride's last 20 samples, 0.2 s at "
    "100 Hz, the foot at rest): ``stance_statistic`` [log10] in [-1, 8], ``log10`` of the SHOE "
    "stance detector's statistic ``1/W sum_j (|f_j - g f_bar/|f_bar||^2 / sigma_a^2 + "
    "|omega_j|^2 / sigma_w^2)`` (Skog et al. 2010, IEEE TBME; ``sigma_a``, ``sigma_w`` the "
    "grade's per-sample noise, 6.9e-3 m/s^2 and 6.6e-4 rad/s), about 1-2 for a still foot "
    "(the gyro's turn-on bias counts), 3.5-5 in a shock; ``imu_activity`` [m/s^2] in [0, 20], "
    "the standard deviation of the specific-force magnitude over the window, about 0.007 for a "
    "still foot and 0.2-1.0 in a shock (Groves 2013, 4.4: noise density to per-sample sigma). "
    "Both are 0 at the first epoch. ``cn0_offset_db`` [dB] in [-10, 10] (default 0; v3 ids only) "
    "models a receiver other than the one trained on: it reports "
    "``round(C/N0 + cn0_offset_db + n)`` per satellite, so ``row_cn0`` "
    "shifts by the offset (clipped into its bounds; rows not delivered stay 0) and "
    "``row_reported_sigma`` follows it (a higher report, a smaller sigma), while the true C/N0, the "
    "fix noise and the episodes stay the same (no extra random draws). "
    "Values are clipped into their bounds. RowScale's "
    "process-noise scale acts on position, velocity and attitude (``process_noise_states`` "
    "0-8), where the accelerometer's and the gyro's noise, and a shock's, enter ``Q``. "
    "``PedestrianNoiseScale-v3`` (the NoiseScale task with ``motion_q=True``: ``s_q`` on those "
    "states only, ``s_r`` on every row, both 0.1 to 1e4) is the one v3 NoiseScale id: its regime "
    "oracle beats the best tuned NoiseScale baseline (the constant ``s_q = 1e4, s_r = 100``) by "
    "40.3 % [33.2, 47.7] on 256 held-out episodes (gate G1); the GpsIns, Quadrotor and Robot2d "
    "variants miss the gate and are not registered (``experiments/knob_reach``)."
)

PEDESTRIAN_V3_CARD = with_paragraph(PEDESTRIAN_CARD, CONTEXT_TEXT)


class PedestrianEnv(PlatformEnv, spec=PEDESTRIAN_V3):  # noqa: D101 - the card is PEDESTRIAN_V3_CARD
    __doc__ = PEDESTRIAN_V3_CARD


class PedestrianVectorEnv(PlatformVectorEnv, spec=PEDESTRIAN_V3):
    """Native batched Pedestrian v3 environment (see :class:`PedestrianEnv` for the card)."""
