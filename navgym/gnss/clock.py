"""Receiver clock: bias and exponentially correlated drift (Carvalho et al. 1997, eq. 11), batched.

State per episode: bias ``b`` [s] and drift ``d`` [s/s] with::

    b_dot = d,   d_dot = -a d + w,   E[w(t) w(s)] = sigma_w^2 delta(t - s)

(Carvalho et al. 1997, eq. 11: "the receiver clock drift is represented by the integration of an
exponentially correlated random process", a = 1/500 s^-1, sigma_w = 1e-12). Steps use the
exact discretisation, so any dt gives the same statistics. The paper does not give initial
values; by default the drift starts at the "typical frequency drift rate of 1e-9 s/s" it quotes
(as a standard deviation) and the bias with a standard deviation of 100 ns (30 m).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from navgym.geo.wgs84 import C_LIGHT

__all__ = [
    "CLOCK_A",
    "CLOCK_SIGMA_W",
    "ClockParams",
    "DEFAULT_CLOCK",
    "ClockState",
    "clock_transition",
    "clock_init",
    "clock_step",
]

#: Inverse correlation time a [1/s] (Carvalho et al. 1997, eq. 11).
CLOCK_A: float = 1.0 / 500.0
#: Driving white-noise intensity sigma_w [s/s/sqrt(s)] (Carvalho et al. 1997, eq. 11).
CLOCK_SIGMA_W: float = 1e-12


class ClockParams(NamedTuple):
    """Clock-model parameters (scalars or per-episode ``(B,)`` arrays).

    Attributes:
        a: Inverse correlation time of the drift [1/s].
        sigma_w: Drift driving-noise intensity [s/s/sqrt(s)].
        bias0_std: Initial bias standard deviation [s].
        drift0_std: Initial drift standard deviation [s/s].
    """

    a: float | NDArray[np.float64] = CLOCK_A
    sigma_w: float | NDArray[np.float64] = CLOCK_SIGMA_W
    bias0_std: float | NDArray[np.float64] = 1e-7
    drift0_std: float | NDArray[np.float64] = 1e-9


#: Carvalho et al. 1997, eq. 11 parameters with the default initial spreads.
DEFAULT_CLOCK = ClockParams()


class ClockState(NamedTuple):
    """Receiver clock state, arrays ``(B,)``.

    Attributes:
        bias: Clock bias dtau [s] (pseudo-ranges carry ``c * bias``).
        drift: Clock drift d(dtau)/dt [s/s] (delta-ranges carry ``c * drift``).
    """

    bias: NDArray[np.float64]
    drift: NDArray[np.float64]

    @property
    def bias_m(self) -> NDArray[np.float64]:
        """Bias in metres, ``c * bias``."""
        return C_LIGHT * self.bias

    @property
    def drift_mps(self) -> NDArray[np.float64]:
        """Drift in metres per second, ``c * drift``."""
        return C_LIGHT * self.drift


def clock_transition(
    dt: ArrayLike, a: ArrayLike = CLOCK_A, sigma_w: ArrayLike = CLOCK_SIGMA_W
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact discrete transition and process-noise covariance of Carvalho et al. 1997, eq. 11.

    With ``phi = exp(-a dt)`` and ``q = sigma_w^2``::

        Phi = [[1, (1 - phi) / a], [0, phi]]
        Q11 = q / a^3 (x - 2 (1 - phi) + (1 - phi^2) / 2),   x = a dt
        Q12 = q (1 - phi)^2 / (2 a^2),   Q22 = q (1 - phi^2) / (2 a)

    (``Q11`` by its series ``q dt^3 (1/3 - x/4 + 7 x^2/60 - x^3/24)`` for x < 1e-3, where
    the closed form cancels.) For states ``[b, d]``.

    Args:
        dt: Step [s] (> 0), any shape.
        a: Inverse correlation time [1/s] (> 0), broadcastable.
        sigma_w: Noise intensity, broadcastable.

    Returns:
        ``(Phi, Q)``, each of shape ``broadcast(dt, a, sigma_w) + (2, 2)``.
    """
    dt, a, sw = np.broadcast_arrays(
        np.asarray(dt, np.float64), np.asarray(a, np.float64), np.asarray(sigma_w, np.float64)
    )
    if np.any(a <= 0):
        raise ValueError(f"a must be > 0, got {a}")
    x = a * dt
    phi = np.exp(-x)
    one_m = -np.expm1(-x)
    one_m2 = -np.expm1(-2.0 * x)
    q = sw * sw
    series = dt * dt * dt * (1.0 / 3.0 - x / 4.0 + 7.0 * x * x / 60.0 - x * x * x / 24.0)
    a_safe = np.maximum(a, 1e-300)
    closed = (x - 2.0 * one_m + 0.5 * one_m2) / (a_safe * a_safe * a_safe)
    q11 = q * np.where(x < 1e-3, series, closed)
    q12 = q * one_m**2 / (2.0 * a * a)
    q22 = q * one_m2 / (2.0 * a)
    big_phi = np.zeros(dt.shape + (2, 2))
    big_phi[..., 0, 0] = 1.0
    big_phi[..., 0, 1] = one_m / a
    big_phi[..., 1, 1] = phi
    big_q = np.empty(dt.shape + (2, 2))
    big_q[..., 0, 0] = q11
    big_q[..., 0, 1] = big_q[..., 1, 0] = q12
    big_q[..., 1, 1] = q22
    return big_phi, big_q


def clock_init(z: ArrayLike, params: ClockParams = DEFAULT_CLOCK) -> ClockState:
    """Initial clock states from standard normals ``z`` of shape ``(B, 2)``.

    ``b_0 = bias0_std z[:, 0]``, ``d_0 = drift0_std z[:, 1]``.
    """
    z = np.asarray(z, np.float64)
    if z.ndim != 2 or z.shape[1] != 2:
        raise ValueError(f"z must have shape (B, 2), got {z.shape}")
    return ClockState(params.bias0_std * z[:, 0], params.drift0_std * z[:, 1])


def clock_step(
    state: ClockState, dt: ArrayLike, z: ArrayLike, params: ClockParams = DEFAULT_CLOCK
) -> ClockState:
    """Advance the clock by ``dt`` with standard normals ``z`` ``(B, 2)``.

    ``x_{k+1} = Phi x_k + L z`` with ``L`` the Cholesky factor of ``Q``
    (:func:`clock_transition`), Carvalho et al. 1997, eq. 11 discretised exactly.

    Args:
        state: Current :class:`ClockState` ``(B,)``.
        dt: Step [s], scalar or ``(B,)``.
        z: Standard normal draws, ``(B, 2)``.
        params: :class:`ClockParams`.

    Returns:
        The next :class:`ClockState`.
    """
    z = np.asarray(z, np.float64)
    if z.ndim != 2 or z.shape != (state.bias.shape[0], 2):
        raise ValueError(f"z must have shape ({state.bias.shape[0]}, 2), got {z.shape}")
    big_phi, big_q = clock_transition(dt, params.a, params.sigma_w)
    l11 = np.sqrt(big_q[..., 0, 0])
    l21 = np.where(l11 > 0, big_q[..., 0, 1] / np.where(l11 > 0, l11, 1.0), 0.0)
    l22 = np.sqrt(np.maximum(big_q[..., 1, 1] - l21 * l21, 0.0))
    bias = state.bias + big_phi[..., 0, 1] * state.drift + l11 * z[:, 0]
    drift = big_phi[..., 1, 1] * state.drift + l21 * z[:, 0] + l22 * z[:, 1]
    return ClockState(bias, drift)
