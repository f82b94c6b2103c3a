"""Quadrotor's v3 context: what the GNSS receiver and the IMU report besides the filter's statistics.

Every number is produced by a simulated sensor from the physics of the episode (its satellites,
the scenario's canyons, jammers and multipath segments, the airframe's vibration), with
randomness from the episode's own generators; no scenario label or truth reaches a feature
except through these sensors. The GNSS receiver (one, delivering the six-row position/velocity
fix) runs one chain per epoch ``k``:

1. **Satellites.** A base count ``n_0`` uniform in :data:`VISIBLE` per episode varies slowly,
   ``n_vis(t) = clip(round(n_0 + A sin(2 pi t / P + phi)), MIN_VISIBLE, N_CHANNELS)`` with
   ``A ~ U(0, 1.5)``, ``P ~ U(120, 600)`` s, ``phi ~ U(0, 2 pi)``; the satellites used are
   ``n_sv = min(n_vis, cap)``, ``cap`` 0 in an outage and an urban canyon's count inside one.
   Since ``n_vis >= MIN_VISIBLE = 5`` a fix exists exactly where v2's ``cap >= 4`` allows one.
2. **DOP** ``HDOP = k_geo / sqrt(n_sv - 3)`` (:func:`navgym.gnss.receiver_report.hdop`; Kaplan &
   Hegarty 2006, 7.1), ``k_geo ~ U(HDOP_K)`` per episode; ``VDOP = 1.5 HDOP`` (the platform's
   ``VERTICAL_FACTOR``, already in its nominal down-row sigmas). Satellites are used by
   decreasing elevation (a canyon keeps the highest).
3. **Per-satellite C/N0.** Elevations per episode (``sin el ~ U(sin 10 deg, 1)``, sorted down);
   ``C/N0_i = effective_cn0_dbhz(nominal_cn0_dbhz(el_i) + o_i - A(k), J/S(k))``
   (:mod:`navgym.gnss.signal_quality`; Kaplan & Hegarty 2006, ch. 8-9, ``Q = 2``), with a fixed
   antenna/pattern offset ``o_i ~ N(0, 1.5 dB)`` per satellite. The attenuation ``A(k)`` is a
   canyon's diffraction loss ``20 log10(noise_scale)`` dB (v2's noise factor as a signal loss:
   6-14 dB for 2-5) plus the largest loss of the active multipath segments, plus epoch fading
   ``N(0, 2 dB)`` wherever it is positive (never below 0). A multipath segment is, with
   probability :data:`LOS_MULTIPATH_PROBABILITY`, line-of-sight multipath (loss ``U(0, 1)`` dB:
   C/N0 stays nearly normal while the bias acts), else NLOS (loss ``U(4, 12)`` dB).
4. **Jamming as J/S** (:func:`navgym.gnss.receiver_report.jammer_to_signal_db`): v2's
   ``jam_sigma`` [m] is the jammer's strength, ``J/S = Q R_c / (c/n0)_ref (jam_sigma /
   sigma_pos)^2``, which at ``CN0_REF_DBHZ`` multiplies the code (and Doppler) noise variance by
   ``1 + (jam_sigma / sigma_pos)^2``: v2's ``sigma_pos^2 + jam_sigma^2`` (30 m of v2 jamming on
   the 2 m fix is ``J/S = 44.6`` dB). No loss of lock is modelled: v2's jamming loss stays.
5. **Fix noise** of row ``r``: ``sigma_r = HDOP sigma_nom,r sqrt(u)``, ``u`` the mean over the
   satellites used of the SIGMA-epsilon variance ``10^(-(C/N0_i - C/N0_ref)/10)`` (Hartinger &
   Brunner 1999; :func:`navgym.gnss.receiver_report.uere_variance_factor`), ``sigma_nom`` the
   platform's row sigmas (2, 2, 3 m; 0.1, 0.1, 0.15 m/s: the down rows carry VDOP / HDOP = 1.5),
   so HDOP 1 with every satellite at 42 dB-Hz gives v2's nominal fix. The Doppler velocity follows the same
   ``1 / (c/n0)`` law (the FLL's thermal jitter in its large-C/N0 limit, Kaplan & Hegarty 2006,
   ch. 5). The platform adds v2's impulsive ratio, multipath bias and noise and gross outliers.
6. **The receiver's report**: ``n_sv``, HDOP, the mean over the satellites used of the reported
   C/N0 (:func:`~navgym.gnss.signal_quality.reported_cn0_dbhz`, 1 dB estimator noise, 1 dB-Hz
   resolution) and its accuracy estimate ``HDOP sigma_nom,r sqrt(u_rep)`` with ``u_rep`` from the
   reported C/N0 (as a receiver's hAcc/vAcc/sAcc): blind to a multipath bias, multipath noise and outliers.
   ``cn0_offset_db`` (the v3 id's keyword argument; :mod:`navgym.gnss.receiver_report`) models
   another receiver's calibration: each satellite's report is ``round(C/N0_i + cn0_offset_db +
   n_i)``, and ``u_rep`` follows it; the true C/N0, ``u`` and the fix noise do not change.

The **IMU context** comes from the simulated 200 Hz samples themselves (the compiled kernel's
per-step sums, :data:`navgym.quadrotor.imu_kernel.N_STATS`): measured specific force ``f`` and
angular rate ``omega`` (truth by flatness, plus bias, plus white noise, plus v2's vibration
noise during a burst: the burst is measured by the sensor, so it shows here). Over the samples
of the last :data:`IMU_WINDOW_S` (the steps that ended by epoch k; nothing at k = 0):

* ``imu_activity = sqrt(mean |f|^2 - |mean f|^2)`` [m/s^2], the RMS deviation of the
  specific-force vector from its window mean: about ``sqrt(3) N_a sqrt(f_s)`` = 0.017 m/s^2 for
  the consumer grade's noise density ``N_a`` (70 ug/sqrt(Hz)) at ``f_s = 200`` Hz plus the
  flight's own changes of thrust and tilt within the second (up to some 0.1 m/s^2 in a turn),
  and ``sqrt(3) s sqrt(f_s)`` = 1.2-7.3 m/s^2 in a vibration burst of density ``s`` = 0.05-0.3
  m/s/sqrt(s) (Groves 2013, ch. 4.4: noise density to per-sample sigma);
* ``imu_gyro_activity``, the same of the angular rate [rad/s] (1.6e-3 rad/s nominal, 0.02-0.12
  in a burst of 0.001-0.005 rad/sqrt(s), but up to some 0.13 in a yaw turn: a manoeuvre);
* ``imu_specific_force``, ``imu_angular_rate``: the window means (body x, y, z).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.envs.features import Feature
from navgym.envs.rows import epoch_index
from navgym.gnss import receiver_report
from navgym.gnss.receiver_report import (
    ReceiverModel,
    ReceiverPhysics,
    trailing_sums,
)
from navgym.scenarios import ScenarioBatch

__all__ = [
    "N_CHANNELS",
    "MIN_VISIBLE",
    "VISIBLE",
    "HDOP_K",
    "CN0_REF_DBHZ",
    "JAMMER_Q",
    "LOS_MULTIPATH_PROBABILITY",
    "IMU_WINDOW_S",
    "ReceiverPhysics",
    "QuadrotorContext",
    "receiver_physics",
    "imu_window",
    "context_reports",
    "context_features",
    "context_feature_values",
]

#: Receiver channels (satellites used at most).
N_CHANNELS = 12
#: Fewest visible satellites in open sky (>= 5: a fix wherever v2 has one).
MIN_VISIBLE = 5
#: Range of the per-episode base count of visible satellites.
VISIBLE = (7, 12)
#: Range of the per-episode geometry factor ``k_geo`` of ``HDOP = k_geo / sqrt(n_sv - 3)``.
HDOP_K = (1.5, 2.5)
#: C/N0 [dB-Hz] at which the SIGMA-epsilon model gives the nominal fix sigma (with DOP 1).
CN0_REF_DBHZ = 42.0
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
#: Window of the IMU statistics [s].
IMU_WINDOW_S = 1.0
#: Second argument of the receiver's generator ``default_rng([gnss_seed, RECEIVER_STREAM])``.
RECEIVER_STREAM = 7
#: This platform's receiver (:func:`receiver_physics`).
RECEIVER = ReceiverModel(
    visible=VISIBLE,
    hdop_k=HDOP_K,
    cn0_zenith_dbhz=48.0,
    cn0_horizon_dbhz=32.0,
    min_elevation_deg=10.0,
    cn0_ref_dbhz=CN0_REF_DBHZ,
    sat_offset_db=SAT_OFFSET_DB,
    n_channels=N_CHANNELS,
    min_visible=MIN_VISIBLE,
    jammer_q=JAMMER_Q,
    los_multipath_probability=LOS_MULTIPATH_PROBABILITY,
    nlos_loss_db=NLOS_LOSS_DB,
    los_loss_db=LOS_LOSS_DB,
    fading_db=FADING_DB,
    cn0_estimator_db=CN0_ESTIMATOR_DB,
    stream=RECEIVER_STREAM,
)


class QuadrotorContext(NamedTuple):
    """The v3 context of B episodes per epoch ``k`` (``(B, T+1, ...)``), all sensor-side.

    Attributes:
        n_sv: Satellites used, the last fix's report held ``(B, T+1)``.
        hdop: Its HDOP, held ``(B, T+1)`` (0 before any fix).
        report_age: Age of the held report [s] ``(B, T+1)`` (0 at a delivered fix).
        row_cn0: Mean reported C/N0 [dB-Hz] of the fix, on its six rows ``(B, T+1, 6)``; 0 where
            no fix was delivered at k.
        row_sigma: The receiver's accuracy estimate per row [m, m/s] ``(B, T+1, 6)``, 0 likewise.
        imu_activity: Specific-force spread over the window [m/s^2] ``(B, T+1)``.
        gyro_activity: Angular-rate spread over the window [rad/s] ``(B, T+1)``.
        f_mean: Window mean of the specific force [m/s^2] ``(B, T+1, 3)``.
        w_mean: Window mean of the angular rate [rad/s] ``(B, T+1, 3)``.

    """

    n_sv: NDArray[np.float64]
    hdop: NDArray[np.float64]
    report_age: NDArray[np.float64]
    row_cn0: NDArray[np.float64]
    row_sigma: NDArray[np.float64]
    imu_activity: NDArray[np.float64]
    gyro_activity: NDArray[np.float64]
    f_mean: NDArray[np.float64]
    w_mean: NDArray[np.float64]


def receiver_physics(
    seeds: NDArray,
    batch: ScenarioBatch,
    tt: NDArray,
    cap: NDArray,
    sigma_ref_m: float,
    cn0_offset_db: float = 0.0,
) -> ReceiverPhysics:
    """The shared receiver chain (module docstring, steps 1-6) with this platform's :data:`RECEIVER`.

    ``cn0_offset_db``: the report's calibration offset [dB] (step 6).
    """
    return receiver_report.receiver_physics(RECEIVER, seeds, batch, tt, cap, sigma_ref_m, cn0_offset_db)


def imu_window(stats: NDArray, n_sub: int, dt: float) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Window statistics of the IMU samples (module docstring) from the kernel's per-step sums.

    Args:
        stats: ``(B, T, 8)`` per-step sums over the step's samples of ``f`` (3), ``|f|^2``,
            ``omega`` (3), ``|omega|^2`` (:func:`navgym.quadrotor.imu_kernel.preintegrated_imu`).
        n_sub: Samples per step.
        dt: Step [s].

    Returns:
        ``imu_activity`` [m/s^2] ``(B, T+1)``, ``gyro_activity`` [rad/s] ``(B, T+1)``, the window
        means of ``f`` ``(B, T+1, 3)`` and of ``omega`` ``(B, T+1, 3)``; zeros at epoch 0.

    """
    w = max(1, int(round(IMU_WINDOW_S / dt)))
    s, cnt = trailing_sums(stats, w)
    m = np.maximum(cnt * n_sub, 1)[None, :, None]
    mean = s / m
    f_mean, w_mean = mean[..., 0:3], mean[..., 4:7]
    f_act = np.sqrt(np.maximum(mean[..., 3] - (f_mean**2).sum(-1), 0.0))
    w_act = np.sqrt(np.maximum(mean[..., 7] - (w_mean**2).sum(-1), 0.0))
    return f_act, w_act, f_mean, w_mean


