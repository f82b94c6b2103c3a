"""Scenarios of B episodes as padded arrays, and vectorized per-step evaluation.

:func:`stack_scenarios` turns B :class:`~navgym.scenarios.scenario.Scenario` objects into a
:class:`ScenarioBatch` of arrays ``(B, K)`` (unused interval slots have ``start = +inf``). The
evaluators take times ``t`` as a scalar (shared), ``(B,)`` (one per episode, e.g. sub-environments
after autoreset) or ``(B, T)`` (whole episodes) and return arrays of the same shape, with no
Python loop over episodes or steps.

Where several intervals of one kind overlap, the most severe value applies (smallest satellite
cap, largest contamination, variance ratio, jamming noise, loss and outlier probability and
size, burst sigmas, canyon noise scale and loss; union of outlier PRNs), except multipath:
segments on one row add (biases and variances). A jamming interval's noise and loss are scaled
by its ramp profile (:meth:`~navgym.scenarios.scenario.Jamming.profile`) before that maximum.
Urban canyons cap the satellites like partial outages (:func:`max_satellites`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from filters.core.compiled import compiled_enabled
from navgym.scenarios.scenario import MAX_PRN, Scenario

__all__ = [
    "ScenarioBatch",
    "NoiseRegimeParams",
    "stack_scenarios",
    "gnss_available",
    "max_satellites",
    "satellite_row_mask",
    "noise_regime",
    "motion_burst",
    "multipath_error",
    "canyon_regime",
    "degradation_flags",
    "OUTAGE",
    "PARTIAL_OUTAGE",
    "IMPULSIVE",
    "JAMMING",
    "OUTLIERS",
    "BURST",
    "MULTIPATH",
    "CANYON",
]

#: Bits of :func:`degradation_flags`.
OUTAGE, PARTIAL_OUTAGE, IMPULSIVE, JAMMING, OUTLIERS = 1, 2, 4, 8, 16
#: Bits of :func:`degradation_flags` for the v2 events.
BURST, MULTIPATH, CANYON = 32, 64, 128


class ScenarioBatch(NamedTuple):
    """B scenarios as arrays, batch axis first (K* = interval slots of each kind, >= 1)."""

    duration: NDArray[np.float64]  # (B,)
    mask_deg: NDArray[np.float64]  # (B,)
    max_satellites: NDArray[np.int64]  # (B,)
    critical: NDArray[np.bool_]  # (B,)
    outage_start: NDArray[np.float64]  # (B, Ko)
    outage_end: NDArray[np.float64]
    partial_start: NDArray[np.float64]  # (B, Kp)
    partial_end: NDArray[np.float64]
    partial_satellites: NDArray[np.int64]
    impulsive_start: NDArray[np.float64]  # (B, Ki)
    impulsive_end: NDArray[np.float64]
    impulsive_eps: NDArray[np.float64]
    impulsive_var_ratio: NDArray[np.float64]
    jamming_start: NDArray[np.float64]  # (B, Kj)
    jamming_end: NDArray[np.float64]
    jamming_sigma: NDArray[np.float64]
    jamming_loss: NDArray[np.float64]
    outlier_start: NDArray[np.float64]  # (B, Kq)
    outlier_end: NDArray[np.float64]
    outlier_probability: NDArray[np.float64]
    outlier_scale: NDArray[np.float64]
    outlier_prns: NDArray[np.bool_]  # (B, Kq, MAX_PRN + 1)
    jamming_ramp: NDArray[np.float64]  # (B, Kj) [s], 0 = step
    burst_start: NDArray[np.float64]  # (B, Kb)
    burst_end: NDArray[np.float64]
    burst_velocity_sigma: NDArray[np.float64]
    burst_yaw_rate_sigma: NDArray[np.float64]
    multipath_start: NDArray[np.float64]  # (B, Km)
    multipath_end: NDArray[np.float64]
    multipath_row: NDArray[np.int64]
    multipath_bias: NDArray[np.float64]
    multipath_sigma: NDArray[np.float64]
    canyon_start: NDArray[np.float64]  # (B, Kc)
    canyon_end: NDArray[np.float64]
    canyon_satellites: NDArray[np.int64]
    canyon_noise_scale: NDArray[np.float64]
    canyon_loss: NDArray[np.float64]

    @property
    def batch_size(self) -> int:
        """Number of episodes B."""
        return int(self.duration.shape[0])


class NoiseRegimeParams(NamedTuple):
    """Noise knobs at given times, named as the keyword arguments of ``navgym.gnss.make_regime``.

    Each field has the shape of the query times; ``outlier_prns`` adds an axis of
    ``MAX_PRN + 1`` booleans (column 0 unused). For one step, ``make_regime(B, sigma=...,
    **params._asdict())`` builds the GNSS noise regime.
    """

    eps: NDArray[np.float64]
    var_ratio: NDArray[np.float64]
    jam_sigma: NDArray[np.float64]
    loss_prob: NDArray[np.float64]
    outlier_prob: NDArray[np.float64]
    outlier_scale: NDArray[np.float64]
    outlier_prns: NDArray[np.bool_]


def _slots(items_per_episode: list[tuple], n_fields: int, min_slots: int, fill: list) -> list:
    k = max(min_slots, 1, *(len(items) for items in items_per_episode))
    b = len(items_per_episode)
    out = [np.full((b, k), f, dtype=np.float64) for f in fill]
    for i, items in enumerate(items_per_episode):
        for j, item in enumerate(items):
            for f in range(n_fields):
                out[f][i, j] = item[f]
    return out


def stack_scenarios(scenarios: Sequence[Scenario], min_slots: int = 1) -> ScenarioBatch:
    """Stack B scenarios into padded arrays.

    Args:
        scenarios: One :class:`Scenario` per episode.
        min_slots: Minimum interval slots per kind (pad to a fixed size to swap episodes in
            and out of a batch with :func:`navgym.motion.trajectory.replace_episodes`).

    Returns:
        :class:`ScenarioBatch`.

    Raises:
        ValueError: If ``scenarios`` is empty or holds something else.

    """
    sc = list(scenarios)
    if not sc or not all(isinstance(s, Scenario) for s in sc):
        raise ValueError("scenarios must be a non-empty sequence of Scenario")
    inf = np.inf
    o = _slots([[(x.start, x.end) for x in s.outages] for s in sc], 2, min_slots, [inf, inf])
    p = _slots(
        [[(x.start, x.end, x.max_satellites) for x in s.partial_outages] for s in sc],
        3,
        min_slots,
        [inf, inf, 0.0],
    )
    i = _slots(
        [[(x.start, x.end, x.eps, x.var_ratio) for x in s.impulsive] for s in sc],
        4,
        min_slots,
        [inf, inf, 0.0, 1.0],
    )
    j = _slots(
        [[(x.start, x.end, x.jam_sigma, x.loss_prob) for x in s.jamming] for s in sc],
        4,
        min_slots,
        [inf, inf, 0.0, 0.0],
    )
    q = _slots(
        [[(x.start, x.end, x.probability, x.scale) for x in s.outliers] for s in sc],
        4,
        min_slots,
        [inf, inf, 0.0, 0.0],
    )
    prns = np.zeros(q[0].shape + (MAX_PRN + 1,), dtype=bool)
    for b, s in enumerate(sc):
        for k, x in enumerate(s.outliers):
            prns[b, k, list(x.prns)] = True
    (ramp,) = _slots([[(x.ramp,) for x in s.jamming] for s in sc], 1, j[0].shape[1], [0.0])
    bu = _slots(
        [[(x.start, x.end, x.velocity_sigma, x.yaw_rate_sigma) for x in s.bursts] for s in sc],
        4,
        min_slots,
        [inf, inf, 0.0, 0.0],
    )
    mp = _slots(
        [[(x.start, x.end, x.row, x.bias, x.sigma) for x in s.multipath] for s in sc],
        5,
        min_slots,
        [inf, inf, 0.0, 0.0, 0.0],
    )
    ca = _slots(
        [[(x.start, x.end, x.max_satellites, x.noise_scale, x.loss_prob) for x in s.canyons] for s in sc],
        5,
        min_slots,
        [inf, inf, 0.0, 1.0, 0.0],
    )
    return ScenarioBatch(
        np.array([s.duration for s in sc], np.float64),
        np.array([s.mask_deg for s in sc], np.float64),
        np.array([s.max_satellites for s in sc], np.int64),
        np.array([s.critical for s in sc], bool),
        o[0],
        o[1],
        p[0],
        p[1],
        p[2].astype(np.int64),
        *i,
        *j,
        *q,
        prns,
        ramp,
        *bu,
        mp[0],
        mp[1],
        mp[2].astype(np.int64),
        mp[3],
        mp[4],
        ca[0],
        ca[1],
        ca[2].astype(np.int64),
        ca[3],
        ca[4],
    )


def _times(batch: ScenarioBatch, t: ArrayLike) -> tuple[NDArray[np.float64], tuple[int, ...]]:
    """Times as ``(B, T)`` plus the output shape (``(B,)`` or ``(B, T)``)."""
    b = batch.batch_size
    t = np.asarray(t, np.float64)
    if t.ndim == 0:
        return np.full((b, 1), float(t)), (b,)
    if t.ndim == 1 and t.shape[0] == b:
        return t[:, None], (b,)
    if t.ndim == 2 and t.shape[0] in (1, b):
        return np.broadcast_to(t, (b, t.shape[1])), (b, t.shape[1])
    raise ValueError(f"t must be a scalar, ({b},) or ({b}, T), got shape {t.shape}")


def _active(start: NDArray, end: NDArray, t: NDArray) -> NDArray[np.bool_]:
    """``(B, T, K)``: interval k of episode b active at its t."""
    tt = t[:, :, None]
    return (start[:, None, :] <= tt) & (tt < end[:, None, :])


def _severest(active: NDArray, values: NDArray, neutral: float) -> NDArray:
    return np.where(active, values[:, None, :], neutral).max(axis=-1)


def gnss_available(batch: ScenarioBatch, t: ArrayLike) -> NDArray[np.bool_]:
    """False where a full outage is active, True elsewhere; shape of ``t`` (see module)."""
    tt, shape = _times(batch, t)
    return (~_active(batch.outage_start, batch.outage_end, tt).any(axis=-1)).reshape(shape)


def max_satellites(batch: ScenarioBatch, t: ArrayLike) -> NDArray[np.int64]:
    """Usable satellites at most: 0 in a full outage, the partial-outage or canyon cap, else channels."""
    tt, shape = _times(batch, t)
    cap = np.where(
        _active(batch.partial_start, batch.partial_end, tt),
        batch.partial_satellites[:, None, :],
        np.iinfo(np.int64).max,
    ).min(axis=-1)
    cap = np.minimum(cap, batch.max_satellites[:, None])
    if np.isfinite(batch.canyon_start).any():
        canyon = np.where(
            _active(batch.canyon_start, batch.canyon_end, tt),
            batch.canyon_satellites[:, None, :],
            np.iinfo(np.int64).max,
        ).min(axis=-1)
        cap = np.minimum(cap, canyon)
    out = np.where(_active(batch.outage_start, batch.outage_end, tt).any(axis=-1), 0, cap)
    return out.reshape(shape)


def satellite_row_mask(batch: ScenarioBatch, t: ArrayLike, m_max: int) -> NDArray[np.bool_]:
    """Rows of an ``m_max``-row measurement vector the scenario lets through, ``t.shape + (m,)``.

    Rows are ordered by decreasing elevation (``navgym.gnss.simulate_gnss_step``), so capping
    to k satellites keeps the k highest: ``row < max_satellites(batch, t)``. AND it with the
    receiver's own mask.
    """
    if int(m_max) < 1:
        raise ValueError(f"m_max must be >= 1, got {m_max!r}")
    k = max_satellites(batch, t)
    return np.arange(int(m_max)) < k[..., None]


def noise_regime(batch: ScenarioBatch, t: ArrayLike) -> NoiseRegimeParams:
    """Noise knobs at times ``t`` (neutral values where nothing is active).

    Returns:
        :class:`NoiseRegimeParams`: contamination ``eps`` and ``var_ratio`` (Benzerrouk 2014, eq. 71),
        ``jam_sigma`` [m] and ``loss_prob`` (scaled by each jamming's ramp profile), ``outlier_prob``,
        ``outlier_scale`` [m] of the shape of ``t``, and ``outlier_prns`` with a trailing
        ``MAX_PRN + 1`` axis.

    """
    tt, shape = _times(batch, t)
    a_i = _active(batch.impulsive_start, batch.impulsive_end, tt)
    a_j = _active(batch.jamming_start, batch.jamming_end, tt)
    a_q = _active(batch.outlier_start, batch.outlier_end, tt)
    prns = (a_q[..., None] & batch.outlier_prns[:, None, :, :]).any(axis=2)
    if (batch.jamming_ramp > 0.0).any():
        ramp = batch.jamming_ramp[:, None, :]
        edge = np.minimum(
            tt[:, :, None] - batch.jamming_start[:, None, :], batch.jamming_end[:, None, :] - tt[:, :, None]
        )
        with np.errstate(divide="ignore", invalid="ignore"):
            profile = np.where(ramp > 0.0, np.clip(edge / ramp, 0.0, 1.0), 1.0)
        jam_sigma = np.where(a_j, batch.jamming_sigma[:, None, :] * profile, 0.0).max(axis=-1)
        jam_loss = np.where(a_j, batch.jamming_loss[:, None, :] * profile, 0.0).max(axis=-1)
    else:  # step profiles: the values themselves
        jam_sigma = _severest(a_j, batch.jamming_sigma, 0.0)
        jam_loss = _severest(a_j, batch.jamming_loss, 0.0)
    return NoiseRegimeParams(
        _severest(a_i, batch.impulsive_eps, 0.0).reshape(shape),
        _severest(a_i, batch.impulsive_var_ratio, 1.0).reshape(shape),
        jam_sigma.reshape(shape),
        jam_loss.reshape(shape),
        _severest(a_q, batch.outlier_probability, 0.0).reshape(shape),
        _severest(a_q, batch.outlier_scale, 0.0).reshape(shape),
        prns.reshape(shape + (MAX_PRN + 1,)),
    )


def motion_burst(batch: ScenarioBatch, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unmodelled motion at times ``t``: ``(velocity_sigma [m/s], yaw_rate_sigma [rad/s])``.

    Each of the shape of ``t``, 0 where no burst is active (the largest where several are).
    """
    tt, shape = _times(batch, t)
    a = _active(batch.burst_start, batch.burst_end, tt)
    return (
        _severest(a, batch.burst_velocity_sigma, 0.0).reshape(shape),
        _severest(a, batch.burst_yaw_rate_sigma, 0.0).reshape(shape),
    )


def multipath_error(
    batch: ScenarioBatch, t: ArrayLike, m_max: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Multipath on the rows of an ``m_max``-row measurement vector: ``(bias [m], variance [m^2])``.

    Each of shape ``t.shape + (m_max,)``: the sum of the active segments' biases and of their
    ``sigma**2`` on each row, 0 elsewhere. A segment on a row ``>= m_max`` raises ``ValueError``.
    """
    m = int(m_max)
    if m < 1:
        raise ValueError(f"m_max must be >= 1, got {m_max!r}")
    used = np.isfinite(batch.multipath_start)
    if (batch.multipath_row[used] >= m).any():
        raise ValueError(
            f"a multipath segment is on row {int(batch.multipath_row[used].max())}; the measurement "
            f"vector has {m} rows (0..{m - 1})"
        )
    tt, shape = _times(batch, t)
    if compiled_enabled():  # the same sums in one loop (navgym.scenarios.multipath_kernel)
        from navgym.scenarios.multipath_kernel import multipath_pass  # numba: on first use

        B, T = tt.shape
        bias_c, var_c = np.zeros((B, T, m)), np.zeros((B, T, m))
        seg = [np.ascontiguousarray(a, np.float64) for a in (batch.multipath_start, batch.multipath_end)]
        seg.append(np.ascontiguousarray(batch.multipath_row, np.int64))
        seg += [np.ascontiguousarray(a, np.float64) for a in (batch.multipath_bias, batch.multipath_sigma)]
        multipath_pass(*seg, np.ascontiguousarray(tt), bias_c, var_c)
        return bias_c.reshape(shape + (m,)), var_c.reshape(shape + (m,))
    a = _active(batch.multipath_start, batch.multipath_end, tt)  # (B, T, K)
    on_row = batch.multipath_row[:, None, :, None] == np.arange(m)  # (B, 1, K, m)
    hit = a[..., None] & on_row
    bias = np.where(hit, batch.multipath_bias[:, None, :, None], 0.0).sum(axis=2)
    var = np.where(hit, batch.multipath_sigma[:, None, :, None] ** 2, 0.0).sum(axis=2)
    return bias.reshape(shape + (m,)), var.reshape(shape + (m,))


def canyon_regime(batch: ScenarioBatch, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Urban canyons at times ``t``: ``(noise_scale, loss_prob)`` (1 and 0 outside every canyon).

    The satellite cap is in :func:`max_satellites`.
    """
    tt, shape = _times(batch, t)
    a = _active(batch.canyon_start, batch.canyon_end, tt)
    return (
        _severest(a, batch.canyon_noise_scale, 1.0).reshape(shape),
        _severest(a, batch.canyon_loss, 0.0).reshape(shape),
    )


def degradation_flags(batch: ScenarioBatch, t: ArrayLike) -> NDArray[np.int64]:
    """Bit flags of what is active (OUTAGE 1, PARTIAL_OUTAGE 2, IMPULSIVE 4, JAMMING 8, OUTLIERS 16).

    And of the v2 events: BURST 32, MULTIPATH 64, CANYON 128.
    """
    tt, shape = _times(batch, t)
    flags = np.zeros(tt.shape, np.int64)
    for bit, start, end in (
        (OUTAGE, batch.outage_start, batch.outage_end),
        (PARTIAL_OUTAGE, batch.partial_start, batch.partial_end),
        (IMPULSIVE, batch.impulsive_start, batch.impulsive_end),
        (JAMMING, batch.jamming_start, batch.jamming_end),
        (OUTLIERS, batch.outlier_start, batch.outlier_end),
        (BURST, batch.burst_start, batch.burst_end),
        (MULTIPATH, batch.multipath_start, batch.multipath_end),
        (CANYON, batch.canyon_start, batch.canyon_end),
    ):
        flags |= np.where(_active(start, end, tt).any(axis=-1), bit, 0)
    return flags.reshape(shape)
