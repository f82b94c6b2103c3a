"""Satellite visibility, fixed-size selection with a mask, and dilution of precision.

Measurements use ``m_max`` rows (default 12) and a boolean mask ``(B, m_max)``; see
:func:`select_satellites` for the ordering rule.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from filters.core.linalg import gram, trace_of_spd_inverse
from navgym.geo.frames import ecef_to_geodetic, ecef_to_ned_matrix

__all__ = [
    "DEFAULT_M_MAX",
    "Dop",
    "check_mask_angle",
    "visible",
    "count_visible",
    "select_satellites",
    "rank_satellites",
    "dop",
]

#: Default number of measurement rows (a 12-channel receiver).
DEFAULT_M_MAX: int = 12


def check_mask_angle(mask_deg: ArrayLike) -> NDArray[np.float64]:
    """Validate an elevation mask angle in degrees: finite and in [0, 90).

    Raises:
        ValueError: Naming ``mask_deg`` when any value is outside [0, 90) or not finite.
    """
    m = np.asarray(mask_deg, np.float64)
    if not np.all(np.isfinite(m)) or np.any(m < 0.0) or np.any(m >= 90.0):
        raise ValueError(f"mask_deg must be in [0, 90) degrees, got {mask_deg!r}")
    return m


def visible(elevation: ArrayLike, mask_deg: ArrayLike) -> NDArray[np.bool_]:
    """Visibility above a mask angle: ``theta > mask`` (Carvalho et al. 1997, §IV-C-1).

    Args:
        elevation: Elevation angles [rad], any shape.
        mask_deg: Mask angle [deg], broadcastable (e.g. per episode ``(B, 1)``).

    Returns:
        Boolean array of the broadcast shape.

    Raises:
        ValueError: Naming ``mask_deg`` if it lies outside [0, 90).
    """
    m = check_mask_angle(mask_deg)
    return np.asarray(elevation, np.float64) > np.deg2rad(m)


def count_visible(elevation: ArrayLike, mask_deg: ArrayLike) -> NDArray[np.int64]:
    """Number of satellites above the mask along the last axis."""
    return visible(elevation, mask_deg).sum(axis=-1)


def select_satellites(
    elevation: ArrayLike,
    mask_deg: ArrayLike,
    m_max: int = DEFAULT_M_MAX,
    available: ArrayLike | None = None,
    sort_by_prn: bool = False,
    prn: ArrayLike | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Choose up to ``m_max`` satellites per receiver: the highest above the mask.

    Ordering: rows hold satellites by decreasing elevation, ties (equal to ~1e-14 in sin el)
    by ascending satellite index. With ``sort_by_prn`` the selected rows are re-ordered by
    ascending PRN (rows then change less often between steps). Rows past the number of
    visible satellites hold the next satellites below the mask (by elevation) with
    ``mask = False``, so every index is valid.

    Args:
        elevation: Elevations [rad], ``(..., S)``.
        mask_deg: Mask angle [deg], broadcastable with ``elevation[..., :1]``.
        m_max: Number of rows (>= 1; clipped to S).
        available: Optional bool ``(..., S)``; False removes a satellite (e.g. unhealthy).
        sort_by_prn: Re-order the selected rows by PRN.
        prn: PRN per satellite ``(S,)`` or ``(..., S)`` (needed with ``sort_by_prn``).

    Returns:
        ``(index, mask)``: satellite indices into the last axis, int ``(..., m)``, and the
        visibility mask, bool ``(..., m)``, with ``m = min(m_max, S)``.

    Raises:
        ValueError: Naming ``mask_deg`` or ``m_max`` for bad values.
    """
    if int(m_max) < 1:
        raise ValueError(f"m_max must be >= 1, got {m_max}")
    el = np.asarray(elevation, np.float64)
    m_rad = np.deg2rad(check_mask_angle(mask_deg))
    order, mask = rank_satellites(el, m_rad, m_max, available)
    if sort_by_prn:
        if prn is None:
            raise ValueError("prn is required with sort_by_prn=True")
        p = np.broadcast_to(np.asarray(prn), el.shape)
        p_sel = np.take_along_axis(p, order, axis=-1)
        # Visible rows first (by PRN), then the masked ones.
        k = np.argsort(np.where(mask, p_sel, p_sel + 10_000), axis=-1, kind="stable")
        order = np.take_along_axis(order, k, axis=-1)
        mask = np.take_along_axis(mask, k, axis=-1)
    return order, mask