def context_reports(
    phys: ReceiverPhysics,
    fix: NDArray,
    row_sigma_nominal: NDArray,
    imu: tuple[NDArray, NDArray, NDArray, NDArray],
    dt: float,
) -> QuadrotorContext:
    """The features' arrays: reports of delivered fixes, held or zeroed where none (class doc).

    Args:
        phys: The receiver's chain.
        fix: ``(B, T+1)`` whether a fix was delivered at k.
        row_sigma_nominal: The platform's nominal sigma of the six fix rows [m, m/s].
        imu: :func:`imu_window`'s four arrays.
        dt: Step [s].

    """
    n_sv, dop, age, cn0, sig = receiver_report.fix_report(phys, fix, row_sigma_nominal, dt)
    return QuadrotorContext(
        n_sv, dop, age, np.repeat(cn0[..., None], row_sigma_nominal.size, axis=-1), sig, *imu
    )


def context_features(m_max: int) -> tuple[Feature, ...]:
    """The v3 context features (each from a simulated sensor; values are clipped into the bounds)."""
    return (
        Feature(
            "row_cn0", 0.0, 60.0, "dB-Hz",
            "mean reported C/N0 of the satellites used by the fix, on each of its rows (p, v NED); "
            "0 where no fix was delivered at this epoch", size=m_max,
        ),
        Feature(
            "row_reported_sigma", 0.0, 100.0, "m, m/s",
            "the receiver's own accuracy estimate per row, "
            "HDOP sigma_nom sqrt(mean 10^(-(C/N0_rep - 42)/10)) "
            "(blind to multipath bias); 0 where no fix was delivered", size=m_max,
        ),
        Feature("gnss_n_sv", 0.0, float(N_CHANNELS), "satellites",
                "satellites used by the fix; the last fix's report held"),
        Feature("gnss_hdop", 0.0, 20.0, "-", "HDOP (k_geo / sqrt(n_sv - 3)); the last fix's report held"),
        Feature("gnss_report_age", 0.0, 60.0, "s", "age of the held report (0 at a delivered fix)"),
        Feature("imu_activity", 0.0, 20.0, "m/s^2",
                "RMS deviation of the 200 Hz specific-force samples from their mean over the last 1 s"),
        Feature("imu_gyro_activity", 0.0, 2.0, "rad/s",
                "RMS deviation of the angular-rate samples from their mean over the last 1 s"),
        Feature("imu_specific_force", -40.0, 40.0, "m/s^2",
                "mean measured specific force over the last 1 s (body x, y, z)", size=3),
        Feature("imu_angular_rate", -5.0, 5.0, "rad/s",
                "mean measured angular rate over the last 1 s (body x, y, z)", size=3),
    )  # fmt: skip


def context_feature_values(ctx: QuadrotorContext, t: NDArray) -> dict[str, NDArray]:
    """The context features of epoch ``t (B,)`` (clipped to the last epoch)."""
    ix = epoch_index(np.minimum(t, ctx.imu_activity.shape[1] - 1))  # views in lock step
    return {
        "row_cn0": ctx.row_cn0[ix],
        "row_reported_sigma": ctx.row_sigma[ix],
        "gnss_n_sv": ctx.n_sv[ix],
        "gnss_hdop": ctx.hdop[ix],
        "gnss_report_age": ctx.report_age[ix],
        "imu_activity": ctx.imu_activity[ix],
        "imu_gyro_activity": ctx.gyro_activity[ix],
        "imu_specific_force": ctx.f_mean[ix],
        "imu_angular_rate": ctx.w_mean[ix],
    }
