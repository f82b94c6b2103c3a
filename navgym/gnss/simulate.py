"""One GNSS measurement step for B episodes: visibility, selection, pseudo- and delta-ranges.

:func:`simulate_gnss_step` composes the pieces of this package for a simulator step: the
almanac constellation (Carvalho et al. 1997, §IV-B), visibility above the mask and the
``m_max``-row selection (:func:`~navgym.gnss.visibility.select_satellites`), pseudo-ranges
(Carvalho et al. 1997, eq. 10/15; Touil & Ghadi 2012, eq. 5) with the troposphere of
Carvalho et al. 1997 and its 5 % noise, delta-ranges (Touil & Ghadi 2012, eq. 6-7), receiver
clock terms (Carvalho et al. 1997, eq. 11) and the per-episode noise regime
(:mod:`navgym.gnss.noise`). Random inputs are arrays (see :data:`NORMALS_PER_ROW`), so the
function is pure; draw them with :class:`~navgym.gnss.streams.EpisodeStreams`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.frames import up_vector
from navgym.gnss.almanac import Almanac, almanac_orbit
from navgym.gnss.clock import ClockState
from navgym.gnss.measurements import geometric_range, range_and_rate, range_rate
from navgym.gnss.noise import NoiseRegime, NoiseSample, sample_noise
from navgym.gnss.orbit import OrbitState, ecef_acceleration
from navgym.gnss.orbit_cache import CachedConstellation
from navgym.gnss.troposphere import TROPO_NOISE_FRACTION, goad_goodman_delay_from_sine
from navgym.gnss.visibility import DEFAULT_M_MAX, check_mask_angle, rank_satellites

__all__ = [
    "NORMALS_PER_ROW",
    "UNIFORMS_PER_ROW",
    "GnssStep",
    "constellation",
    "simulate_gnss_step",
]

#: Standard normals per measurement row. ``normals`` ``(B, 3 m_max)`` is read block-wise:
#: columns ``[0, m)`` pseudo-range noise, ``[m, 2m)`` delta-range noise, ``[2m, 3m)``
#: troposphere noise (row i of each block belongs to measurement row i).
NORMALS_PER_ROW: int = 3
#: Uniforms per measurement row, block-wise as above: mixture component, loss, outlier.
UNIFORMS_PER_ROW: int = 3


class GnssStep(NamedTuple):
    """Measurements of one step, rows ``(B, m)`` (``m = m_max``).

    Attributes:
        pseudorange: Pseudo-ranges [m] (finite also where masked).
        delta_range: Delta-ranges [m/s] (None when not simulated).
        mask: Row usable: satellite above the mask and not lost.
        visible: Satellite above the mask (before losses).
        prn: PRN per row.
        sat_index: Index into the almanac's satellite axis.
        sin_elevation: Sine of the elevation (``elevation`` gives the angle).
        sat_pos: Satellite ECEF positions at the receive time [m], ``(B, m, 3)``.
        sat_vel: Satellite ECEF velocities [m/s], ``(B, m, 3)``.
        troposphere: Modelled (noise-free) tropospheric delay [m].
        noise: The sampled :class:`~navgym.gnss.noise.NoiseSample`.
    """

    pseudorange: NDArray[np.float64]
    delta_range: NDArray[np.float64] | None
    mask: NDArray[np.bool_]
    visible: NDArray[np.bool_]
    prn: NDArray[np.int64]
    sat_index: NDArray[np.int64]
    sin_elevation: NDArray[np.float64]
    sat_pos: NDArray[np.float64]
    sat_vel: NDArray[np.float64]
    troposphere: NDArray[np.float64]
    noise: NoiseSample

    @property
    def elevation(self) -> NDArray[np.float64]:
        """Elevation angle [rad], ``(B, m)``."""
        return np.arcsin(self.sin_elevation)


def constellation(almanac: Almanac, t: ArrayLike) -> OrbitState:
    """All satellites at GPS time ``t``: scalar -> ``(S, 3)``, ``(B,)`` -> ``(B, S, 3)``.

    When all episodes share the step's time, compute this once per step and pass it to
    :func:`simulate_gnss_step` (``orbit=``).
    """
    return almanac_orbit(almanac, t)


def simulate_gnss_step(
    almanac: Almanac,
    t: ArrayLike,
    rx_ecef: ArrayLike,
    rx_vel: ArrayLike,
    clock: ClockState,
    regime: NoiseRegime,
    normals: ArrayLike,
    uniforms: ArrayLike,
    mask_deg: ArrayLike = 10.0,
    m_max: int = DEFAULT_M_MAX,
    troposphere: bool = True,
    earth_rotation: bool = True,
    orbit: OrbitState | CachedConstellation | None = None,
    available: ArrayLike | None = None,
    delta_range: bool = True,
) -> GnssStep:
    """Simulate pseudo-ranges and delta-ranges of B receivers at one step.

    Per episode b and row i (satellite s_i chosen by elevation, highest first)::

        rho_i = |r_s - r| (light time + Sagnac) + c dtau_b + T(theta_i) (1 + 0.05 nu) + e_pr
        drho_i = R_i + c d(dtau)/dt + e_dr

    Carvalho et al. 1997, eq. 10 / 15 (troposphere T of §IV-C-3 with 5 % noise nu), Touil & Ghadi
    2012, eq. 5-7 (R_i the range rate), errors e from the episode's :class:`NoiseRegime`. Rows
    past the visible satellites hold the next ones below the mask with ``mask = False``; their
    values are finite and must be ignored.

    Args:
        almanac: Constellation (:func:`~navgym.gnss.almanac.load_default_almanac`).
        t: GPS seconds, scalar (shared) or ``(B,)``.
        rx_ecef: True receiver positions [m], ``(B, 3)``.
        rx_vel: True receiver ECEF velocities [m/s], ``(B, 3)``.
        clock: Receiver :class:`~navgym.gnss.clock.ClockState` ``(B,)``.
        regime: :class:`~navgym.gnss.noise.NoiseRegime` ``(B,)``.
        normals: Standard normals ``(B, 3 m_max)``, block-wise: pseudo-range noise, delta-range
            noise, troposphere noise (``m_max`` columns each).
        uniforms: Uniforms ``(B, 3 m_max)``, block-wise: mixture component, loss, outlier.
        mask_deg: Elevation mask [deg], scalar or ``(B,)``, in [0, 90).
        m_max: Number of rows.
        troposphere: Add the Carvalho et al. 1997 tropospheric delay and its noise.
        earth_rotation: Light-time and Sagnac terms (see :mod:`navgym.gnss.measurements`).
        orbit: Precomputed :func:`constellation` at ``t`` (saves the Kepler solve), or an
            :meth:`~navgym.gnss.orbit_cache.OrbitCache.lookup` at ``t``.
        available: Optional bool ``(S,)`` or ``(B, S)``: satellites that may be tracked
            (scenario drop-outs).
        delta_range: Simulate delta-ranges; False skips the range rates (satellite
            accelerations included) for consumers of pseudo-ranges only, and the step's
            ``delta_range`` is None. The pseudo-ranges and every random draw are the same.

    Returns:
        :class:`GnssStep`.

    Raises:
        ValueError: For bad shapes or a mask angle outside [0, 90).
    """
    rx = np.asarray(rx_ecef, np.float64)
    if rx.ndim != 2 or rx.shape[1] != 3:
        raise ValueError(f"rx_ecef must have shape (B, 3), got {rx.shape}")
    b = rx.shape[0]
    rows = int(m_max)
    if rows < 1:
        raise ValueError(f"m_max must be >= 1, got {m_max}")
    vel_in = np.asarray(rx_vel, np.float64)
    if vel_in.shape != (b, 3):
        raise ValueError(f"rx_vel must have shape ({b}, 3), got {vel_in.shape}")
    if np.shape(clock.bias) != (b,) or np.shape(clock.drift) != (b,):
        raise ValueError(f"clock must hold ({b},) arrays, got {np.shape(clock.bias)}")
    if regime.batch_size != b:
        raise ValueError(f"regime must have batch size {b}, got {regime.batch_size}")
    m = min(rows, almanac.prn.shape[0])
    z = np.asarray(normals, np.float64)
    u = np.asarray(uniforms, np.float64)
    if z.shape != (b, NORMALS_PER_ROW * rows):
        raise ValueError(f"normals must have shape ({b}, {NORMALS_PER_ROW * rows}), got {z.shape}")
    if u.shape != (b, UNIFORMS_PER_ROW * rows):
        raise ValueError(f"uniforms must have shape ({b}, {UNIFORMS_PER_ROW * rows}), got {u.shape}")
    z = z.reshape(b, NORMALS_PER_ROW, rows)[..., :m]
    u = u.reshape(b, UNIFORMS_PER_ROW, rows)[..., :m]
    if orbit is None:
        orbit = almanac_orbit(almanac, t)
    mask_arr = check_mask_angle(mask_deg)
    sin_mask = np.sin(np.deg2rad(mask_arr if mask_arr.ndim == 0 else mask_arr.reshape(b, 1)))
    up = up_vector(rx)
    pos_all = orbit.position
    pos_c = None  # component slabs (3, B, S) of per-episode positions
    if pos_all.ndim == 2:
        # Shared time: BLAS products give u.(r_s - r) and |r_s - r|^2 for all pairs.
        su = up @ pos_all.T
        su -= np.sum(up * rx, axis=1, keepdims=True)
        d2 = rx @ pos_all.T
        d2 *= -2.0
        d2 += np.sum(pos_all * pos_all, axis=1)
        d2 += np.sum(rx * rx, axis=1, keepdims=True)
    else:
        # Component slabs: contiguous (B, S) arithmetic, about 3x faster than einsum on (B, S, 3).
        pos_c = np.ascontiguousarray(np.moveaxis(pos_all, -1, 0))
        dx, dy, dz = (pos_c[i] - rx[:, i : i + 1] for i in range(3))
        su = dx * up[:, 0:1]
        su += dy * up[:, 1:2]
        su += dz * up[:, 2:3]
        d2 = dx * dx
        d2 += dy * dy
        d2 += dz * dz
    # Rank by sin(el) |sin(el)| = su |su| / d2 (monotone in el, no square root on (B, S)).
    score = su * np.abs(su) / d2
    idx, vis = rank_satellites(score, sin_mask * np.abs(sin_mask), m, available)
    flat = idx + score.shape[1] * np.arange(b)[:, None]
    sin_el = np.take(score, flat)
    sin_el = np.sign(sin_el) * np.sqrt(np.abs(sin_el))
    sp, sv = _selected_states(orbit, idx, flat, pos_c)
    prn = np.take(almanac.prn, idx)
    noise = sample_noise(regime, prn, z[:, 0], z[:, 1], u[:, 0], u[:, 1], u[:, 2])
    rx_b = rx[:, None, :]
    vel_b = vel_in[:, None, :]
    rate = None
    if not delta_range:
        rho = geometric_range(rx_b, sp, sv, earth_rotation=earth_rotation)
    elif earth_rotation:
        sa = ecef_acceleration(sp, sv)  # for the selected satellites only
        rho, rate = range_and_rate(rx_b, vel_b, sp, sv, sa)
    else:
        rho = geometric_range(rx_b, sp, None, earth_rotation=False)
        rate = range_rate(rx_b, vel_b, sp, sv, earth_rotation=False)
    pr = rho + clock.bias_m[:, None] + noise.pseudorange
    if troposphere:
        tropo = goad_goodman_delay_from_sine(sin_el)
        pr += tropo * (1.0 + TROPO_NOISE_FRACTION * z[:, 2])
    else:
        tropo = np.zeros_like(sin_el)
    dr = None if rate is None else rate + clock.drift_mps[:, None] + noise.delta_range
    return GnssStep(pr, dr, vis & ~noise.lost, vis, prn, idx, sin_el, sp, sv, tropo, noise)


def _selected_states(
    orbit: OrbitState | CachedConstellation,
    idx: NDArray[np.int64],
    flat: NDArray[np.int64],
    pos_c: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Positions and velocities ``(B, m, 3)`` of the selected satellites ``idx (B, m)``.

    ``flat`` is ``idx`` offset by ``S b`` (row-major ``(B, S)`` positions). A
    :class:`~navgym.gnss.orbit_cache.CachedConstellation` evaluates velocities for these
    satellites only. The results are ``(B, m, 3)`` views of component slabs ``(3, B, m)``, so
    the component-wise range and range-rate code runs on contiguous memory. ``pos_c`` holds the
    per-episode positions as component slabs ``(3, B, S)`` (the caller's ranking formed them; a
    :class:`~navgym.gnss.orbit_cache.CachedConstellation` is always per episode).
    """
    if isinstance(orbit, CachedConstellation):
        sp = np.take(pos_c.reshape(3, -1), flat, axis=1)
        sv = np.ascontiguousarray(np.moveaxis(orbit.velocities(idx), -1, 0))
        return np.moveaxis(sp, 0, -1), np.moveaxis(sv, 0, -1)
    pos_all, vel_all = orbit.position, orbit.velocity
    B, m = idx.shape
    if pos_all.ndim == 2:
        # One component-first gather of position and velocity: (6, B, m).
        g = np.take(np.concatenate([pos_all.T, vel_all.T]), idx, axis=1)
        return np.moveaxis(g[0:3], 0, -1), np.moveaxis(g[3:6], 0, -1)
    S = pos_all.shape[1]
    pv = np.concatenate([pos_all, vel_all], axis=2).reshape(B * S, 6)[flat.ravel()].reshape(B, m, 6)
    return pv[..., 0:3], pv[..., 3:6]
