"""Generic pieces of a simulated GNSS receiver's own quality report (batched, pure).

A receiver reports with each fix the satellites it used, the dilution of precision of their
geometry and the C/N0 of each; from these it also estimates its own accuracy. The functions
here are the platform-independent links of that chain, as the platforms' context modules
(:mod:`navgym.robot2d.context`, :mod:`navgym.quadrotor.context`,
:mod:`navgym.pedestrian.context`) assemble them. Every function broadcasts over leading axes
(episodes, epochs).

* **HDOP** (:func:`hdop`): ``k_geo / sqrt(n_sv - 3)``: ``(G^T G)^-1`` of ``n`` well spread lines
  of sight shrinks like ``1 / (n - 3)`` once the four unknowns (position, clock) are fixed;
  ``k_geo`` is the geometry's luck (Kaplan & Hegarty 2006, ch. 7.1, DOP). ``inf`` below 4.
* **Jamming as J/S** (:func:`jammer_to_signal_db`): a v2 jamming regime adds ``jam_sigma^2`` to
  a fix variance ``sigma_ref^2``. Acting through C/N0 instead, ``1/(c/n0)_eff = 1/(c/n0) +
  (J/S)/(Q R_c)`` (Kaplan & Hegarty 2006, ch. 9) with ``J/S = Q R_c / (c/n0)_ref (jam_sigma /
  sigma_ref)^2`` multiplies the SIGMA-epsilon variance at ``(C/N0)_ref`` by exactly
  ``1 + (jam_sigma / sigma_ref)^2``: the v2 variance.
* **Range-error variance from C/N0** (:func:`uere_variance_factor`): the SIGMA-epsilon law
  ``sigma_i^2 = C_i 10^(-C/N0_i / 10)`` (Hartinger & Brunner 1999; the large-C/N0 limit of the
  DLL jitter, Kaplan & Hegarty 2006, ch. 5) averaged over the satellites used, relative to its
  value at ``(C/N0)_ref``: ``u = mean_i 10^(-(C/N0_i - C/N0_ref) / 10)``. A fix's noise per axis
  is then ``DOP sigma_ref sqrt(u)`` (``sigma_UERE = sigma_ref sqrt(u)``).
* **Held reports** (:func:`held`): a report is repeated until the next fix, with its age.
* **Trailing windows** (:func:`trailing_sums`): sums over the last ``W`` steps that ended by
  epoch ``k`` (0 at the start), for windowed IMU statistics.
* **One receiver's chain** (:func:`receiver_physics`, its figures a :class:`ReceiverModel`):
  satellites in view varying slowly per episode, capped by the sky (canyon, outage); HDOP;
  per-satellite C/N0 from elevation with an offset, lowered by canyon diffraction and the active
  multipath segments (NLOS, or line-of-sight multipath that leaves C/N0 nearly normal) with
  epoch fading, then by the jammer's J/S; the reported C/N0; the SIGMA-epsilon factors ``u``
  (true) and ``u_rep`` (reported) of the fix noise ``DOP sigma_ref sqrt(u)``.
* **Another receiver's calibration** (``cn0_offset_db``, :func:`check_cn0_offset`): a receiver
  of another model estimates C/N0 with a different calibration, so it reports
  ``round(C/N0 + cn0_offset_db + sigma_est n)`` for the same signal (the offset enters before
  its rounding to the report's resolution); everything it derives from its report (``u_rep``,
  its accuracy figure) follows, while the true C/N0, ``u`` and the fix noise do not change. No
  random number is drawn for it. The distribution shift of issue #36 ("a C/N0 model offset by a
  few dB: a receiver other than the one trained on").
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.envs import arguments
from navgym.gnss.signal_quality import (
    CA_CHIP_RATE_HZ,
    effective_cn0_dbhz,
    nominal_cn0_dbhz,
    reported_cn0_dbhz,
    sigma_epsilon_variance,
)
from navgym.scenarios import ScenarioBatch, canyon_regime, noise_regime

__all__ = [
    "ReceiverModel",
    "ReceiverPhysics",
    "CN0_OFFSET_MAX_DB",
    "active_segments",
    "check_cn0_offset",
    "cn0_offset_argument",
    "fix_variance_factor",
    "hdop",
    "held",
    "jammer_to_signal_db",
    "receiver_physics",
    "fix_report",
    "trailing_sums",
    "uere_variance_factor",
]


#: Largest magnitude [dB] of a receiver report's C/N0 calibration offset ``cn0_offset_db``: a few dB
#: separate receiver models' C/N0 estimators; 10 dB bounds a plausible miscalibration.
CN0_OFFSET_MAX_DB: float = 10.0


def cn0_offset_argument(kwargs: dict[str, Any]) -> float:
    """The v3 ids' keyword argument ``cn0_offset_db``, popped from ``kwargs`` (default 0) and checked.

    A finite real number in ``[-CN0_OFFSET_MAX_DB, CN0_OFFSET_MAX_DB]``, else the
    :mod:`navgym.envs.arguments` error naming it.
    """
    return arguments.real(
        "cn0_offset_db", kwargs.pop("cn0_offset_db", 0.0), -CN0_OFFSET_MAX_DB, CN0_OFFSET_MAX_DB
    )


def check_cn0_offset(cn0_offset_db: float, context: bool) -> None:
    """Refuse a report offset outside ``[-CN0_OFFSET_MAX_DB, CN0_OFFSET_MAX_DB]`` or without a context.

    A platform calls this from its ``__post_init__``: the offset changes the v3 context's
    receiver report only, so a nonzero one on a platform without the context (``context=False``,
    the v0-v2 ids) would be silently ignored.

    Raises:
        ValueError: naming ``cn0_offset_db``.
    """
    try:
        v = float(cn0_offset_db)
    except (TypeError, ValueError):
        v = math.nan
    if isinstance(cn0_offset_db, (bool, np.bool_)) or not (math.isfinite(v) and abs(v) <= CN0_OFFSET_MAX_DB):
        raise ValueError(
            f"cn0_offset_db must be a finite number in [{-CN0_OFFSET_MAX_DB:g}, {CN0_OFFSET_MAX_DB:g}] dB; "
            f"got {cn0_offset_db!r}"
        )
    if v != 0.0 and not context:
        raise ValueError(
            f"cn0_offset_db={cn0_offset_db!r} shifts the v3 context's reported C/N0; it needs context=True"
        )


def hdop(n_sv: ArrayLike, k_geo: ArrayLike) -> NDArray[np.float64]:
    """``HDOP = k_geo / sqrt(n_sv - 3)`` (module docstring); ``inf`` below 4 satellites."""
    n = np.asarray(n_sv, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n >= 4, np.asarray(k_geo) / np.sqrt(np.maximum(n - 3.0, 1e-300)), np.inf)


def jammer_to_signal_db(
    jam_sigma: ArrayLike, sigma_ref_m: float, cn0_ref_dbhz: float, q: float = 2.0
) -> NDArray[np.float64]:
    """``J/S`` [dB] equivalent to a v2 jamming noise ``jam_sigma`` [m] (module docstring); -inf at 0.

    Args:
        jam_sigma: v2 jamming noise [m], any shape.
        sigma_ref_m: The fix sigma [m] that the jamming variance is added to in v2.
        cn0_ref_dbhz: C/N0 [dB-Hz] at which the SIGMA-epsilon model gives ``sigma_ref_m``.
        q: The jammer's spectral-separation factor ``Q`` (2: broad-band noise).
    """
    base = 10.0 * np.log10(q * CA_CHIP_RATE_HZ) - cn0_ref_dbhz
    with np.errstate(divide="ignore"):
        return base + 20.0 * np.log10(np.asarray(jam_sigma, np.float64) / sigma_ref_m)


def uere_variance_factor(cn0_dbhz: ArrayLike, used: ArrayLike, cn0_ref_dbhz: float) -> NDArray[np.float64]:
    """``u = mean over used satellites of 10^(-(C/N0_i - C/N0_ref)/10)`` along the last axis.

    The SIGMA-epsilon range variance relative to ``C/N0_ref`` (module docstring); ``inf`` where no
    satellite is used.

    Args:
        cn0_dbhz: Per-satellite C/N0 [dB-Hz] ``(..., n_channels)``.
        used: Whether each channel's satellite is used, same shape.
        cn0_ref_dbhz: The reference C/N0 [dB-Hz].
    """
    used = np.asarray(used, bool)
    v = np.where(used, sigma_epsilon_variance(cn0_dbhz, 10.0 ** (cn0_ref_dbhz / 10.0)), 0.0).sum(-1)
    cnt = used.sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(cnt > 0, v / np.maximum(cnt, 1), np.inf)


def held(values: ArrayLike, delivered: ArrayLike, dt: float) -> tuple[NDArray, NDArray[np.float64]]:
    """Forward-fill ``values (B, n, ...)`` from the epochs ``delivered (B, n)`` (epoch 0 counts).

    Returns:
        The held values and their age [s] ``(B, n)``.

    """
    values = np.asarray(values)
    B, n = values.shape[:2]
    k = np.arange(n)
    d = np.array(delivered, bool, copy=True)
    d[:, 0] = True
    last = np.maximum.accumulate(np.where(d, k, 0), axis=1)
    idx = last.reshape(last.shape + (1,) * (values.ndim - 2))
    return np.take_along_axis(values, np.broadcast_to(idx, values.shape), axis=1), (k - last) * dt


def trailing_sums(x: ArrayLike, window: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Sums of ``x (B, T, ...)`` over the steps ``max(0, k - window) .. k - 1`` for ``k = 0 .. T``.

    Returns:
        The sums ``(B, T + 1, ...)`` (0 at ``k = 0``) and the number of steps summed ``(T + 1,)``.

    """
    a = np.asarray(x, np.float64)
    n = a.shape[1]
    out = np.zeros((a.shape[0], n + 1) + a.shape[2:])
    for j in range(min(int(window), n)):  # the window's j-th last step (direct sums: no cumsum drift)
        out[:, j + 1 :] += a[:, : n - j]
    k = np.arange(n + 1)
    return out, k - np.maximum(k - int(window), 0)


