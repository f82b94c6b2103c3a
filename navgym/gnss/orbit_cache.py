"""Satellite orbits on a time grid with cubic Hermite interpolation, for many episode times.

Episodes of a batch run at different GPS times, so every step needs the constellation at B
distinct times: B x S Kepler solves (``almanac_orbit``), the dominant cost of a batched
simulator step. Orbits are smooth, so positions and velocities tabulated every ``step`` seconds
and interpolated with cubic Hermite polynomials (position and its derivative at both ends) are
exact to well below a millimetre: the interpolation error is about ``step^4 |r''''| / 384``
with ``|r''''| ~ n^4 a`` (n the mean motion), i.e. ~4e-6 m for ``step = 30`` s. The table is
built lazily per almanac and covers ``t_ref +- span``; times outside fall back to the exact model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from navgym.gnss.almanac import Almanac, almanac_orbit
from navgym.gnss.orbit import OrbitState


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
    _pos: np.ndarray | None = field(init=False, default=None, repr=False)
    _vel: np.ndarray | None = field(init=False, default=None, repr=False)
    _ecc: np.ndarray | None = field(init=False, default=None, repr=False)

    def _build(self) -> None:
        t_ref = float(np.median(self.almanac.t_ref))
        self._t0 = t_ref - self.span
        grid = self._t0 + self.step * np.arange(int(np.ceil(2 * self.span / self.step)) + 2)
        orbit = almanac_orbit(self.almanac, grid)  # (G, S, 3)
        self._pos, self._vel = orbit.position, orbit.velocity
        self._ecc = np.unwrap(orbit.eccentric_anomaly, axis=0)

    def __call__(self, t: ArrayLike) -> OrbitState:
        """Constellation at GPS times ``t (B,)``: positions/velocities ``(B, S, 3)``."""
        if self._pos is None:
            self._build()
        t = np.asarray(t, dtype=np.float64)
        u = (t - self._t0) / self.step
        i = np.floor(u).astype(np.int64)
        if t.ndim != 1 or (i < 0).any() or (i >= self._pos.shape[0] - 1).any():
            return almanac_orbit(self.almanac, t)
        s = (u - i)[:, None, None]
        p0, p1 = self._pos[i], self._pos[i + 1]
        v0, v1 = self._vel[i] * self.step, self._vel[i + 1] * self.step
        s2, s3 = s * s, s * s * s
        pos = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * v0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * v1
        vel = (
            (6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * v0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * v1
        ) / self.step
        e0, e1 = self._ecc[i], self._ecc[i + 1]
        ecc = e0 + (e1 - e0) * s[..., 0]
        return OrbitState(pos, vel, ecc)
