"""GpsIns v3 context physics: the C/N0 -> pseudo-range noise chain, the jammer's J/S, the IMU.

The v3 variant (``GpsInsPlatform(context=True)``, :mod:`navgym.gps_ins.env_v3`) gives every
pseudo-range row a C/N0 from physics and draws the row's code noise from it, and gives the
agent what a receiver and an IMU report. Per epoch and row (satellite ``i``, elevation ``el``
seen from the true position; the compiled epoch :mod:`navgym.gps_ins.epoch_kernel`, or
:func:`row_cn0_and_variance` on the NumPy path)::

    L    = canyon loss 20 log10(noise_scale) + sum of the active multipath segments' losses on i
    L'   = max(L + FADING_DB n, 0) where L > 0 (0 in open sky)
    C/N0 = eff(C_nom(el) + o_i - L', J/S)          (o_i ~ N(0, SAT_OFFSET_DB) per satellite)
    sigma_i = pseudorange_sigma_m(C/N0, sigma_pr)  (times v2's impulsive ratio where contaminated)

replacing v2's fixed per-event sigmas (canyon factor, jamming and multipath sigma); the
multipath bias and the outliers stay. A multipath segment is NLOS (loss ``U(4, 12)`` dB) or,
with probability :data:`LOS_MULTIPATH_PROBABILITY`, line-of-sight multipath (``U(0, 1)`` dB:
C/N0 nearly normal while its bias acts). The receiver reports ``round(C/N0 + n)`` (1 dB
estimator noise, 1 dB-Hz resolution; :func:`navgym.gnss.signal_quality.reported_cn0_dbhz`) and
its own sigma from it; another receiver's calibration (the v3 id's ``cn0_offset_db``,
:mod:`navgym.gnss.receiver_report`) reports ``round(C/N0 + cn0_offset_db + n)`` and its sigma
from that, while the true C/N0 and the rows' noise stay. The IMU (:func:`imu_window_statistics`)
senses the v2 manoeuvre bursts as vibration/manoeuvre acceleration. Pure, batched functions that
broadcast over episodes and rows.

* **Pseudo-range sigma from C/N0** (:func:`pseudorange_sigma_m`): a row's code noise follows
  the DLL thermal jitter of :func:`navgym.gnss.signal_quality.dll_jitter_m` (Kaplan & Hegarty
  2006, ch. 5), scaled so that the open-sky value at the reference elevation ``el_ref``
  (45 degrees) equals the v2 nominal ``sigma_pr``::

      sigma(C/N0) = sigma_pr * jitter(C/N0) / jitter(C_nom(el_ref))

  with ``C_nom`` the nominal C/N0 of :func:`navgym.gnss.signal_quality.nominal_cn0_dbhz`. In
  its large-C/N0 limit this is the SIGMA-epsilon law ``sigma^2 ∝ 10^(-C/N0/10)`` (Hartinger &
  Brunner 1999).
* **J/S of a v2 jamming regime** (:func:`jammer_to_signal_db`): v2 adds a jamming variance
  ``jam_sigma^2`` to ``sigma_pr^2``. v3 acts through C/N0 instead; the J/S is the one that makes
  DLL jitter variance at the reference C/N0 grow by the same factor
  ``k^2 = 1 + (jam_sigma / sigma_pr)^2``. With ``u = 1 / (c/n0)`` the jitter variance is
  ``∝ u (1 + a u)``, ``a = 2 / ((2 - d) T)`` (the squaring loss), so the jammed
  ``u_j = (sqrt(1 + 4 a k^2 V) - 1) / (2 a)`` with ``V = u_ref (1 + a u_ref)``, and since
  ``1/(c/n0)_eff = 1/(c/n0) + (J/S)/(Q R_c)`` (Kaplan & Hegarty 2006, ch. 9),

      J/S = Q R_c (u_j - u_ref)        (linear; -inf dB without jamming)
"""

from __future__ import annotations

from functools import cache
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.envs.features import Feature
from navgym.gnss import signal_quality as sq

__all__ = [
    "REFERENCE_ELEVATION_RAD",
    "JAMMER_Q",
    "pseudorange_sigma_m",
    "jammer_to_signal_db",
    "row_cn0_dbhz",
    "window_stats",
    "GpsInsContext",
    "row_cn0_and_variance",
    "draw_receiver_context",
    "imu_window_statistics",
    "context_features",
    "imu_feature_values",
    "jitter_reference_variance",
]