class ReceiverModel(NamedTuple):
    """The figures of one simulated receiver (:func:`receiver_physics`); each platform sets its own.

    Attributes:
        visible: Range of the per-episode base count of visible satellites.
        hdop_k: Range of the per-episode geometry factor ``k_geo`` of :func:`hdop`.
        cn0_zenith_dbhz, cn0_horizon_dbhz: Open-sky C/N0 at the zenith and the horizon [dB-Hz].
        min_elevation_deg: Lowest elevation of a satellite in view [deg].
        cn0_ref_dbhz: C/N0 at which the SIGMA-epsilon model gives the nominal fix sigma (DOP 1).
        sat_offset_db: Per-satellite antenna/pattern offset sigma [dB].
        n_channels: Channels (satellites used at most).
        min_visible: Fewest visible satellites in open sky.
        jammer_q: Spectral-separation factor of the jammer (2: broad-band noise).
        los_multipath_probability: Share of multipath segments that are line-of-sight multipath.
        nlos_loss_db, los_loss_db: Loss ranges [dB] of an NLOS and of a line-of-sight segment.
        fading_db: Epoch fading sigma [dB] where a loss acts.
        cn0_estimator_db: Sigma of the receiver's C/N0 estimate [dB].
        stream: Second argument of the receiver's generator ``default_rng([gnss_seed, stream])``.
    """

    visible: tuple[int, int]
    hdop_k: tuple[float, float]
    cn0_zenith_dbhz: float
    cn0_horizon_dbhz: float
    min_elevation_deg: float
    cn0_ref_dbhz: float
    sat_offset_db: float
    n_channels: int = 12
    min_visible: int = 5
    jammer_q: float = 2.0
    los_multipath_probability: float = 0.3
    nlos_loss_db: tuple[float, float] = (4.0, 12.0)
    los_loss_db: tuple[float, float] = (0.0, 1.0)
    fading_db: float = 2.0
    cn0_estimator_db: float = 1.0
    stream: int = 7


