"""Iridium filter models: 2D constant-velocity kinematics and Iridium fixes as virtual beacons.

Benzerrouk 2014 (§2.7d) positions a vehicle during GPS loss with Iridium geolocation fixes
alone: "the same kinematic model of 2D navigation", with "each iridium location measurement as
an artificial beacon or virtual beacon", whose pseudo-range (eq. 83)::

    VR_j^i = rho_j^i + w_k = sqrt((x_j - x^i)^2 + (y_j - y^i)^2) + w_k

is the distance from the vehicle ``(x_j, y_j)`` to the beacon ``(x^i, y^i)`` (the fix), with a
measurement covariance "time varying and dependent on the CEP radius of each incoming Iridium
geolocation". The filter state is::

    x = [x_N, y_E, v_N, v_E]

north/east position [m] and velocity [m/s] in a local tangent plane. **Transition**: the
discretized continuous white-noise-acceleration model (Bar-Shalom et al. 2001, §6.2.2) over one
step ``dt``, per axis::

    F = [[1, dt], [0, 1]],   Q = q [[dt^3 / 3, dt^2 / 2], [dt^2 / 2, dt]]

with the acceleration power spectral density ``q`` [m^2/s^3]. **Measurement**: the beacon's
position, ``z = [x^i, y^i] = H x + e``, ``H = [I_2, 0]``, ``R = sigma^2 I_2`` with ``sigma =
CEP / sqrt(2 ln 2)`` from the fix's CEP radius (:func:`navgym.iridium.sensors.cep_sigma`). The
innovation ``z - H x`` is the vector from the estimate to the beacon, so its norm is eq. 83's
``rho`` at the estimate and the beacon's zero measured range is ``rho + w``; the two Cartesian
rows carry what the range does (the pull toward the beacon along the line of sight) and keep
the filter linear: eq. 83 with a measured range of zero has no Jacobian where the estimate
reaches the beacon. Both rows are the rows of one fix: the Mixture task's outlier weight applies
per row (:mod:`filters.row_mixture`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["ConstantVelocity", "BeaconFix", "cv_process_noise"]


def cv_process_noise(q: np.ndarray, dt: float) -> np.ndarray:
    """``Q (B, 4, 4)`` of the white-noise-acceleration model for PSDs ``q (B,)`` [m^2/s^3] (see above)."""
    q = np.asarray(q, np.float64)
    Q = np.zeros(q.shape + (4, 4))
    for i in (0, 1):
        Q[..., i, i] = q * dt**3 / 3.0
        Q[..., i, i + 2] = Q[..., i + 2, i] = q * dt**2 / 2.0
        Q[..., i + 2, i + 2] = q * dt
    return Q


_F_UNIT = np.eye(4)


class ConstantVelocity(NamedTuple):
    """``x+ = F x`` with ``F = [[I, dt I], [0, I]]`` (Bar-Shalom et al. 2001, §6.2.2), batched over B.

    ``f`` broadcasts over ``(B, n)``, sigma points ``(B, S, n)`` and particles ``(B, N, n)``.
    """

    Q: np.ndarray  # (B, 4, 4)

    def repeat_batch(self, K: int) -> ConstantVelocity:
        """Each episode's ``Q`` repeated K times (Gaussian-sum filters stack components)."""
        return ConstantVelocity(np.repeat(self.Q, K, axis=0))

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 10.0) -> np.ndarray:
        """``[p + dt v, v]``; ``u`` is ignored (no control: Iridium fixes only)."""
        out = np.array(x, dtype=np.float64, copy=True)
        out[..., :2] += dt * out[..., 2:]
        return out

    def F(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 10.0) -> np.ndarray:
        """The constant Jacobian ``(B, 4, 4)``."""
        J = np.broadcast_to(_F_UNIT, (x.shape[0], 4, 4)).copy()
        J[:, 0, 2] = J[:, 1, 3] = dt
        return J


_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
_H.setflags(write=False)


class BeaconFix(NamedTuple):
    """The Iridium fix as a virtual beacon: ``h(x) = [x_N, y_E]``, ``R (B, 2, 2)`` from its CEP radius."""

    R: np.ndarray  # (B, 2, 2)

    def repeat_batch(self, K: int) -> BeaconFix:
        """Each episode's ``R`` repeated K times."""
        return BeaconFix(np.repeat(self.R, K, axis=0))

    def h(self, x: np.ndarray) -> np.ndarray:
        return x[..., :2]

    def H(self, x: np.ndarray) -> np.ndarray:
        return _H