#: The "typical" elevation at which v3's open-sky pseudo-range sigma equals v2's sigma_pr [rad].
REFERENCE_ELEVATION_RAD: float = float(np.deg2rad(45.0))
#: Spectral-separation factor Q of the simulated jammer (broad-band noise; Kaplan & Hegarty 2006).
JAMMER_Q: float = 2.0


@cache
def _reference_cn0_dbhz() -> float:
    """The nominal C/N0 at :data:`REFERENCE_ELEVATION_RAD` (a constant: computed once)."""
    return float(sq.nominal_cn0_dbhz(REFERENCE_ELEVATION_RAD))


@cache
def _reference_jitter_m() -> float:
    """The DLL jitter at the reference C/N0 (a constant: computed once, every step reads it)."""
    return float(sq.dll_jitter_m(_reference_cn0_dbhz()))


def pseudorange_sigma_m(cn0_dbhz: ArrayLike, sigma_pr: float) -> NDArray[np.float64]:
    """Pseudo-range noise sigma [m] of rows at ``cn0_dbhz``: ``sigma_pr jitter(C/N0) / jitter(C_ref)``."""
    return sigma_pr * sq.dll_jitter_m(cn0_dbhz) / _reference_jitter_m()


def jammer_to_signal_db(jam_sigma_m: ArrayLike, sigma_pr: float) -> NDArray[np.float64]:
    """J/S [dB] equivalent to v2's jamming sigma ``jam_sigma_m`` (module docstring); -inf at 0."""
    k2 = 1.0 + (np.asarray(jam_sigma_m, np.float64) / sigma_pr) ** 2
    a = 2.0 / ((2.0 - 1.0) * 0.02)  # dll_jitter_m's defaults: d = 1 chip, T = 20 ms
    u_ref = 10.0 ** (-_reference_cn0_dbhz() / 10.0)
    u_j = (np.sqrt(1.0 + 4.0 * a * k2 * u_ref * (1.0 + a * u_ref)) - 1.0) / (2.0 * a)
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(np.maximum(JAMMER_Q * sq.CA_CHIP_RATE_HZ * (u_j - u_ref), 0.0))


def row_cn0_dbhz(
    elevation_rad: ArrayLike,
    attenuation_db: ArrayLike,
    jammer_to_signal_db: ArrayLike,
) -> NDArray[np.float64]:
    """True C/N0 [dB-Hz] of rows: nominal at their elevation, less the obstruction, under the jammer.

    ``C/N0 = eff(C_nom(el) - L, J/S)`` with ``C_nom`` :func:`navgym.gnss.signal_quality.nominal_cn0_dbhz`,
    ``L >= 0`` the row's attenuation [dB] (NLOS / canyon, 0 in open sky) and ``eff`` the
    interference law :func:`navgym.gnss.signal_quality.effective_cn0_dbhz` (one J/S for all rows
    of an episode: pass it with a trailing axis of length 1).
    """
    clear = sq.nominal_cn0_dbhz(elevation_rad) - np.asarray(attenuation_db, np.float64)
    return sq.effective_cn0_dbhz(clear, jammer_to_signal_db, q=JAMMER_Q)