def rank_satellites(
    score: ArrayLike,
    threshold: ArrayLike,
    m_max: int = DEFAULT_M_MAX,
    available: ArrayLike | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Top-``m_max`` satellites by a score increasing with elevation (el, sin el, ...).

    The kernel of :func:`select_satellites`: ``visible = score > threshold`` (and
    ``available``); rows sorted by decreasing score, ties by satellite index, so the visible
    satellites come first and the rows after them hold the next ones below the mask
    (unavailable satellites last). Scores must lie in [-1, 1] (elevation in rad or a sine).

    Args:
        score: ``(..., S)``.
        threshold: Broadcastable with ``score`` (mask angle in the same units).
        m_max: Number of rows (clipped to S).
        available: Optional bool ``(..., S)``.

    Returns:
        ``(index (..., m), mask (..., m))``.
    """
    sc = np.asarray(score, np.float64)
    vis = sc > threshold
    n = sc.shape[-1]
    m = min(int(m_max), n)
    # Keys 2 - score in [1, 3] (unavailable: 10 + index). Positive floats order like their bit
    # patterns, so the satellite index goes into the 6 lowest mantissa bits (a 2^-46 relative
    # quantisation) and one integer sort ranks everything, ties by index.
    key = 2.0 - sc
    if available is not None:
        avail = np.asarray(available, bool)
        vis = vis & avail
        key = np.where(avail, key, 10.0 + np.arange(n))
    if n <= 64:
        bits = (key.view(np.int64) & ~np.int64(63)) | np.arange(n)
        order = np.sort(bits, axis=-1)[..., :m] & 63
    else:
        order = np.argsort(key, axis=-1, kind="stable")[..., :m]
    n_vis = np.minimum(vis.sum(axis=-1, keepdims=True), m)
    return order, np.arange(m) < n_vis


class Dop(NamedTuple):
    """Dilution of precision, each ``(...)``; ``inf`` where fewer than 4 usable satellites.

    Attributes:
        gdop: sqrt(trace Q).
        pdop: sqrt(Q_NN + Q_EE + Q_DD).
        hdop: sqrt(Q_NN + Q_EE).
        vdop: sqrt(Q_DD).
        tdop: sqrt(Q_bb).
    """

    gdop: NDArray[np.float64]
    pdop: NDArray[np.float64]
    hdop: NDArray[np.float64]
    vdop: NDArray[np.float64]
    tdop: NDArray[np.float64]


def dop(rx_ecef: ArrayLike, sat_ecef: ArrayLike, mask: ArrayLike | None = None) -> Dop:
    """Dilution of precision from the geometry matrix in local NED axes.

    ``G`` has rows ``[-u_N, -u_E, -u_D, 1]`` (u the unit line of sight, Kaplan & Hegarty,
    "Understanding GPS", 2nd ed., §7.3.1); ``Q = (G^T W G)^-1`` with W the 0/1 mask, and
    GDOP = sqrt(tr Q), PDOP, HDOP, VDOP, TDOP from its diagonal. Carvalho et al. 1997, §V: with fewer than
    4 satellites the geometry is not invertible and GDOP is undefined (returned as ``inf``).

    Args:
        rx_ecef: Receiver positions [m], ``(..., 3)``.
        sat_ecef: Satellite positions [m], ``(..., m, 3)``.
        mask: Usable rows, bool ``(..., m)`` (all if None).

    Returns:
        :class:`Dop` of shape ``(...)``.
    """
    rx = np.asarray(rx_ecef, np.float64)
    sat = np.asarray(sat_ecef, np.float64)
    lat, lon, _ = ecef_to_geodetic(rx)
    c = ecef_to_ned_matrix(lat, lon)
    d = sat - rx[..., None, :]
    u = np.einsum("...ij,...mj->...mi", c, d) / np.linalg.norm(d, axis=-1, keepdims=True)
    g = np.concatenate([-u, np.ones(u.shape[:-1] + (1,))], axis=-1)
    w = np.ones(g.shape[:-1]) if mask is None else np.asarray(mask, np.float64)
    n = np.einsum("...mi,...m,...mj->...ij", g, w, g)
    enough = (w > 0).sum(axis=-1) >= 4
    cond_ok = enough & (np.linalg.cond(np.where(enough[..., None, None], n, np.eye(4))) < 1e12)
    q = np.linalg.inv(np.where(cond_ok[..., None, None], n, np.eye(4)))
    diag = np.where(cond_ok[..., None], np.diagonal(q, axis1=-2, axis2=-1), np.inf)
    return Dop(
        np.sqrt(diag.sum(axis=-1)),
        np.sqrt(diag[..., :3].sum(axis=-1)),
        np.sqrt(diag[..., :2].sum(axis=-1)),
        np.sqrt(diag[..., 2]),
        np.sqrt(diag[..., 3]),
    )


def gdop(rx_ecef: np.ndarray, sat_ecef: np.ndarray, mask: np.ndarray) -> NDArray[np.float64]:
    """Geometric dilution of precision ``sqrt(tr (G^T W G)^-1)``, G rows ``[-u^T, 1]``, batched.

    The GDOP of :func:`dop` (it is invariant to the axes of u, so no local frame is needed)
    for the per-step use of the environments: ``A = G^T W G`` is formed from component-first
    ``(B, m)`` arrays and ``tr A^-1`` by an element-wise 4 x 4 Cholesky over the whole batch
    (:func:`filters.core.linalg.trace_of_spd_inverse`) instead of B LAPACK calls in NumPy's
    loop. ``inf`` with fewer than 4 usable satellites or a degenerate geometry.

    Args:
        rx_ecef: receiver positions ``(B, 3)`` [m].
        sat_ecef: satellite positions ``(B, m, 3)`` [m].
        mask: usable rows ``(B, m)`` (bool).

    Returns:
        ``(B,)`` GDOP values.
    """
    rx = np.asarray(rx_ecef, np.float64)
    sat = np.asarray(sat_ecef, np.float64)
    w = np.asarray(mask).astype(np.float64)
    d = [sat[..., i] - rx[:, i : i + 1] for i in range(3)]  # component-first (B, m) arrays
    scale = w / np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    # A = G^T W G = Gw Gw^T with the columns of Gw (B, 4, m) the rows [-u^T, 1] times the 0/1
    # weight (w^2 = w): one batched product instead of ten short reductions.
    Gw = np.empty((w.shape[0], 4, w.shape[1]))
    for i in range(3):
        np.multiply(d[i], -scale, out=Gw[:, i])  # minus the unit line of sight, 0 where masked
    Gw[:, 3] = w
    A = gram(Gw)
    ok = A[:, 3, 3] >= 4
    tr = trace_of_spd_inverse(np.where(ok[:, None, None], A, np.eye(4)))
    return np.where(ok & np.isfinite(tr) & (tr > 0), np.sqrt(np.abs(tr)), np.inf)
