"""Pedestrian's v3 context: what the GPS/GLONASS receiver and the foot IMU report besides the filter.

Every number is produced by a simulated sensor from the physics of the episode (its satellites,
the scenario's canyons, jammers and multipath segments, the foot's shocks), with randomness from
the episode's own generator; no scenario label or truth reaches a feature except through these
sensors. The structure is the Quadrotor's (:mod:`navgym.quadrotor.context`), with the numbers
of a body-worn GPS/GLONASS receiver in a city street and a foot-mounted IMU.

**The receiver** (one, delivering the three-row position fix; the ZUPT rows 3-5 have no
receiver) runs one chain per epoch ``k``:

1. **Satellites.** A base count ``n_0`` uniform in :data:`VISIBLE` per episode (a street masks
   part of the sky) varies slowly, ``n_vis(t) = clip(round(n_0 + A sin(2 pi t / P + phi)),
   MIN_VISIBLE, N_CHANNELS)`` with ``A ~ U(0, 1.5)``, ``P ~ U(120, 600)`` s, ``phi ~ U(0, 2 pi)``;
   the satellites used are ``n_sv = min(n_vis, cap)``, ``cap`` 0 in an outage and an urban
   canyon's count inside one. Since ``n_vis >= MIN_VISIBLE = 5`` a fix exists exactly where v2's
   ``cap >= 4`` allows one.
2. **DOP** ``HDOP = k_geo / sqrt(n_sv - 3)`` (:func:`navgym.gnss.receiver_report.hdop`; Kaplan &
   Hegarty 2006, 7.1), ``k_geo ~ U(HDOP_K)`` per episode (a street's one-sided geometry: larger
   than the Quadrotor's open sky); ``VDOP = 1.5 HDOP`` (the nominal down row's sigma already
   carries it). Satellites are used by decreasing elevation (a canyon keeps the highest).
3. **Per-satellite C/N0.** Elevations per episode (``sin el ~ U(sin 15 deg, 1)``, sorted down);
   ``C/N0_i = effective_cn0_dbhz(nominal_cn0_dbhz(el_i, 45, 28) + o_i - A(k), J/S(k))``
   (:mod:`navgym.gnss.signal_quality`; Kaplan & Hegarty 2006, ch. 8-9, ``Q = 2``): a body-worn
   receiver's small antenna sees 28 dB-Hz at the horizon, 45 at the zenith (3-4 dB below a
   patch antenna on a vehicle roof, the default 32-48), with a fixed antenna/body-shadowing
   offset ``o_i ~ N(0, 2 dB)`` per satellite. The attenuation ``A(k)`` is a canyon's diffraction
   loss ``20 log10(noise_scale)`` dB (v2's noise factor as a signal loss: 6-14 dB for 2-5) plus
   the largest loss of the active multipath segments, plus epoch fading ``N(0, 2 dB)`` wherever
   it is positive (never below 0). A multipath segment is, with probability
   :data:`LOS_MULTIPATH_PROBABILITY`, line-of-sight multipath (loss ``U(0, 1)`` dB: C/N0 stays
   nearly normal while the bias acts), else NLOS (a reflection only, loss ``U(4, 12)`` dB).
4. **Jamming as J/S** (:func:`navgym.gnss.receiver_report.jammer_to_signal_db`): v2's
   ``jam_sigma`` [m] is the jammer's strength, ``J/S = Q R_c / (c/n0)_ref (jam_sigma /
   sigma_pos)^2``, which at :data:`CN0_REF_DBHZ` multiplies the code noise variance by
   ``1 + (jam_sigma / sigma_pos)^2``: v2's ``sigma_pos^2 + jam_sigma^2`` (v2's 30 m on the 5 m fix
   is ``J/S = 40.7`` dB). No loss of lock is modelled: v2's jamming loss stays.
5. **Fix noise** of row ``r``: ``sigma_r = HDOP sigma_nom,r sqrt(u)``, ``u`` the mean over the
   satellites used of the SIGMA-epsilon variance ``10^(-(C/N0_i - C/N0_ref)/10)`` (Hartinger &
   Brunner 1999; :func:`navgym.gnss.receiver_report.uere_variance_factor`), ``sigma_nom`` the
   platform's fix sigmas (5, 5, 7.5 m), so HDOP 1 with every satellite at 38 dB-Hz gives v2's
   nominal fix. The platform adds v2's impulsive ratio, multipath bias and noise and outliers.
6. **The receiver's report**: ``n_sv``, HDOP, the mean over the satellites used of the reported
   C/N0 (:func:`~navgym.gnss.signal_quality.reported_cn0_dbhz`, 1 dB estimator noise, 1 dB-Hz
   resolution) and its accuracy estimate ``HDOP sigma_nom,r sqrt(u_rep)`` with ``u_rep`` from the
   reported C/N0 (as a receiver's hAcc/vAcc): blind to a multipath bias, multipath noise and outliers.
   ``cn0_offset_db`` (the v3 id's keyword argument; :mod:`navgym.gnss.receiver_report`) models
   another receiver's calibration: each satellite's report is ``round(C/N0_i + cn0_offset_db +
   n_i)``, and ``u_rep`` follows it; the true C/N0, ``u`` and the fix noise do not change.

**The foot IMU's context** comes from the simulated IMU samples themselves (truth, biases, white
noise and v2's shocks: a shock's extra accelerometer and gyro noise is measured by the sensor,
so it shows here). The stance detector looks at the samples of the **stance window** that ends
at epoch ``k``: the last ``W = max(2, round(STANCE_HALF n_sub))`` samples of stride ``k - 1``
(20 samples, 0.2 s, at 100 Hz; the foot is at rest there, :mod:`navgym.pedestrian.gait`; below
10 Hz the window reaches into the swing):

* ``stance_statistic = log10 T_SHOE`` with the SHOE detector's statistic (Skog, Handel, Nilsson,
  Rantakokko 2010, "Zero-velocity detection: an algorithm evaluation", IEEE TBME, the
  generalized likelihood ratio test of a stationary foot)::

      T = 1/W sum_j ( |f_j - g f_bar / |f_bar||^2 / sigma_a^2 + |omega_j|^2 / sigma_w^2 )

  with ``f_bar`` the window mean, ``g`` the home's gravity magnitude and ``sigma_a``,
  ``sigma_w`` the IMU grade's per-sample noise (``N / sqrt(delta)``: 6.9e-3 m/s^2 and 6.6e-4
  rad/s for consumer MEMS at 100 Hz; Groves 2013, ch. 4.4). A still foot gives ``T`` of order
  10-100 (the chi-square's 6 per sample, plus the gyro's turn-on bias of 0.1 deg/s, about 21,
  and the accelerometer's along gravity): ``log10 T`` about 1-2; a shock (running, stairs,
  rough pavement; v2's 0.02-0.1 m/s/sqrt(s) and 0.001-0.005 rad/sqrt(s)) gives ``T`` of 1e3-1e5,
  ``log10 T`` 3.5-5: the detector would no longer call the foot still.
* ``imu_activity`` [m/s^2]: the standard deviation over the stance window of the specific-force
  magnitude ``|f_j|``: the accelerometer's noise along gravity, about 6.9e-3 m/s^2 when the
  foot is still, 0.2-1.0 m/s^2 in a shock (its per-sample ``s / sqrt(delta)``).

Both are 0 at epoch 0 (no stride yet).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.envs.features import Feature
from navgym.gnss import receiver_report
from navgym.gnss.receiver_report import (
    ReceiverModel,
    ReceiverPhysics,
)
from navgym.pedestrian.gait import STANCE_HALF
from navgym.scenarios import ScenarioBatch

__all__ = [
    "N_CHANNELS",
    "MIN_VISIBLE",
    "VISIBLE",
    "HDOP_K",
    "CN0_REF_DBHZ",
    "CN0_ZENITH_DBHZ",
    "CN0_HORIZON_DBHZ",
    "JAMMER_Q",
    "LOS_MULTIPATH_PROBABILITY",
    "ReceiverPhysics",
    "PedestrianContext",
    "receiver_physics",
    "stance_window",
    "stance_stats",
    "context_reports",
    "context_features",
    "context_feature_values",
]

#: Receiver channels (satellites used at most; the scenario's 12 channels).
N_CHANNELS = 12
#: Fewest visible satellites in a street (>= 5: a fix wherever v2 has one).
MIN_VISIBLE = 5
#: Range of the per-episode base count of visible GPS/GLONASS satellites (a street masks part of the sky).
VISIBLE = (6, 12)
#: Range of the per-episode geometry factor ``k_geo`` of ``HDOP = k_geo / sqrt(n_sv - 3)``.
HDOP_K = (2.0, 3.0)
#: Body-worn antenna: C/N0 at the zenith and the horizon [dB-Hz] (module docstring, step 3).
CN0_ZENITH_DBHZ = 45.0
CN0_HORIZON_DBHZ = 28.0
#: Lowest elevation of a satellite in view [deg].
MIN_ELEVATION_DEG = 15.0
#: C/N0 [dB-Hz] at which the SIGMA-epsilon model gives the nominal fix sigma (with DOP 1).
CN0_REF_DBHZ = 38.0
#: Spectral-separation factor of the jammer (broad-band noise; Kaplan & Hegarty 2006, ch. 9).
JAMMER_Q = 2.0
#: Probability that a multipath segment is line-of-sight multipath (C/N0 nearly normal).
LOS_MULTIPATH_PROBABILITY = 0.3
#: NLOS loss range [dB], line-of-sight multipath loss range [dB], epoch fading sigma [dB].
NLOS_LOSS_DB = (4.0, 12.0)
LOS_LOSS_DB = (0.0, 1.0)
FADING_DB = 2.0
#: Per-satellite antenna/body-shadowing offset sigma [dB]; receiver C/N0 estimator sigma [dB].
SAT_OFFSET_DB = 2.0
CN0_ESTIMATOR_DB = 1.0
#: Second argument of the receiver's generator ``default_rng([gnss_seed, RECEIVER_STREAM])``.
RECEIVER_STREAM = 7
#: This platform's receiver (:func:`receiver_physics`).
RECEIVER = ReceiverModel(
    visible=VISIBLE,
    hdop_k=HDOP_K,
    cn0_zenith_dbhz=CN0_ZENITH_DBHZ,
    cn0_horizon_dbhz=CN0_HORIZON_DBHZ,
    min_elevation_deg=MIN_ELEVATION_DEG,
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
#: Bounds of the features ``stance_statistic`` [log10] and ``imu_activity`` [m/s^2].
STANCE_BOUNDS = (-1.0, 8.0)
ACTIVITY_BOUND = 20.0


class PedestrianContext(NamedTuple):
    """The v3 context of B episodes per epoch ``k`` (``(B, T+1, ...)``), all sensor-side.

    Attributes:
        n_sv: Satellites used, the last fix's report held ``(B, T+1)``.
        hdop: Its HDOP, held ``(B, T+1)`` (0 before any fix).
        report_age: Age of the held report [s] ``(B, T+1)`` (0 at a delivered fix).
        row_cn0: Mean reported C/N0 [dB-Hz] of the fix on its rows 0-2, 0 on the ZUPT rows and
            where no fix was delivered at k ``(B, T+1, 6)``.
        row_sigma: The receiver's accuracy estimate per fix row [m] ``(B, T+1, 6)``, 0 likewise.
        stance_statistic: ``log10`` of the SHOE statistic of the stance window ``(B, T+1)``.
        imu_activity: Spread of ``|f|`` over the stance window [m/s^2] ``(B, T+1)``.

    """

    n_sv: NDArray[np.float64]
    hdop: NDArray[np.float64]
    report_age: NDArray[np.float64]
    row_cn0: NDArray[np.float64]
    row_sigma: NDArray[np.float64]
    stance_statistic: NDArray[np.float64]
    imu_activity: NDArray[np.float64]


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


def stance_window(n_sub: int) -> int:
    """Samples ``W = max(2, round(STANCE_HALF n_sub))`` of the stance window (module docstring)."""
    return max(2, int(np.floor(STANCE_HALF * n_sub + 0.5)))


def stance_stats(
    accel: NDArray, gyro: NDArray, g: NDArray, sigma_a: float, sigma_w: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The stance detector's statistics of windows of IMU samples (module docstring).

    Args:
        accel: Measured specific force [m/s^2] ``(B, S, W, 3)``: the windows of S strides.
        gyro: Measured angular rate [rad/s] ``(B, S, W, 3)``.
        g: Gravity magnitude [m/s^2] ``(B,)`` (the home's).
        sigma_a: The detector's accelerometer noise per sample [m/s^2].
        sigma_w: The detector's gyro noise per sample [rad/s].

    Returns:
        ``log10 T_SHOE`` ``(B, S)`` and the standard deviation of ``|f|`` over each window
        [m/s^2] ``(B, S)``.

    """
    f_bar = accel.mean(axis=2, keepdims=True)
    u = f_bar / np.linalg.norm(f_bar, axis=-1, keepdims=True)
    da = accel - np.asarray(g)[:, None, None, None] * u
    t = ((da * da).sum(-1) / sigma_a**2 + (gyro * gyro).sum(-1) / sigma_w**2).mean(axis=2)
    with np.errstate(divide="ignore"):
        log_t = np.log10(t)
    return log_t, np.linalg.norm(accel, axis=-1).std(axis=2)


