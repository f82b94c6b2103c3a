"""Sigma-point rules: unit points and weights for Gaussian moment integrals.

A rule maps the state dimension ``n`` to :class:`SigmaPoints` ``(xi, wm, wc)`` for the
standard normal ``N(0, I_n)``; a filter places them at ``m + chol(P) xi`` (Benzerrouk 2014, eq. 51).
Rules are small frozen objects satisfying the :class:`Quadrature` protocol; their point sets
are cached per dimension.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np


class SigmaPoints(NamedTuple):
    """Unit sigma points and weights.

    Attributes:
        xi: points of the standard normal, shape ``(S, n)``.
        wm: mean weights ``(S,)`` (sum to 1).
        wc: covariance weights ``(S,)``.

    """

    xi: np.ndarray
    wm: np.ndarray
    wc: np.ndarray


@runtime_checkable
class Quadrature(Protocol):
    """A Gaussian quadrature rule (unscented, cubature, Gauss-Hermite, ...)."""

    def sigma_points(self, n: int) -> SigmaPoints:
        """Points and weights for dimension ``n``."""
        ...


@dataclass(frozen=True)
class Unscented:
    """Scaled unscented transform (Julier 2002; Van der Merwe 2004).

    The same points and weights as filterpy's ``MerweScaledSigmaPoints``.
    ``lambda = alpha^2 (n + kappa) - n``; points ``0, +-sqrt(n + lambda) e_i``;
    ``wm_0 = lambda / (n + lambda)``, ``wc_0 = wm_0 + 1 - alpha^2 + beta``,
    ``w_i = 1 / (2 (n + lambda))``. The default alpha = 1, beta = 2, kappa = 0 keeps every
    weight non-negative (the often quoted alpha = 1e-3 gives wm_0 ~ -1e6 and loses ~12 digits).
    """

    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0

    def __post_init__(self) -> None:
        if not self.alpha > 0:
            raise ValueError(f"alpha must be > 0; got {self.alpha}")

    def sigma_points(self, n: int) -> SigmaPoints:
        return _unscented(n, self.alpha, self.beta, self.kappa)


@dataclass(frozen=True)
class Cubature:
    """Third-degree spherical-radial cubature rule (Arasaratnam & Haykin 2009; Benzerrouk 2014, eq. 42).

    ``2n`` points ``+-sqrt(n) e_i`` with equal weights ``1 / (2n)``. Equals the unscented rule
    with ``alpha = 1, beta = 0, kappa = 0``.
    """

    def sigma_points(self, n: int) -> SigmaPoints:
        return _cubature(n)


#: Most points of a tensor-product Gauss-Hermite rule (``p**n``): beyond them one filter step's
#: points alone take gigabytes, so :meth:`GaussHermite.sigma_points` refuses the rule.
MAX_GAUSS_HERMITE_POINTS = 5_000_000


@dataclass(frozen=True)
class GaussHermite:
    """Tensor-product Gauss-Hermite rule with ``p^n`` points (Benzerrouk 2014, eq. 43-50).

    One-dimensional nodes are ``sqrt(2)`` times the eigenvalues of the Jacobi matrix with
    ``J_{i,i+1} = sqrt(i/2)`` (eq. 48), weights the squared first components of its normalized
    eigenvectors; the n-dimensional weights are products (eq. 50). Exact for polynomials of
    degree ``2p - 1`` in each coordinate.
    """

    p: int = 3

    def __post_init__(self) -> None:
        if self.p < 1:
            raise ValueError(f"p must be >= 1; got {self.p}")

    def n_points(self, n: int) -> int:
        """The rule's number of points in ``n`` dimensions: ``p**n``."""
        return int(self.p) ** int(n)

    def sigma_points(self, n: int) -> SigmaPoints:
        if self.n_points(n) > MAX_GAUSS_HERMITE_POINTS:
            raise ValueError(f"GaussHermite(p={self.p}) in n={n} needs {self.n_points(n)} points; too many")
        return _gauss_hermite(n, self.p)


@functools.lru_cache(maxsize=64)
def _unscented(n: int, alpha: float, beta: float, kappa: float) -> SigmaPoints:
    lam = alpha**2 * (n + kappa) - n
    c = n + lam
    if c <= 0:
        raise ValueError(f"unscented rule needs n + lambda > 0; got {c} (alpha={alpha}, kappa={kappa})")
    xi = np.vstack([np.zeros(n), np.sqrt(c) * np.eye(n), -np.sqrt(c) * np.eye(n)])
    wm = np.full(2 * n + 1, 0.5 / c)
    wc = wm.copy()
    wm[0] = lam / c
    wc[0] = lam / c + 1.0 - alpha**2 + beta
    return _frozen(SigmaPoints(xi, wm, wc))


@functools.lru_cache(maxsize=64)
def _cubature(n: int) -> SigmaPoints:
    xi = np.sqrt(n) * np.vstack([np.eye(n), -np.eye(n)])
    w = np.full(2 * n, 0.5 / n)
    return _frozen(SigmaPoints(xi, w, w.copy()))


def gauss_hermite_1d(p: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of the p-point rule for ``N(0, 1)`` (Jacobi matrix, Benzerrouk 2014, eq. 48)."""
    J = np.zeros((p, p))
    i = np.arange(1, p)
    J[i - 1, i] = J[i, i - 1] = np.sqrt(i / 2.0)
    eps, vecs = np.linalg.eigh(J)
    return np.sqrt(2.0) * eps, vecs[0, :] ** 2


@functools.lru_cache(maxsize=16)
def _gauss_hermite(n: int, p: int) -> SigmaPoints:
    nodes, weights = gauss_hermite_1d(p)
    idx = np.array(list(itertools.product(range(p), repeat=n)), dtype=np.intp).reshape(-1, n)
    xi = nodes[idx]
    w = np.prod(weights[idx], axis=1)
    return _frozen(SigmaPoints(xi, w, w.copy()))


def _frozen(sp: SigmaPoints) -> SigmaPoints:
    for a in sp:
        a.setflags(write=False)
    return sp


RULES: dict[str, Quadrature] = {
    "ukf": Unscented(),
    "ckf": Cubature(),
    "ghkf": GaussHermite(3),
    "ghkf5": GaussHermite(5),
}