class ReceiverPhysics(NamedTuple):
    """The receiver's chain per epoch (``(B, T+1)``) before the delivery mask.

    Attributes:
        n_sv: Satellites used (0 in an outage).
        hdop: HDOP (``inf`` below 4 satellites).
        cn0_true: Mean effective C/N0 of the satellites used [dB-Hz] (NaN without satellites).
        cn0_reported: Mean reported C/N0 of the satellites used [dB-Hz] (NaN likewise).
        uere_factor: ``u``, the mean SIGMA-epsilon variance relative to ``cn0_ref_dbhz`` (inf: none).
        reported_factor: ``u_rep``, the same from the reported C/N0.
    """

    n_sv: NDArray[np.float64]
    hdop: NDArray[np.float64]
    cn0_true: NDArray[np.float64]
    cn0_reported: NDArray[np.float64]
    uere_factor: NDArray[np.float64]
    reported_factor: NDArray[np.float64]


def fix_variance_factor(phys: ReceiverPhysics) -> NDArray[np.float64]:
    """``HDOP^2 u`` of each epoch, the factor of the nominal fix variance; 0 where there is no fix.

    The fix noise of a row is ``sigma_nom HDOP sqrt(u)`` (module docstring); where HDOP or ``u`` is
    not finite (fewer than 4 satellites, none used) the factor is 0 (no fix is delivered there).
    """
    fin = np.isfinite(phys.hdop) & np.isfinite(phys.uere_factor)
    return np.where(fin, phys.hdop, 0.0) ** 2 * np.where(fin, phys.uere_factor, 0.0)


