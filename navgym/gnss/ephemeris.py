"""Broadcast-ephemeris satellite positions and clocks (IS-GPS-200 §20.3.3.3.3, Table 20-IV).

Works on :class:`~navgym.gnss.rinex.BroadcastEphemeris` arrays: :func:`select_ephemeris`
picks, for every (time, PRN) pair, the record with the nearest ``t_oe``; :func:`take_ephemeris`
gathers those records into arrays of the query shape, which :func:`ephemeris_orbit` and
:func:`ephemeris_clock` evaluate without Python loops.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.gnss.orbit import RELATIVISTIC_F, OrbitState, keplerian_orbit
from navgym.gnss.rinex import BroadcastEphemeris

__all__ = [
    "MAX_EPHEMERIS_AGE_S",
    "select_ephemeris",
    "take_ephemeris",
    "ephemeris_orbit",
    "ephemeris_clock",
]

#: Largest |t - t_oe| accepted when selecting an ephemeris [s] (a 4-hour fit interval).
MAX_EPHEMERIS_AGE_S: float = 7200.0


def select_ephemeris(
    eph: BroadcastEphemeris, prn: ArrayLike, t: ArrayLike, healthy_only: bool = True
) -> NDArray[np.int64]:
    """Index of the ephemeris record to use for each (PRN, time) query.

    The record of the same PRN with the smallest ``|t - t_oe|`` (at most
    :data:`MAX_EPHEMERIS_AGE_S`), healthy if ``healthy_only``; ``-1`` where none qualifies.

    Args:
        eph: Broadcast ephemerides over records ``(R,)``.
        prn: PRN numbers, any shape (0 or negative = empty slot).
        t: GPS seconds, broadcastable with ``prn``.
        healthy_only: Skip records whose health word is non-zero.

    Returns:
        Record indices, int, broadcast shape of ``prn`` and ``t``; -1 for no ephemeris.
    """
    prn, t = np.broadcast_arrays(np.asarray(prn), np.asarray(t, np.float64))
    dt = np.abs(t[..., None] - eph.toe)  # (..., R)
    ok = (prn[..., None] == eph.prn) & (dt <= MAX_EPHEMERIS_AGE_S)
    if healthy_only:
        ok &= eph.health == 0
    dt = np.where(ok, dt, np.inf)
    idx = np.argmin(dt, axis=-1)
    return np.where(np.any(ok, axis=-1), idx, -1)


def take_ephemeris(eph: BroadcastEphemeris, index: ArrayLike) -> BroadcastEphemeris:
    """Gather records: every field becomes ``field[index]`` (any index shape; -1 -> record 0)."""
    idx = np.maximum(np.asarray(index), 0)
    return BroadcastEphemeris(*(np.asarray(f)[idx] for f in eph))


def ephemeris_orbit(eph: BroadcastEphemeris, t: ArrayLike) -> OrbitState:
    """Satellite ECEF position and velocity from broadcast ephemerides at GPS times ``t``.

    IS-GPS-200 Table 20-IV with the harmonic corrections (see
    :func:`navgym.gnss.orbit.keplerian_orbit`); ``t_k = t - t_oe`` on the continuous scale.
    ``t`` is the signal *transmission* time when positions feed a pseudo-range model.

    Args:
        eph: Gathered ephemerides (shape ``(...)``, see :func:`take_ephemeris`).
        t: GPS seconds, broadcastable with the ephemeris shape.

    Returns:
        :class:`~navgym.gnss.orbit.OrbitState`.
    """
    tk = np.asarray(t, np.float64) - eph.toe
    return keplerian_orbit(
        tk,
        eph.sqrt_a,
        eph.e,
        eph.m0,
        eph.omega,
        eph.i0,
        eph.omega0,
        eph.omega_dot,
        eph.toe_sow,
        delta_n=eph.delta_n,
        idot=eph.idot,
        cuc=eph.cuc,
        cus=eph.cus,
        crc=eph.crc,
        crs=eph.crs,
        cic=eph.cic,
        cis=eph.cis,
    )


def ephemeris_clock(
    eph: BroadcastEphemeris,
    t: ArrayLike,
    eccentric_anomaly: ArrayLike | None = None,
    l1_group_delay: bool = True,
) -> NDArray[np.float64]:
    """Satellite clock offset dt_sv [s] for L1 C/A users.

    IS-GPS-200 §20.3.3.3.3.1 and §20.3.3.3.3.2::

        dt_sv = a_f0 + a_f1 (t - t_oc) + a_f2 (t - t_oc)^2 + dt_r,  dt_r = F e sqrt(A) sin E_k
        (dt_sv)_L1 = dt_sv - T_GD

    The corrected pseudo-range is ``P + c (dt_sv)_L1``.

    Args:
        eph: Gathered ephemerides.
        t: GPS seconds (transmission time), broadcastable with the ephemeris shape.
        eccentric_anomaly: E_k from :func:`ephemeris_orbit`; computed if omitted.
        l1_group_delay: Subtract T_GD (single-frequency L1 users).

    Returns:
        Clock offsets [s], broadcast shape.
    """
    t = np.asarray(t, np.float64)
    if eccentric_anomaly is None:
        eccentric_anomaly = ephemeris_orbit(eph, t).eccentric_anomaly
    dt = t - eph.toc
    dts = eph.af0 + eph.af1 * dt + eph.af2 * dt * dt
    dts = dts + RELATIVISTIC_F * eph.e * eph.sqrt_a * np.sin(eccentric_anomaly)
    if l1_group_delay:
        dts = dts - eph.tgd
    return dts