def context_reports(
    phys: ReceiverPhysics,
    fix: NDArray,
    fix_sigma_nominal: NDArray,
    m_max: int,
    imu: tuple[NDArray, NDArray],
    dt: float,
) -> PedestrianContext:
    """The features' arrays: reports of delivered fixes, held or zeroed where none (class doc).

    Args:
        phys: The receiver's chain.
        fix: ``(B, T+1)`` whether a fix was delivered at k.
        fix_sigma_nominal: The platform's nominal sigma of the fix rows [m] ``(r,)``, rows 0 .. r-1.
        m_max: Rows of the measurement vector (the ZUPT rows after the fix's get 0).
        imu: :func:`stance_stats`' two arrays per stride ``(B, T)``.
        dt: Step [s].

    """
    n_sv, dop, age, cn0, sig = receiver_report.fix_report(phys, fix, fix_sigma_nominal, dt)
    B, n = fix.shape
    r = fix_sigma_nominal.size
    row_cn0 = np.zeros((B, n, m_max))
    row_cn0[..., :r] = cn0[..., None]
    row_sig = np.zeros((B, n, m_max))
    row_sig[..., :r] = sig
    stance, act = (np.concatenate([np.zeros((B, 1)), x], axis=1) for x in imu)  # 0 at epoch 0
    return PedestrianContext(n_sv, dop, age, row_cn0, row_sig, stance, act)