def active_segments(start: NDArray, end: NDArray, tt: NDArray) -> NDArray[np.bool_]:
    """``(B, T, K)``: slot K of episode b active at its time (as :mod:`navgym.scenarios.batch`)."""
    return (start[:, None, :] <= tt[:, :, None]) & (tt[:, :, None] < end[:, None, :])


def receiver_physics(
    model: ReceiverModel,
    seeds: NDArray,
    batch: ScenarioBatch,
    tt: NDArray,
    cap: NDArray,
    sigma_ref_m: float,
    cn0_offset_db: float = 0.0,
) -> ReceiverPhysics:
    """The receiver's chain (module docstring) of B episodes at times ``tt (B, T+1)``.

    Each episode draws from ``np.random.default_rng([seed, model.stream])`` of its GNSS seed
    (its other generators are untouched): the per-episode constants, then the per-epoch normals,
    then two uniforms per multipath segment it has (so a batch equals its single episodes).

    Args:
        model: The receiver's figures.
        seeds: The episodes' GNSS seeds ``(B,)``.
        batch: The episodes' scenarios.
        tt: Epoch times [s] ``(B, T+1)``.
        cap: Satellites the sky allows ``(B, T+1)`` (0 in an outage, a canyon's count in one).
        sigma_ref_m: The nominal horizontal fix sigma [m] (the J/S reference).
        cn0_offset_db: The report's calibration offset [dB] (module docstring): it shifts the
            reported C/N0 and ``u_rep``, not the true C/N0 or ``u``; no extra draws.
    """
    B, n = tt.shape
    c = model.n_channels
    k_geo, n0, amp, period, phase = (np.empty(B) for _ in range(5))
    sin_el, offset = np.empty((B, c)), np.empty((B, c))
    est, fade = np.empty((B, n, c)), np.empty((B, n))
    seg_loss = np.zeros(batch.multipath_start.shape)
    nlos, los_db = model.nlos_loss_db, model.los_loss_db
    for i in range(B):  # per-episode draws from its own generator (not per-step work)
        g = np.random.default_rng([int(seeds[i]), model.stream])
        k_geo[i] = g.uniform(*model.hdop_k)
        n0[i] = g.integers(model.visible[0], model.visible[1] + 1)
        amp[i], period[i], phase[i] = g.uniform(0, 1.5), g.uniform(120, 600), g.uniform(0, 2 * np.pi)
        sin_el[i] = -np.sort(-g.uniform(np.sin(np.deg2rad(model.min_elevation_deg)), 1.0, c))
        offset[i] = g.standard_normal(c) * model.sat_offset_db
        est[i] = g.standard_normal((n, c))
        fade[i] = g.standard_normal(n)
        j = np.flatnonzero(np.isfinite(batch.multipath_start[i]))
        los = g.random(j.size) < model.los_multipath_probability
        u = g.random(j.size)
        seg_loss[i, j] = np.where(los, los_db[0] + u * np.diff(los_db), nlos[0] + u * np.diff(nlos))
    # satellites and geometry
    wave = amp[:, None] * np.sin(2 * np.pi * tt / period[:, None] + phase[:, None])
    n_vis = np.clip(np.round(n0[:, None] + wave), model.min_visible, c)
    n_sv = np.minimum(n_vis, np.asarray(cap, np.float64))
    used = np.arange(c) < n_sv[..., None]  # (B, n, c): the highest n_sv
    dop = hdop(n_sv, k_geo[:, None])
    # attenuation: canyon diffraction + the active multipath segments' loss, with fading
    loss = np.zeros((B, n))
    if np.isfinite(batch.canyon_start).any():
        scale, _ = canyon_regime(batch, tt)
        loss = loss + 20.0 * np.log10(scale)
    if np.isfinite(batch.multipath_start).any():
        a = active_segments(batch.multipath_start, batch.multipath_end, tt)  # (B, n, K)
        loss = loss + np.where(a, seg_loss[:, None, :], 0.0).max(axis=-1)
    loss = np.where(loss > 0, np.maximum(loss + model.fading_db * fade, 0.0), 0.0)
    open_sky = nominal_cn0_dbhz(np.arcsin(sin_el), model.cn0_zenith_dbhz, model.cn0_horizon_dbhz) + offset
    js = jammer_to_signal_db(
        noise_regime(batch, tt).jam_sigma, sigma_ref_m, model.cn0_ref_dbhz, model.jammer_q
    )
    cn0 = effective_cn0_dbhz(open_sky[:, None, :] - loss[..., None], js[..., None], q=model.jammer_q)
    rep = reported_cn0_dbhz(cn0 + cn0_offset_db, est, model.cn0_estimator_db, 1.0)
    # the fix noise factor and the receiver's estimate of it
    cnt = np.maximum(n_sv, 1.0)
    none = n_sv < 1
    with np.errstate(invalid="ignore"):
        cn0_mean = np.where(none, np.nan, np.where(used, cn0, 0.0).sum(-1) / cnt)
        rep_mean = np.where(none, np.nan, np.where(used, rep, 0.0).sum(-1) / cnt)
    u_true = uere_variance_factor(cn0, used, model.cn0_ref_dbhz)
    u_rep = uere_variance_factor(rep, used, model.cn0_ref_dbhz)
    return ReceiverPhysics(n_sv, dop, cn0_mean, rep_mean, u_true, u_rep)


