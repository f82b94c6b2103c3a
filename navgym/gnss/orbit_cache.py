"""Satellite orbits on a time grid with cubic Hermite interpolation, for many episode times.

Episodes of a batch run at different GPS times, so every step needs the constellation at B
distinct times: B x S Kepler solves (``almanac_orbit``), the dominant cost of a batched
simulator step. Orbits are smooth, so positions and velocities tabulated every ``step`` seconds
and interpolated with cubic Hermite polynomials (position and its derivative at both ends) are
exact to well below a millimetre: the interpolation error is about ``step^4 |r''''| / 384``
with ``|r''''| ~ n^4 a`` (n the mean motion), i.e. ~4e-6 m for ``step = 30`` s. The table is
built lazily per almanac and covers ``t_ref +- span``; times outside fall back to the exact model.

Each grid interval stores the Hermite cubic in power form, ``r(s) = c0 + c1 s + c2 s^2 + c3 s^3``
with ``s in [0, 1)`` (``c0 = p0``, ``c1 = h v0``, ``c2 = 3 (p1 - p0) - h (2 v0 + v1)``,
``c3 = 2 (p0 - p1) + h (v0 + v1)``, ``h = step``), so a lookup is one gather and a Horner
evaluation. A simulator step needs every satellite's position (to rank them by elevation) but
the velocity of the selected ones only: :meth:`OrbitCache.lookup` returns a
:class:`CachedConstellation` whose :meth:`~CachedConstellation.select` evaluates velocities
for chosen satellites.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.gnss.almanac import Almanac, almanac_orbit, load_default_almanac
from navgym.gnss.orbit import OrbitState


class CachedConstellation(NamedTuple):
    """All satellites' positions at B times, plus what is needed for selected velocities.

    Attributes:
        position: ECEF positions [m], ``(B, S, 3)``.
        coef: The intervals' power-form coefficients ``(B, S, 3, 4)`` (power last).
        s: Position in the interval, ``(B,)`` in [0, 1).
        step: Grid spacing [s].
    """

    position: NDArray[np.float64]
    coef: NDArray[np.float64]
    s: NDArray[np.float64]
    step: float

    def select(self, idx: NDArray[np.int64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Positions and velocities ``(B, m, 3)`` of satellites ``idx (B, m)``.

        The velocities are those of :meth:`velocities`.
        """
        B, m = idx.shape
        S = self.coef.shape[1]
        flat = (idx + S * np.arange(B)[:, None]).ravel()
        pos = np.take(self.position.reshape(B * S, 3), flat, axis=0).reshape(B, m, 3)
        return pos, self.velocities(idx)

    def velocities(self, idx: NDArray[np.int64]) -> NDArray[np.float64]:
        """Velocities ``(B, m, 3)`` of satellites ``idx (B, m)``.

        ``v = (c1 + 2 c2 s + 3 c3 s^2) / h``, evaluated for the selected satellites only
        (a gather of their coefficients and one small product per episode).
        """
        B, m = idx.shape
        S = self.coef.shape[1]
        flat = (idx + S * np.arange(B)[:, None]).ravel()
        c = np.take(self.coef.reshape(B * S, 12), flat, axis=0).reshape(B, m * 3, 4)
        s = self.s
        dpow = np.stack([np.zeros_like(s), np.ones_like(s), 2.0 * s, 3.0 * s * s], axis=1) / self.step
        return (c @ dpow[:, :, None]).reshape(B, m, 3)

    def orbit_state(self) -> OrbitState:
        """The full :class:`~navgym.gnss.orbit.OrbitState` (velocities of every satellite)."""
        B, S = self.coef.shape[:2]
        _, vel = self.select(np.broadcast_to(np.arange(S), (B, S)))
        return OrbitState(self.position, vel, np.full((B, S), np.nan))


class OrbitBuffer(NamedTuple):
    """Per-episode copy of the current interval's coefficients, refreshed on interval change.

    An episode's time advances by one filter step at a time, so it stays in the same grid
    interval for ``step / dt`` steps (30 for 1 s steps): keeping its ``(S, 3, 4)`` coefficients
    saves the gather from the large table (about a third of a lookup at B = 4096) on the other
    steps. Row b holds ``coef[b] = table[interval[b]]`` whenever ``interval[b] >= 0``, so a row
    is valid exactly when its stored interval equals the one looked up: a lookup with a buffer
    returns bit-identical results, whatever wrote the buffer before (a reset episode simply
    finds a different interval and is refreshed). Create one with
    :meth:`OrbitCache.new_buffer`; :meth:`OrbitCache.lookup` updates it in place.

    Attributes:
        interval: Grid interval of each row's coefficients, ``(B,)`` int64 (-1: empty).
        coef: The coefficients ``(B, S, 3, 4)``.
    """

    interval: NDArray[np.int64]
    coef: NDArray[np.float64]


