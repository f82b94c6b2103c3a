"""Robot2d's v3 context: what the GNSS receivers and a gyro report besides the filter's statistics.

Every number here is produced by a simulated sensor from the physics of the episode (its
satellites, the scenario's canyons, jammers and multipath segments, the robot's true yaw rate),
with randomness from the episode's own generator; no scenario label or truth reaches a feature
except through these sensors. Two receivers (GPS, GLONASS) each run one chain per epoch ``k``:

1. **Visible satellites.** Per episode and receiver a base count ``n_0`` (GPS uniform in
   :data:`GPS_VISIBLE`, GLONASS in :data:`GLONASS_VISIBLE`) varies slowly,
   ``n_vis(t) = clip(round(n_0 + A sin(2 pi t / P + phi)), MIN_VISIBLE, N_CHANNELS)`` with
   ``A ~ U(0, 1.5)``, ``P ~ U(120, 600)`` s, ``phi ~ U(0, 2 pi)``. The satellites used are
   ``n_sv = min(n_vis, cap)``, the cap the scenario's sky blockage allows
   (:func:`navgym.scenarios.max_satellites`: 0 in an outage, the urban canyon's or partial outage's
   count, the same for both receivers). Since ``n_vis >= MIN_VISIBLE = 5``, a fix exists exactly
   where v2's ``cap >= 4`` allows one.
2. **HDOP** ``= k_geo / sqrt(n_sv - 3)``, ``k_geo`` per episode and receiver uniform in
   :data:`HDOP_K` (``(G^T G)^-1`` of n well spread lines of sight shrinks like ``1 / (n - 3)``
   once the four unknowns are fixed; the factor is the geometry's luck; Kaplan & Hegarty 2006,
   ch. 7.1, DOP). Satellites are used by decreasing elevation, so a canyon keeps the highest.
3. **Per-satellite C/N0.** Elevations per episode (``sin el ~ U(sin 10 deg, 1)``, sorted down),
   open-sky ``C/N0_i = nominal_cn0_dbhz(el_i) + o_i`` (:mod:`navgym.gnss.signal_quality`; a fixed
   antenna/pattern offset ``o_i ~ N(0, 1.5 dB)`` per satellite), minus the attenuation ``A(k)`` of
   the receiver, then the jammer: ``effective_cn0_dbhz(C/N0_i - A, J/S)`` (Kaplan & Hegarty 2006,
   ch. 9, ``Q = 2``). ``A(k)`` is the canyon's diffraction loss ``20 log10(noise_scale)`` dB (the
   v2 canyon's noise factor as a signal loss: 6-14 dB for 2-5) plus the NLOS loss of the active
   multipath segments of the receiver's rows (the largest), plus epoch-to-epoch fading
   ``N(0, 2 dB)`` wherever the loss is positive, never below 0. Each multipath segment is, with
   probability :data:`LOS_MULTIPATH_PROBABILITY`, line-of-sight multipath (loss ``U(0, 1)`` dB:
   C/N0 stays nearly normal, the bias is still there), else NLOS (loss ``U(4, 12)`` dB).
4. **Jamming as J/S.** The v2 jamming regime's ``jam_sigma`` [m] (ramped) is the jammer's
   strength; it maps to ``J/S = Q R_c / (C/N0_ref) (jam_sigma / JAM_REF_M)^2`` (linear), which
   at ``C/N0_ref`` multiplies the code-noise variance by ``1 + (jam_sigma / 3 m)^2``: v2's
   ``3^2 + jam_sigma^2`` for a 3 m receiver. 30 m of v2 jamming is ``J/S = 38`` dB.
5. **Fix noise** per axis: ``sigma = HDOP sigma_UERE`` with ``sigma_UERE^2`` the mean over the
   satellites used of the SIGMA-epsilon variance ``C_i 10^(-C/N0_i / 10)`` (Hartinger & Brunner
   1999; :func:`navgym.gnss.signal_quality.sigma_epsilon_variance`, the large-C/N0 limit of the
   DLL jitter), ``C_i = sigma_v2^2 10^(CN0_REF / 10)`` so that ``HDOP = 1`` with every satellite
   at :data:`CN0_REF_DBHZ` gives the v2 sensor sigma (3 m GPS, 5 m GLONASS). The platform adds
   v2's multipath bias and noise and the impulsive-noise ratio on top.
6. **The receiver's report**: ``n_sv``, ``HDOP``, the mean over the satellites used of the
   reported C/N0 (:func:`~navgym.gnss.signal_quality.reported_cn0_dbhz`, 1 dB estimator noise,
   1 dB-Hz resolution) and its accuracy estimate ``HDOP sqrt(mean C_i 10^(-C/N0_rep,i / 10))``
   [m per axis]: it does not see a multipath bias, the multipath noise or an impulsive outlier.
   ``cn0_offset_db`` (the v3 ids' keyword argument; :mod:`navgym.gnss.receiver_report`) models
   another receiver's calibration: each satellite's report is ``round(C/N0_i + cn0_offset_db +
   n_i)``, and the accuracy estimate follows it; the true C/N0 and the fix noise do not change.

The **gyro** (z axis, MEMS; Groves 2013, ch. 4.4.6 and Table 4.1, figures of a Bosch BMI088's
datasheet): ``omega_g,k = (phi_{k+1} - phi_k) / dt + b_k + n_k``, the true mean yaw rate over the
step (the slip bursts' extra yaw included), white noise ``n_k ~ N(0, N^2 / dt)`` with the noise
density ``N = 0.014 deg/s/sqrt(Hz)``, the bias ``b_0 ~ N(0, 0.1 deg/s)`` (a zero-rate offset left
after calibration at standstill) walking ``b_{k+1} = b_k + K sqrt(dt) w_k`` with
``K = 0.001 deg/s/sqrt(s)``. The **odometry yaw rate** is the kinematic model's (Benzerrouk
2014, eq. 77) from the measured encoder speed and steering angle, ``omega_o = v_c tan(alpha) / L``,
``v_c = v_e / (1 - H tan(alpha) / L)``, and the **odometry-IMU consistency** is the RMS of
``omega_o - omega_g`` over the last second (the steps that ended by epoch k; 0 at the start): a
few hundredths of a rad/s on firm ground, more under wheel slip.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.envs.features import Feature
from navgym.envs.rows import epoch_index
from navgym.gnss import receiver_report
from navgym.gnss.receiver_report import active_segments, hdop, held
from navgym.gnss.signal_quality import (
    effective_cn0_dbhz,
    nominal_cn0_dbhz,
    reported_cn0_dbhz,
    sigma_epsilon_variance,
)
from navgym.robot2d.robot import RobotGeometry
from navgym.scenarios import ScenarioBatch, canyon_regime, max_satellites, noise_regime

__all__ = [
    "CONTEXT_FEATURES",
    "context_feature_values",
    "gyro_consistency",
    "N_CHANNELS",
    "CN0_REF_DBHZ",
    "JAM_REF_M",
    "Robot2dContext",
    "ReceiverPhysics",
    "receiver_physics",
    "jammer_to_signal_db",
    "hdop",
    "gyro_rates",
    "odometry_yaw_rate",
    "windowed_rms",
    "context_reports",
]

#: Receiver channels (satellites at most per receiver).
N_CHANNELS = 12
#: Fewest visible satellites of a receiver in open sky (>= 5: a fix wherever v2 has one).
MIN_VISIBLE = 5
#: Range of the per-episode base count of visible GPS / GLONASS satellites.
GPS_VISIBLE = (7, 12)
GLONASS_VISIBLE = (5, 10)
#: Range of the per-episode geometry factor ``k_geo`` of ``HDOP = k_geo / sqrt(n_sv - 3)``.
HDOP_K = (1.5, 2.5)
#: C/N0 [dB-Hz] at which the SIGMA-epsilon model gives the v2 sensor sigma (with HDOP = 1).
CN0_REF_DBHZ = 42.0
#: Jamming of this v2 noise [m] doubles the code-noise variance at ``CN0_REF_DBHZ``.
JAM_REF_M = 3.0
#: Spectral-separation factor of the jammer (broad-band noise; Kaplan & Hegarty 2006, ch. 9).
JAMMER_Q = 2.0
#: Probability that a multipath segment is line-of-sight multipath (C/N0 nearly normal).
LOS_MULTIPATH_PROBABILITY = 0.3
#: NLOS loss range [dB], line-of-sight multipath loss range [dB], epoch fading sigma [dB].
NLOS_LOSS_DB = (4.0, 12.0)
LOS_LOSS_DB = (0.0, 1.0)
FADING_DB = 2.0
#: Per-satellite antenna/pattern offset sigma [dB]; receiver C/N0 estimator sigma [dB].
SAT_OFFSET_DB = 1.5
CN0_ESTIMATOR_DB = 1.0
#: MEMS gyro (BMI088 datasheet; Groves 2013 Table 4.1): noise density [rad/s/sqrt(Hz)], initial
#: bias sigma [rad/s], bias random walk [rad/s/sqrt(s)].
GYRO_NOISE_DENSITY = np.deg2rad(0.014)
GYRO_BIAS_SIGMA = np.deg2rad(0.1)
GYRO_BIAS_WALK = np.deg2rad(0.001)
#: Window of the odometry-IMU consistency [s].
CONSISTENCY_WINDOW_S = 1.0


class Robot2dContext(NamedTuple):
    """The v3 context of B episodes per epoch ``k`` (``(B, T+1, ...)``), all sensor-side.

    Attributes:
        n_sv: Satellites used by GPS / GLONASS, the last report held ``(B, T+1, 2)``.
        hdop: Their HDOP, the last report held ``(B, T+1, 2)``.
        report_age: Age of the held report [s] ``(B, T+1, 2)`` (0 at a delivered fix).
        row_cn0: Mean reported C/N0 [dB-Hz] of the row's receiver ``(B, T+1, 5)``, 0 on rows
            not delivered at k (and on the compass).
        row_sigma: The receiver's reported accuracy [m per axis] ``(B, T+1, 5)``, 0 likewise.
        imu_activity: RMS of odometry minus gyro yaw rate over the last second [rad/s] ``(B, T+1)``.

    """

    n_sv: NDArray[np.float64]
    hdop: NDArray[np.float64]
    report_age: NDArray[np.float64]
    row_cn0: NDArray[np.float64]
    row_sigma: NDArray[np.float64]
    imu_activity: NDArray[np.float64]


class ReceiverPhysics(NamedTuple):
    """One chain per receiver and epoch (``(B, T+1, 2)``: GPS, GLONASS) before the delivery mask.

    Attributes:
        n_sv: Satellites used (0 in an outage).
        hdop: HDOP (``inf`` below 4 satellites).
        cn0_true: Mean effective C/N0 of the satellites used [dB-Hz] (NaN without satellites).
        cn0_reported: Mean reported C/N0 of the satellites used [dB-Hz] (NaN likewise).
        fix_var: Fix noise variance per axis ``(HDOP sigma_UERE)^2`` [m^2].
        reported_sigma: The receiver's accuracy estimate [m per axis].

    """

    n_sv: NDArray[np.float64]
    hdop: NDArray[np.float64]
    cn0_true: NDArray[np.float64]
    cn0_reported: NDArray[np.float64]
    fix_var: NDArray[np.float64]
    reported_sigma: NDArray[np.float64]


def jammer_to_signal_db(jam_sigma: NDArray) -> NDArray[np.float64]:
    """``J/S`` [dB] of v2's jamming noise ``jam_sigma`` [m] (module docstring, step 4); -inf at 0.

    :func:`navgym.gnss.receiver_report.jammer_to_signal_db` at Robot2d's reference figures.
    """
    return receiver_report.jammer_to_signal_db(jam_sigma, JAM_REF_M, CN0_REF_DBHZ, JAMMER_Q)


def receiver_physics(
    seeds: NDArray,
    batch: ScenarioBatch,
    tt: NDArray,
    sigma_nominal: tuple[float, float],
    cn0_offset_db: float = 0.0,
) -> ReceiverPhysics:
    """The receivers' chain (module docstring, steps 1-6) of B episodes at times ``tt (B, T+1)``.

    Each episode draws from ``np.random.default_rng([seed, 2])`` of its misc seed (its other
    generators are untouched): the per-episode constants first, then the per-epoch normals,
    then two uniforms per multipath segment it has (so a batch equals its single episodes).

    Args:
        seeds: The episodes' misc seeds ``(B,)``.
        batch: The episodes' scenarios.
        tt: Epoch times [s] ``(B, T+1)``.
        sigma_nominal: v2 sensor sigma per axis of GPS and GLONASS [m].
        cn0_offset_db: Calibration offset [dB] of both receivers' C/N0 reports (module
            docstring, step 6): it shifts the reported C/N0 and accuracy, not the true C/N0 or
            the fix noise; no extra draws.

    """
    B, n = tt.shape
    c = N_CHANNELS
    k_geo, n0, amp, period, phase = (np.empty((B, 2)) for _ in range(5))
    sin_el, offset = np.empty((B, 2, c)), np.empty((B, 2, c))
    est, fade = np.empty((B, n, 2, c)), np.empty((B, n, 2))
    seg_los = np.zeros(batch.multipath_start.shape, bool)
    seg_loss = np.zeros(batch.multipath_start.shape)
    for i in range(B):
        g = np.random.default_rng([int(seeds[i]), 2])
        k_geo[i] = g.uniform(*HDOP_K, size=2)
        n0[i] = [
            g.integers(GPS_VISIBLE[0], GPS_VISIBLE[1] + 1),
            g.integers(GLONASS_VISIBLE[0], GLONASS_VISIBLE[1] + 1),
        ]
        amp[i], period[i], phase[i] = g.uniform(0, 1.5, 2), g.uniform(120, 600, 2), g.uniform(0, 2 * np.pi, 2)
        sin_el[i] = -np.sort(-g.uniform(np.sin(np.deg2rad(10.0)), 1.0, (2, c)), axis=1)
        offset[i] = g.standard_normal((2, c)) * SAT_OFFSET_DB
        est[i] = g.standard_normal((n, 2, c))
        fade[i] = g.standard_normal((n, 2))
        j = np.flatnonzero(np.isfinite(batch.multipath_start[i]))
        los = g.random(j.size) < LOS_MULTIPATH_PROBABILITY
        u = g.random(j.size)
        seg_los[i, j] = los
        seg_loss[i, j] = np.where(
            los, LOS_LOSS_DB[0] + u * np.diff(LOS_LOSS_DB), NLOS_LOSS_DB[0] + u * np.diff(NLOS_LOSS_DB)
        )
    # 1. satellites
    wave = amp[:, None, :] * np.sin(2 * np.pi * tt[..., None] / period[:, None, :] + phase[:, None, :])
    n_vis = np.clip(np.round(n0[:, None, :] + wave), MIN_VISIBLE, c)
    cap = max_satellites(batch, tt).astype(np.float64)
    n_sv = np.minimum(n_vis, cap[..., None])
    used = np.arange(c) < n_sv[..., None]  # (B, n, 2, c): the highest n_sv
    dop = hdop(n_sv, k_geo[:, None, :])
    # 3. attenuation: canyon diffraction + the receiver's NLOS segments, with fading
    scale, _ = canyon_regime(batch, tt)
    loss = np.repeat((20.0 * np.log10(scale))[..., None], 2, axis=-1)
    if np.isfinite(batch.multipath_start).any():
        a = active_segments(batch.multipath_start, batch.multipath_end, tt)  # (B, n, K)
        rx = batch.multipath_row[:, None, :] // 2  # GPS rows 0, 1; GLONASS rows 2, 3
        for r in range(2):
            hit = a & (rx == r)
            loss[..., r] += np.where(hit, seg_loss[:, None, :], 0.0).max(axis=-1)
    loss = np.where(loss > 0, np.maximum(loss + FADING_DB * fade, 0.0), 0.0)
    el = np.arcsin(sin_el)
    open_sky = nominal_cn0_dbhz(el) + offset  # (B, 2, c)
    js = jammer_to_signal_db(noise_regime(batch, tt).jam_sigma)  # (B, n)
    cn0 = effective_cn0_dbhz(open_sky[:, None] - loss[..., None], js[:, :, None, None], q=JAMMER_Q)
    rep = reported_cn0_dbhz(cn0 + cn0_offset_db, est, CN0_ESTIMATOR_DB, 1.0)
    # 5. fix noise and the receiver's estimate
    ci = (np.asarray(sigma_nominal, np.float64) ** 2 * 10.0 ** (CN0_REF_DBHZ / 10.0))[:, None]  # (2, 1)
    cnt = np.maximum(n_sv, 1.0)
    with np.errstate(invalid="ignore"):
        uere2 = np.where(used, sigma_epsilon_variance(cn0, 1.0) * ci, 0.0).sum(-1) / cnt
        rep2 = np.where(used, sigma_epsilon_variance(rep, 1.0) * ci, 0.0).sum(-1) / cnt
        none = n_sv < 1
        cn0_mean = np.where(none, np.nan, np.where(used, cn0, 0.0).sum(-1) / cnt)
        rep_mean = np.where(none, np.nan, np.where(used, rep, 0.0).sum(-1) / cnt)
        fin = np.isfinite(dop)
        fix_var = np.where(fin, np.where(fin, dop, 0.0) ** 2 * uere2, np.inf)
        rep_sigma = np.where(fin, np.where(fin, dop, 0.0) * np.sqrt(rep2), np.inf)
    return ReceiverPhysics(n_sv, dop, cn0_mean, rep_mean, fix_var, rep_sigma)


def odometry_yaw_rate(encoder: NDArray, steering: NDArray, geometry: RobotGeometry) -> NDArray[np.float64]:
    """``omega_o = v_c tan(alpha) / L``, ``v_c = v_e / (1 - H tan(alpha) / L)`` (eq. 77) [rad/s]."""
    ta = np.tan(steering)
    v_c = encoder / (1.0 - geometry.encoder_offset * ta / geometry.wheelbase)
    return v_c * ta / geometry.wheelbase


def gyro_rates(heading: NDArray, seeds: NDArray, dt: float) -> NDArray[np.float64]:
    """Gyro output over each step ``k -> k+1`` (module docstring) ``(B, T)`` [rad/s].

    Normals from ``np.random.default_rng([seed, 3])`` of each episode's misc seed.
    """
    B, n = heading.shape
    draws = np.stack([np.random.default_rng([int(s), 3]).standard_normal(2 * n) for s in seeds])
    white = draws[:, : n - 1] * (GYRO_NOISE_DENSITY / np.sqrt(dt))
    b0 = draws[:, n - 1 : n] * GYRO_BIAS_SIGMA
    walk = draws[:, n : 2 * n - 2] * (GYRO_BIAS_WALK * np.sqrt(dt))
    bias = b0 + np.concatenate([np.zeros((B, 1)), np.cumsum(walk, axis=1)], axis=1)
    return np.diff(heading, axis=1) / dt + bias + white


def windowed_rms(d: NDArray, window: int) -> NDArray[np.float64]:
    """``(B, T+1)``: RMS of ``d (B, T)`` over the steps ``max(0, k - window) .. k - 1``; 0 at k = 0."""
    B, n = d.shape
    c = np.concatenate([np.zeros((B, 1)), np.cumsum(d * d, axis=1)], axis=1)
    k = np.arange(n + 1)
    lo = np.maximum(k - window, 0)
    cnt = np.maximum(k - lo, 1)
    return np.sqrt(np.maximum(c[:, k] - c[:, lo], 0.0) / cnt)


def context_reports(
    phys: ReceiverPhysics,
    delivered: NDArray,
    imu_activity: NDArray,
    dt: float,
) -> Robot2dContext:
    """The features' arrays: reports of delivered fixes, held or zeroed where none (class doc).

    Args:
        phys: The receivers' chain.
        delivered: ``(B, T+1, 2)`` whether GPS / GLONASS delivered a fix at k.
        imu_activity: ``(B, T+1)`` the odometry-IMU consistency.
        dt: Step [s].

    """
    n_sv, dop, age = np.empty_like(phys.n_sv), np.empty_like(phys.hdop), np.empty_like(phys.n_sv)
    for r in range(2):
        n_sv[..., r], age[..., r] = held(phys.n_sv[..., r], delivered[..., r], dt)
        dop[..., r], _ = held(phys.hdop[..., r], delivered[..., r], dt)
    cn0 = np.where(delivered, phys.cn0_reported, 0.0)
    sig = np.where(delivered, phys.reported_sigma, 0.0)
    zero = np.zeros(cn0.shape[:2] + (1,))
    rows = [0, 0, 1, 1]
    return Robot2dContext(
        n_sv,
        dop,
        age,
        np.concatenate([cn0[..., rows], zero], axis=-1),
        np.concatenate([sig[..., rows], zero], axis=-1),
        imu_activity,
    )


def gyro_consistency(
    heading: NDArray,
    encoder: NDArray,
    steering: NDArray,
    seeds: Sequence[int] | NDArray,
    dt: float,
    geometry: RobotGeometry,
) -> NDArray[np.float64]:
    """``(B, T+1)`` odometry-IMU consistency: windowed RMS of ``omega_o - omega_g`` (module docstring)."""
    gyro = gyro_rates(heading, np.asarray(seeds), dt)
    odo = odometry_yaw_rate(encoder[:, :-1], steering[:, :-1], geometry)
    return windowed_rms(odo - gyro, int(round(CONSISTENCY_WINDOW_S / dt)))


#: The v3 context features (each from a simulated sensor; bounds clip, see the card).
CONTEXT_FEATURES = (
    Feature(
        "row_cn0", 0.0, 60.0, "dB-Hz",
        "mean reported C/N0 of the satellites the row's receiver used (GPS N/E, GLONASS N/E; "
        "compass 0); 0 on rows not delivered at this epoch", size=5,
    ),
    Feature(
        "row_reported_sigma", 0.0, 100.0, "m",
        "the receiver's own accuracy estimate per axis, HDOP sqrt(mean C_i 10^(-C/N0_rep/10)) "
        "(blind to multipath bias); 0 on rows not delivered (and the compass)", size=5,
    ),
    Feature("gnss_n_sv", 0.0, float(N_CHANNELS), "satellites",
            "satellites used by GPS, GLONASS; the last fix's report held", size=2),
    Feature("gnss_hdop", 0.0, 20.0, "-",
            "HDOP of GPS, GLONASS (k_geo / sqrt(n_sv - 3)); the last fix's report held", size=2),
    Feature("gnss_report_age", 0.0, 60.0, "s",
            "age of the held GPS, GLONASS report (0 at a delivered fix)", size=2),
    Feature("imu_activity", 0.0, 2.0, "rad/s",
            "RMS over the last 1 s of odometry yaw rate (encoder, steering; eq. 77) minus gyro rate"),
)  # fmt: skip


def context_feature_values(ctx: Robot2dContext, t: NDArray) -> dict[str, NDArray]:
    """The context features of epoch ``t (B,)`` (clipped to the last epoch)."""
    ix = epoch_index(np.minimum(t, ctx.imu_activity.shape[1] - 1))  # views in lock step
    return {
        "row_cn0": ctx.row_cn0[ix],
        "row_reported_sigma": ctx.row_sigma[ix],
        "gnss_n_sv": ctx.n_sv[ix],
        "gnss_hdop": ctx.hdop[ix],
        "gnss_report_age": ctx.report_age[ix],
        "imu_activity": ctx.imu_activity[ix],
    }
