"""Small reference problems used by benchmarks, tests and examples.

They satisfy the model protocols of :mod:`filters.core.models` (``f``/``F``/``Q`` and
``h``/``H``/``R``) and broadcast over any leading axes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from filters.core.models import ElementwiseModel, LinearGaussianModel


@dataclass(frozen=True)
class RangeTracking(ElementwiseModel):
    """Nine-state target with quadratic drag tracked by ranges to four beacons.

    State ``x = [p (3), v (3), a (3)]`` in metres, m/s and m/s^2::

        p+ = p + v dt + a dt^2 / 2
        v+ = v + (a - c |v| v) dt          (quadratic drag, c in 1/m)
        a+ = exp(-dt / tau) a              (first-order Gauss-Markov acceleration)

    Measurements are the ranges ``|p - b_i|`` to beacons ``b_i`` (``m = 4``), the usual
    nonlinear GNSS-like observation. ``Q`` follows a white-jerk model on the acceleration.
    ``f`` and ``h`` are element-wise in the state components, built from ``+ - *`` and ``sqrt``
    (the norms unrolled; ``exp`` only of the scalar ``-dt / tau``), so the model is an
    :class:`~filters.core.models.ElementwiseModel`.
    """

    dt: float = 0.1
    drag: float = 1e-3
    tau: float = 20.0
    sigma_jerk: float = 0.5
    sigma_range: float = 1.0
    beacons: np.ndarray = field(
        default_factory=lambda: np.array(
            [[1000.0, 0.0, 50.0], [0.0, 1000.0, -40.0], [-800.0, -600.0, 30.0], [300.0, -900.0, 500.0]]
        )
    )

    @property
    def n(self) -> int:
        return 9

    @property
    def m(self) -> int:
        return int(self.beacons.shape[0])

    @cached_property
    def Q(self) -> np.ndarray:
        dt, q = self.dt, self.sigma_jerk**2
        G = np.array([dt**3 / 6.0, dt**2 / 2.0, dt])
        Q1 = q * np.outer(G, G) + 1e-6 * np.eye(3)
        Q = np.zeros((9, 9))
        for i in range(3):  # block layout p, v, a per axis
            idx = [i, 3 + i, 6 + i]
            Q[np.ix_(idx, idx)] = Q1
        return Q

    @cached_property
    def R(self) -> np.ndarray:
        return self.sigma_range**2 * np.eye(self.m)

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        dt = self.dt if dt is None else dt
        p, v, a = x[..., 0:3], x[..., 3:6], x[..., 6:9]
        speed = _norm3(v)[..., None]
        out = np.empty_like(x)
        out[..., 0:3] = p + v * dt + a * (0.5 * dt * dt)
        out[..., 3:6] = v + (a - self.drag * speed * v) * dt
        out[..., 6:9] = np.exp(-dt / self.tau) * a
        return out

    def F(self, x: np.ndarray, u: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        dt = self.dt if dt is None else dt
        v = x[..., 3:6]
        speed = _norm3(v)[..., None, None]
        # d(|v| v)/dv = |v| I + v v^T / |v|
        dvv = v[..., :, None] * (v[..., None, :] / np.maximum(speed, 1e-12))
        dvv[..., 0, 0] += speed[..., 0, 0]
        dvv[..., 1, 1] += speed[..., 0, 0]
        dvv[..., 2, 2] += speed[..., 0, 0]
        J = np.broadcast_to(self._F_linear(dt), (*x.shape[:-1], 9, 9)).copy()
        J[..., 3:6, 3:6] -= (self.drag * dt) * dvv
        return J

    def _F_linear(self, dt: float) -> np.ndarray:
        """The Jacobian without the drag term (constant for a given dt)."""
        eye = np.eye(3)
        J = np.zeros((9, 9))
        J[0:3, 0:3] = eye
        J[0:3, 3:6] = dt * eye
        J[0:3, 6:9] = 0.5 * dt * dt * eye
        J[3:6, 3:6] = eye
        J[3:6, 6:9] = dt * eye
        J[6:9, 6:9] = np.exp(-dt / self.tau) * eye
        return J

    def h(self, x: np.ndarray) -> np.ndarray:
        return _norm3(x[..., None, 0:3] - self.beacons)

    def H(self, x: np.ndarray) -> np.ndarray:
        d = x[..., None, 0:3] - self.beacons
        r = _norm3(d)[..., None]
        J = np.zeros((*x.shape[:-1], self.m, 9))
        J[..., 0:3] = d / r
        return J

    def initial_state(self, B: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Truth ``(B, 9)``, prior mean ``(B, 9)`` and prior covariance ``(B, 9, 9)``."""
        P0 = np.diag([25.0] * 3 + [4.0] * 3 + [0.25] * 3)
        truth = np.concatenate(
            [rng.normal(0, 100, (B, 3)), rng.normal(0, 10, (B, 3)), rng.normal(0, 0.5, (B, 3))], axis=1
        )
        m0 = truth + rng.standard_normal((B, 9)) @ np.linalg.cholesky(P0).T
        return truth, m0, np.broadcast_to(P0, (B, 9, 9)).copy()

    def simulate(self, truth: np.ndarray, T: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Truth trajectory ``(T, B, 9)`` and measurements ``(T, B, m)``."""
        chol_Q = np.linalg.cholesky(self.Q)
        xs, zs = [], []
        x = truth
        for _ in range(T):
            x = self.f(x) + rng.standard_normal(x.shape) @ chol_Q.T
            xs.append(x)
            zs.append(self.h(x) + self.sigma_range * rng.standard_normal((x.shape[0], self.m)))
        return np.stack(xs), np.stack(zs)

    def linear(self) -> LinearGaussianModel:
        """The drag-free, linear-measurement counterpart (for KF benchmarks)."""
        F = self.F(np.zeros(9))
        rng = np.random.default_rng(1234)
        H = np.zeros((self.m, 9))
        H[:, 0:3] = rng.standard_normal((self.m, 3))
        return LinearGaussianModel(F, H, self.Q, self.R)


def _norm3(d: np.ndarray) -> np.ndarray:
    """Euclidean norm over a last axis of length 3 (unrolled: a tiny-axis ufunc reduce is slow)."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.sqrt(x * x + y * y + z * z)


class UNGM:
    """Univariate nonstationary growth model, Touil & Ghadi 2012, eq. 18-19 (Q = 10, R = 1).

    ``x_k = 0.5 x + 25 x / (1 + x^2) + 8 cos(1.2 (k - 1)) + w_k``, ``y_k = x_k^2 / 20 + v_k``.
    The time index ``k`` of the step being predicted is passed as the control ``u``. ``f``/``h``
    broadcast over ``(B, n)`` and ``(B, N, n)``; ``F``/``H`` are the EKF Jacobians. The classic
    benchmark where the posterior is bimodal (the sign of x is unobservable from x^2).
    """

    Q = np.array([[10.0]])
    R = np.array([[1.0]])

    def f(self, x: np.ndarray, u: float, dt: float = 1.0) -> np.ndarray:
        return 0.5 * x + 25.0 * x / (1.0 + x**2) + 8.0 * np.cos(1.2 * (u - 1))

    def F(self, x: np.ndarray, u: float, dt: float = 1.0) -> np.ndarray:
        return (0.5 + 25.0 * (1.0 - x**2) / (1.0 + x**2) ** 2)[:, :, None]

    def h(self, x: np.ndarray) -> np.ndarray:
        return x**2 / 20.0

    def H(self, x: np.ndarray) -> np.ndarray:
        return (x / 10.0)[:, :, None]