@dataclass
class OrbitCache:
    """Tabulated almanac orbits (see the module docstring).

    Attributes:
        almanac: The constellation.
        step: Grid spacing [s].
        span: Half-width of the tabulated interval around the almanac reference time [s].
    """

    almanac: Almanac
    step: float = 30.0
    span: float = 4 * 86400.0
    _t0: float = field(init=False, default=0.0)
    _coef: np.ndarray | None = field(init=False, default=None, repr=False)
    _ecc: np.ndarray | None = field(init=False, default=None, repr=False)

    def _build(self) -> None:
        t_ref = float(np.median(self.almanac.t_ref))
        self._t0 = t_ref - self.span
        grid = self._t0 + self.step * np.arange(int(np.ceil(2 * self.span / self.step)) + 2)
        orbit = almanac_orbit(self.almanac, grid)  # (G, S, 3)
        p, v = orbit.position, orbit.velocity * self.step
        p0, p1, v0, v1 = p[:-1], p[1:], v[:-1], v[1:]
        self._coef = np.ascontiguousarray(
            np.stack([p0, v0, 3.0 * (p1 - p0) - 2.0 * v0 - v1, 2.0 * (p0 - p1) + v0 + v1], axis=-1)
        )  # (G - 1, S, 3, 4)
        self._ecc = np.unwrap(orbit.eccentric_anomaly, axis=0)

    def _index(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        if self._coef is None:
            self._build()
        u = (t - self._t0) / self.step
        i = np.floor(u).astype(np.int64)
        if t.ndim != 1 or (i < 0).any() or (i >= self._coef.shape[0]).any():
            return None
        return i, u - i

    def new_buffer(self, B: int) -> OrbitBuffer:
        """An empty :class:`OrbitBuffer` for ``B`` episodes."""
        S = self.almanac.prn.shape[0]
        return OrbitBuffer(np.full(B, -1, dtype=np.int64), np.zeros((B, S, 3, 4)))

    def _gather(self, i: np.ndarray, buffer: OrbitBuffer | None) -> np.ndarray:
        if buffer is None:
            return self._coef[i]  # (B, S, 3, 4)
        if buffer.interval.shape != i.shape or buffer.coef.shape[1:] != self._coef.shape[1:]:
            raise ValueError(
                f"buffer holds {buffer.interval.shape[0]} rows of {buffer.coef.shape[1:]}, "
                f"expected {i.shape[0]} rows of {self._coef.shape[1:]}"
            )
        stale = np.flatnonzero(buffer.interval != i)
        if stale.size:
            buffer.coef[stale] = self._coef[i[stale]]
            buffer.interval[stale] = i[stale]
        return buffer.coef

    def _positions(
        self, i: np.ndarray, s: np.ndarray, buffer: OrbitBuffer | None = None
    ) -> CachedConstellation:
        c = self._gather(i, buffer)
        B, S = c.shape[:2]
        powers = np.stack([np.ones_like(s), s, s * s, s * s * s], axis=1)  # (B, 4)
        # one small product per episode: (3 S, 4) @ [1, s, s^2, s^3]
        pos = (c.reshape(B, S * 3, 4) @ powers[:, :, None]).reshape(B, S, 3)
        return CachedConstellation(pos, c, s, self.step)

    def interval_coefficients(
        self, t: ArrayLike, buffer: OrbitBuffer | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The grid intervals' power-form coefficients at GPS times ``t (B,)``, for own evaluation.

        Returns ``(coef (B, S, 3, 4), s (B,))`` with ``r(s) = sum_k coef[..., k] s^k`` and
        ``v = (c1 + 2 c2 s + 3 c3 s^2) / step`` (module docstring), or None for times outside
        the table (use :meth:`lookup`, which falls back to the exact model). With ``buffer`` the
        coefficients are its rows, refreshed in place.
        """
        found = self._index(np.asarray(t, dtype=np.float64))
        if found is None:
            return None
        i, s = found
        return self._gather(i, buffer), s

    def lookup(self, t: ArrayLike, buffer: OrbitBuffer | None = None) -> CachedConstellation | OrbitState:
        """Positions of the constellation at GPS times ``t (B,)``, velocities on demand.

        Args:
            t: GPS seconds, ``(B,)``.
            buffer: Optional :class:`OrbitBuffer` of B rows, updated in place (the result is the
                same with or without it).

        Returns:
            A :class:`CachedConstellation`, or the exact :class:`OrbitState` from
            ``almanac_orbit`` for times outside the table.
        """
        t = np.asarray(t, dtype=np.float64)
        found = self._index(t)
        return almanac_orbit(self.almanac, t) if found is None else self._positions(*found, buffer)

    def __call__(self, t: ArrayLike) -> OrbitState:
        """Constellation at GPS times ``t (B,)``: positions/velocities ``(B, S, 3)``."""
        t = np.asarray(t, dtype=np.float64)
        found = self._index(t)
        if found is None:
            return almanac_orbit(self.almanac, t)
        i, s = found
        state = self._positions(i, s).orbit_state()
        e0, e1 = self._ecc[i], self._ecc[i + 1]
        return state._replace(eccentric_anomaly=e0 + (e1 - e0) * s[:, None])


@functools.cache
def default_orbit_cache() -> OrbitCache:
    """The process-wide :class:`OrbitCache` of the packaged almanac (built on first use)."""
    return OrbitCache(load_default_almanac())
