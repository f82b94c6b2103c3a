"""Random test problems shared by the filter tests (float64, seeded)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class RandomNonlinear:
    """A random smooth nonlinear model with analytic Jacobians.

    ``f(x) = A x + a sin(x)``, ``h(x) = C x + c (D x)^2`` (elementwise square), additive noise.
    """

    A: np.ndarray
    a: float
    C: np.ndarray
    D: np.ndarray
    c: float
    Q: np.ndarray
    R: np.ndarray

    @classmethod
    def draw(cls, n: int, m: int, seed: int) -> RandomNonlinear:
        rng = np.random.default_rng(seed)
        A = rng.standard_normal((n, n))
        A *= 0.95 / max(abs(np.linalg.eigvals(A)))
        Lq = rng.standard_normal((n, n)) * 0.1
        Lr = rng.standard_normal((m, m)) * 0.2
        return cls(
            A=A,
            a=0.2,
            C=rng.standard_normal((m, n)),
            D=rng.standard_normal((m, n)) * 0.3,
            c=0.1,
            Q=Lq @ Lq.T + 0.05 * np.eye(n),
            R=Lr @ Lr.T + 0.1 * np.eye(m),
        )

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.C.shape[0]

    def f(self, x, u=None, dt=1.0):
        return x @ self.A.T + self.a * np.sin(x)

    def F(self, x, u=None, dt=1.0):
        return self.A + self.a * np.cos(x)[..., None, :] * np.eye(self.n)

    def h(self, x):
        return x @ self.C.T + self.c * (x @ self.D.T) ** 2

    def H(self, x):
        return self.C + 2.0 * self.c * (x @ self.D.T)[..., :, None] * self.D

    # filterpy-style single-filter callables
    def fx(self, x, dt=1.0):
        return self.f(x)

    def hx(self, x):
        return self.h(np.asarray(x).ravel())

    def simulate(self, B: int, T: int, seed: int):
        """Prior (m0, P0) of shape (B, n), (B, n, n), and measurements (T, B, m)."""
        rng = np.random.default_rng(seed)
        P0 = np.eye(self.n)
        x = rng.standard_normal((B, self.n))
        m0 = x + rng.standard_normal((B, self.n))
        chol_Q, chol_R = np.linalg.cholesky(self.Q), np.linalg.cholesky(self.R)
        zs = []
        for _ in range(T):
            x = self.f(x) + rng.standard_normal(x.shape) @ chol_Q.T
            zs.append(self.h(x) + rng.standard_normal((B, self.m)) @ chol_R.T)
        return m0, np.broadcast_to(P0, (B, self.n, self.n)).copy(), np.stack(zs)


def random_linear(n: int, m: int, seed: int):
    """A random stable LinearGaussianModel and a prior."""
    from filters import LinearGaussianModel

    p = RandomNonlinear.draw(n, m, seed)
    return LinearGaussianModel(p.A, p.C, p.Q, p.R)