def window_stats(x: ArrayLike, t: int, window: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and standard deviation of ``x[:, t - window + 1 : t + 1]`` along the time axis (1).

    ``x`` is ``(B, T, ...)`` (e.g. an IMU's specific-force magnitude per sample); the window is
    shortened at the start of the episode.
    """
    a = np.asarray(x, np.float64)[:, max(0, t - window + 1) : t + 1]
    return a.mean(axis=1), a.std(axis=1)


# ------------------------------------------------------------------------------ the v3 build
#: Per-satellite antenna-pattern / signal-power offset sigma [dB] (fixed over an episode).
SAT_OFFSET_DB: float = 1.5
#: Receiver C/N0 estimator sigma [dB] and the report's resolution [dB-Hz] (NMEA GSV: 1 dB-Hz).
CN0_ESTIMATOR_DB: float = 1.0
CN0_RESOLUTION_DB: float = 1.0
#: Probability that a multipath segment is line-of-sight multipath (C/N0 nearly normal).
LOS_MULTIPATH_PROBABILITY: float = 0.3
#: Loss range [dB] of an NLOS segment and of a line-of-sight multipath segment; epoch fading sigma [dB].
NLOS_LOSS_DB: tuple[float, float] = (4.0, 12.0)
LOS_LOSS_DB: tuple[float, float] = (0.0, 1.0)
FADING_DB: float = 2.0
#: DLL squaring-loss constant ``a = 2 / ((2 - d) T)`` [Hz] of
#: :func:`navgym.gnss.signal_quality.dll_jitter_m`'s defaults (d = 1 chip, T = 20 ms): the
#: jitter variance is ``∝ u (1 + a u)``, ``u = 1 / (c/n0)``.
DLL_SQUARING_HZ: float = 2.0 / ((2.0 - 1.0) * 0.02)
#: IMU output rate of the v3 IMU [Hz] and the window of its statistics [s].
IMU_RATE_HZ: int = 10
IMU_WINDOW_S: float = 1.0
#: Unmodelled INS acceleration error per unit of manoeuvre acceleration (scale-factor and
#: misalignment errors excited by the manoeuvre, the g-sensitivity): a v2 burst of
#: ``velocity_sigma`` [m/s^2] is a manoeuvre/vibration of ``velocity_sigma / MANOEUVRE_COUPLING``.
MANOEUVRE_COUPLING: float = 0.05
#: Baseline road/sea vibration per axis [m/s^2] (outside bursts).
BASE_VIBRATION: float = 0.05
#: Speed [m/s] turning a lateral vibration into an angular one: ``sigma_w = sigma_a / V_TURN``.
V_TURN: float = 10.0
#: Accelerometer and gyro white noise per 10 Hz sample [m/s^2], [rad/s] (MEMS: ~0.1 mg/sqrt(Hz),
#: ~0.01 deg/s/sqrt(Hz) at 5 Hz bandwidth; Groves 2013 Table 4.1).
ACCEL_NOISE: float = 0.002
GYRO_NOISE: float = 0.0005
#: Standard gravity [m/s^2].
GRAVITY: float = 9.80665


class GpsInsContext(NamedTuple):
    """The v3 context inputs of B episodes, drawn at reset (sensor side: what makes the sensors).

    Attributes:
        sat_offset_db: ``(B, S)`` per-satellite C/N0 offset [dB] (almanac order).
        seg_loss_db: ``(B, MULTIPATH_SLOTS)`` attenuation of each multipath segment [dB] (0 unused).
        canyon_loss_db: ``(B, T+1)`` an urban canyon's diffraction loss ``20 log10(noise_scale)`` [dB].
        jam_lin: ``(B, T+1)`` the jammer's ``(J/S) / (Q R_c)`` [1/Hz] (0 without jamming).
        fade_db: ``(B, T+1, m_max)`` epoch fading of each row [dB] (``FADING_DB`` normals).
        est: ``(B, T+1, m_max)`` the C/N0 estimator's standard normals.
        imu: ``(B, T+1, 4)`` IMU window statistics of the step ending at epoch k: specific-force
            magnitude mean, spread [m/s^2], angular-rate magnitude mean, spread [rad/s] (0 at k = 0).
    """

    sat_offset_db: NDArray[np.float64]
    seg_loss_db: NDArray[np.float64]
    canyon_loss_db: NDArray[np.float64]
    jam_lin: NDArray[np.float64]
    fade_db: NDArray[np.float64]
    est: NDArray[np.float64]
    imu: NDArray[np.float64]


def jitter_reference_variance() -> float:
    """``u_ref (1 + a u_ref)``: the DLL variance factor at the reference C/N0 (module docstring)."""
    u_ref = 10.0 ** (-_reference_cn0_dbhz() / 10.0)
    return u_ref * (1.0 + DLL_SQUARING_HZ * u_ref)


def row_cn0_and_variance(
    sin_el: ArrayLike,
    offset_db: ArrayLike,
    loss_db: ArrayLike,
    fade_db: ArrayLike,
    jam_lin: ArrayLike,
    sigma_pr: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """True C/N0 [dB-Hz] of rows and their code-noise variance [m^2] (the compiled epoch's law).

    ``L' = max(L + fade, 0)`` where the row's attenuation ``L > 0`` (0 otherwise);
    ``u = 10^(-(C_nom(el) + offset - L') / 10) + jam_lin`` (Kaplan & Hegarty 2006, ch. 9: the
    effective noise density), C/N0 ``= -10 log10 u``, and the variance
    ``sigma_pr^2 u (1 + a u) / (u_ref (1 + a u_ref))``: :func:`pseudorange_sigma_m` squared.
    """
    loss = np.asarray(loss_db, np.float64)
    loss = np.where(loss > 0.0, np.maximum(loss + fade_db, 0.0), 0.0)
    el = np.arcsin(np.clip(np.asarray(sin_el, np.float64), 0.0, 1.0))
    u = 10.0 ** (-(sq.nominal_cn0_dbhz(el) + offset_db - loss) / 10.0) + np.asarray(jam_lin, np.float64)
    var = sigma_pr**2 * u * (1.0 + DLL_SQUARING_HZ * u) / jitter_reference_variance()
    return -10.0 * np.log10(u), var


def draw_receiver_context(
    seeds: NDArray,
    n_sats: int,
    m_max: int,
    mp_start: NDArray,
    canyon_scale: NDArray,
    jam_sigma: NDArray,
    sigma_pr: float,
) -> tuple[NDArray[np.float64], ...]:
    """The receiver side of :class:`GpsInsContext` (all but ``imu``) of B episodes.

    Each episode draws from ``np.random.default_rng([seed, 2])``: the satellites' offsets
    ``N(0, SAT_OFFSET_DB)``, the fading and estimator normals of every epoch and row, then per
    used multipath slot whether it is line-of-sight multipath (probability
    ``LOS_MULTIPATH_PROBABILITY``, loss ``U(LOS_LOSS_DB)``) or NLOS (``U(NLOS_LOSS_DB)``): the
    segments come last, so an episode with one more segment keeps every other draw.

    Args:
        seeds: ``(B,)`` the episodes' context seeds.
        n_sats: Satellites of the almanac (S).
        m_max: Rows.
        mp_start: ``(B, MULTIPATH_SLOTS)`` the episodes' multipath slots' starts (inf unused).
        canyon_scale: ``(B, T+1)`` the canyon's noise factor (1 outside).
        jam_sigma: ``(B, T+1)`` v2's jamming sigma [m] (ramped; 0 outside).
        sigma_pr: The nominal pseudo-range sigma [m].
    """
    B, n = canyon_scale.shape
    off = np.empty((B, n_sats))
    seg = np.zeros(mp_start.shape)
    fade = np.empty((B, n, m_max))
    est = np.empty((B, n, m_max))
    for i in range(B):
        g = np.random.default_rng([int(seeds[i]), 2])
        off[i] = g.standard_normal(n_sats) * SAT_OFFSET_DB
        fade[i] = g.standard_normal((n, m_max)) * FADING_DB
        est[i] = g.standard_normal((n, m_max))
        j = np.flatnonzero(np.isfinite(mp_start[i]))
        los = g.random(j.size) < LOS_MULTIPATH_PROBABILITY
        u = g.random(j.size)
        seg[i, j] = np.where(
            los, LOS_LOSS_DB[0] + u * np.diff(LOS_LOSS_DB), NLOS_LOSS_DB[0] + u * np.diff(NLOS_LOSS_DB)
        )
    canyon = 20.0 * np.log10(canyon_scale)
    jam = 10.0 ** (jammer_to_signal_db(jam_sigma, sigma_pr) / 10.0) / (JAMMER_Q * sq.CA_CHIP_RATE_HZ)
    return off, seg, canyon, jam, fade, est


def imu_window_statistics(
    seeds: NDArray, position_ne: NDArray, heading: NDArray, burst_sigma: NDArray, dt: float
) -> NDArray[np.float64]:
    """``(B, T+1, 4)`` IMU statistics of the step ``k-1 -> k`` (:class:`GpsInsContext.imu`).

    A strapdown IMU (level body, x along the heading; Groves 2013, ch. 4) sampled at
    ``IMU_RATE_HZ`` senses, over each step, the vehicle's dynamics from the track (per step:
    along-track ``dv/dt`` and centripetal ``v dTheta/dt`` of the finite-differenced track,
    ``-g`` vertical), a vibration of ``sigma = sqrt(BASE_VIBRATION^2 + (b / MANOEUVRE_COUPLING)^2)``
    per axis where ``b`` is the v2 burst's ``velocity_sigma`` of the step (the manoeuvre that
    excites the INS error), and white noise ``ACCEL_NOISE``; its gyros the turn rate, an angular
    vibration ``sigma / V_TURN`` per axis and ``GYRO_NOISE``. The statistics are the mean and
    standard deviation of the specific-force magnitude ``|f|`` and of the angular-rate
    magnitude ``|w|`` over the step's ``IMU_WINDOW_S dt``-long window (:func:`window_stats` of the
    samples). Normals from ``np.random.default_rng([seed, 3])`` per episode.
    """
    B, n = heading.shape
    N = int(round(IMU_RATE_HZ * IMU_WINDOW_S * dt))
    d = np.diff(position_ne, axis=1)
    v = np.hypot(d[..., 0], d[..., 1]) / dt  # (B, T) speed of step k -> k + 1
    acc = np.diff(v, axis=1, prepend=v[:, :1]) / dt
    turn = np.angle(np.exp(1j * np.diff(heading, axis=1))) / dt
    vib = np.sqrt(BASE_VIBRATION**2 + (burst_sigma[:, :-1] / MANOEUVRE_COUPLING) ** 2)  # (B, T)
    sa = np.sqrt(vib**2 + ACCEL_NOISE**2)[..., None]
    sw = np.sqrt((vib / V_TURN) ** 2 + GYRO_NOISE**2)[..., None]
    out = np.zeros((B, n, 4))
    for i in range(B):
        z = np.random.default_rng([int(seeds[i]), 3]).standard_normal((6, n - 1, N))
        f = np.sqrt(
            (acc[i, :, None] + sa[i] * z[0]) ** 2 + ((v * turn)[i, :, None] + sa[i] * z[1]) ** 2
            + (-GRAVITY + sa[i] * z[2]) ** 2
        )  # fmt: skip
        w = np.sqrt((sw[i] * z[3]) ** 2 + (sw[i] * z[4]) ** 2 + (turn[i, :, None] + sw[i] * z[5]) ** 2)
        out[i, 1:, 0], out[i, 1:, 1] = f.mean(axis=1), f.std(axis=1)
        out[i, 1:, 2], out[i, 1:, 3] = w.mean(axis=1), w.std(axis=1)
    return out


#: Bounds of the context features (values beyond are clipped).
ROW_CN0_BOUND = 60.0
ROW_SIGMA_BOUND = 100.0
IMU_ACTIVITY_BOUND = 10.0


#: The v3 context features (``GpsInsPlatform(context=True)``; the card's paragraph says more).
def context_features(m_max: int) -> tuple[Feature, ...]:
    """The context features of ``m_max`` pseudo-range rows."""
    return (
        Feature("row_cn0", 0.0, ROW_CN0_BOUND, "dB-Hz",
                "reported C/N0 of each pseudo-range row's satellite (1 dB estimator noise, 1 dB-Hz "
                "resolution); 0 on rows not received", size=m_max),
        Feature("row_elevation", 0.0, 90.0, "deg",
                "elevation of each row's satellite seen from the estimated position; 0 on rows not received",
                size=m_max),
        Feature("row_reported_sigma", 0.0, ROW_SIGMA_BOUND, "m",
                "the receiver's own pseudo-range sigma of each row from its reported C/N0 (DLL jitter "
                "law, sigma_pr at the 45 deg nominal C/N0; blind to multipath bias); 0 on rows not received",
                size=m_max),
        Feature("imu_activity", 0.0, IMU_ACTIVITY_BOUND, "m/s^2",
                "standard deviation of the IMU's specific-force magnitude over the last 1 s (10 Hz samples)"),
        Feature("imu_force_mean", 0.0, 30.0, "m/s^2", "mean IMU specific-force magnitude over the last 1 s"),
        Feature("imu_rate_mean", 0.0, 2.0, "rad/s", "mean IMU angular-rate magnitude over the last 1 s"),
        Feature("imu_rate_spread", 0.0, 2.0, "rad/s",
                "standard deviation of the IMU angular-rate magnitude over the last 1 s"),
    )  # fmt: skip


def imu_feature_values(imu: NDArray) -> dict[str, NDArray[np.float64]]:
    """The IMU features of ``imu (B, 4)`` (one epoch of :attr:`GpsInsContext.imu`)."""
    return {
        "imu_activity": imu[:, 1],
        "imu_force_mean": imu[:, 0],
        "imu_rate_mean": imu[:, 2],
        "imu_rate_spread": imu[:, 3],
    }