def context_features(m_max: int) -> tuple[Feature, ...]:
    """The v3 context features (each from a simulated sensor; values are clipped into the bounds)."""
    return (
        Feature(
            "row_cn0", 0.0, 60.0, "dB-Hz",
            "mean reported C/N0 of the satellites used by the fix, on its rows (fix N, E, D); "
            "0 on the ZUPT rows and where no fix was delivered at this epoch", size=m_max,
        ),
        Feature(
            "row_reported_sigma", 0.0, 100.0, "m",
            "the receiver's own accuracy estimate per fix row, "
            "HDOP sigma_nom sqrt(mean 10^(-(C/N0_rep - 38)/10)) "
            "(blind to multipath bias); 0 on the ZUPT rows and where no fix was delivered", size=m_max,
        ),
        Feature("gnss_n_sv", 0.0, float(N_CHANNELS), "satellites",
                "GPS/GLONASS satellites used by the fix; the last fix's report held"),
        Feature("gnss_hdop", 0.0, 20.0, "-", "HDOP (k_geo / sqrt(n_sv - 3)); the last fix's report held"),
        Feature("gnss_report_age", 0.0, 60.0, "s", "age of the held report (0 at a delivered fix)"),
        Feature("stance_statistic", *STANCE_BOUNDS, "log10",
                "log10 of the SHOE stance detector's statistic (Skog et al. 2010) over the stance "
                "window before the epoch; 0 at the first epoch"),
        Feature("imu_activity", 0.0, ACTIVITY_BOUND, "m/s^2",
                "standard deviation of the specific-force magnitude over the stance window before "
                "the epoch; 0 at the first epoch"),
    )  # fmt: skip


def context_feature_values(ctx: PedestrianContext, t: NDArray) -> dict[str, NDArray]:
    """The context features of epoch ``t (B,)`` (clipped to the last epoch)."""
    rows = np.arange(t.shape[0])
    k = np.minimum(t, ctx.imu_activity.shape[1] - 1)
    return {
        "row_cn0": ctx.row_cn0[rows, k],
        "row_reported_sigma": ctx.row_sigma[rows, k],
        "gnss_n_sv": ctx.n_sv[rows, k],
        "gnss_hdop": ctx.hdop[rows, k],
        "gnss_report_age": ctx.report_age[rows, k],
        "stance_statistic": ctx.stance_statistic[rows, k],
        "imu_activity": ctx.imu_activity[rows, k],
    }
