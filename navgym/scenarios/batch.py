"""Scenarios of B episodes as padded arrays, and vectorized per-step evaluation.

:func:`stack_scenarios` turns B :class:`~navgym.scenarios.scenario.Scenario` objects into a
:class:`ScenarioBatch` of arrays ``(B, K)`` (unused interval slots have ``start = +inf``). The
evaluators take times ``t`` as a scalar (shared), ``(B,)`` (one per episode, e.g. sub-environments
after autoreset) or ``(B, T)`` (whole episodes) and return arrays of the same shape, with no
Python loop over episodes or steps.

Where several intervals of one kind overlap, the most severe value applies (smallest satellite
cap, largest contamination, variance ratio, jamming noise, loss and outlier probability and
size; union of outlier PRNs).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.scenarios.scenario import MAX_PRN, Scenario

__all__ = [
    "ScenarioBatch",
    "NoiseRegimeParams",
    "stack_scenarios",
    "gnss_available",
    "max_satellites",
    "satellite_row_mask",
    "noise_regime",
    "degradation_flags",
    "OUTAGE",
    "PARTIAL_OUTAGE",
    "IMPULSIVE",
    "JAMMING",
    "OUTLIERS",
]

#: Bits of :func:`degradation_flags`.
OUTAGE, PARTIAL_OUTAGE, IMPULSIVE, JAMMING, OUTLIERS = 1, 2, 4, 8, 16


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
    """Usable satellites at most: 0 in a full outage, the partial-outage cap, else channels."""
    tt, shape = _times(batch, t)
    cap = np.where(
        _active(batch.partial_start, batch.partial_end, tt),
        batch.partial_satellites[:, None, :],
        np.iinfo(np.int64).max,
    ).min(axis=-1)
    cap = np.minimum(cap, batch.max_satellites[:, None])
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
        ``jam_sigma`` [m], ``loss_prob``, ``outlier_prob``, ``outlier_scale`` [m] of the shape of
        ``t``, and ``outlier_prns`` with a trailing ``MAX_PRN + 1`` axis.

    """
    tt, shape = _times(batch, t)
    a_i = _active(batch.impulsive_start, batch.impulsive_end, tt)
    a_j = _active(batch.jamming_start, batch.jamming_end, tt)
    a_q = _active(batch.outlier_start, batch.outlier_end, tt)
    prns = (a_q[..., None] & batch.outlier_prns[:, None, :, :]).any(axis=2)
    return NoiseRegimeParams(
        _severest(a_i, batch.impulsive_eps, 0.0).reshape(shape),
        _severest(a_i, batch.impulsive_var_ratio, 1.0).reshape(shape),
        _severest(a_j, batch.jamming_sigma, 0.0).reshape(shape),
        _severest(a_j, batch.jamming_loss, 0.0).reshape(shape),
        _severest(a_q, batch.outlier_probability, 0.0).reshape(shape),
        _severest(a_q, batch.outlier_scale, 0.0).reshape(shape),
        prns.reshape(shape + (MAX_PRN + 1,)),
    )


def degradation_flags(batch: ScenarioBatch, t: ArrayLike) -> NDArray[np.int64]:
    """Bit flags of what is active: OUTAGE 1, PARTIAL_OUTAGE 2, IMPULSIVE 4, JAMMING 8, OUTLIERS 16."""
    tt, shape = _times(batch, t)
    flags = np.zeros(tt.shape, np.int64)
    for bit, start, end in (
        (OUTAGE, batch.outage_start, batch.outage_end),
        (PARTIAL_OUTAGE, batch.partial_start, batch.partial_end),
        (IMPULSIVE, batch.impulsive_start, batch.impulsive_end),
        (JAMMING, batch.jamming_start, batch.jamming_end),
        (OUTLIERS, batch.outlier_start, batch.outlier_end),
    ):
        flags |= np.where(_active(start, end, tt).any(axis=-1), bit, 0)
    return flags.reshape(shape)