def fix_report(
    phys: ReceiverPhysics, fix: NDArray, row_sigma_nominal: NDArray, dt: float
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """What the receiver reports with each delivered fix, held or zeroed between fixes.

    Args:
        phys: The receiver's chain.
        fix: ``(B, T+1)`` whether a fix was delivered at k.
        row_sigma_nominal: The nominal sigma of the fix's rows ``(r,)`` (at DOP 1, ``u = 1``).
        dt: Step [s].

    Returns:
        ``(n_sv, hdop, age, cn0, sigma)``: satellites used and HDOP of the last fix, held, with its
        age [s] ``(B, T+1)``; the mean reported C/N0 [dB-Hz] ``(B, T+1)`` and the receiver's
        accuracy estimate per row ``HDOP sigma_nominal sqrt(u_rep)`` ``(B, T+1, r)``, 0 where no fix
        was delivered.
    """
    report_ok = fix & (phys.n_sv >= 4)  # a delivered fix always has 4 satellites or more
    n_sv, age = held(np.where(report_ok, phys.n_sv, 0.0), report_ok, dt)
    dop, _ = held(np.where(report_ok, phys.hdop, 0.0), report_ok, dt)
    cn0 = np.where(report_ok, phys.cn0_reported, 0.0)
    with np.errstate(invalid="ignore"):
        sig = (phys.hdop * np.sqrt(phys.reported_factor))[..., None] * row_sigma_nominal
    return n_sv, dop, age, cn0, np.where(report_ok[..., None], sig, 0.0)
