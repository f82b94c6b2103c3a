"""Estimates from weighted particle clouds: normalization, ESS, moments, health.

The particle approximation of the posterior is ``sum_i w_i delta(x - x_i)`` (Carvalho et al. 1997, §III-A,
the Dirac comb after eq. 7), so the estimate of ``E[phi(X_k) | Y_k]`` is ``sum_i w_i phi(x_i)``
(Carvalho et al. 1997, eq. 7). Weights live in the log domain; every reduction subtracts the row maximum
first (log-sum-exp), so no weight underflows to a 0/0.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.compiled import compiled_enabled
from filters.core.layout import cloud_dtype, is_component_major, weights_in
from filters.core.linalg import symmetrize
from filters.core.resampling import check_log_weights, exp_weights, normalized_weights
from filters.core.threads import matmul, over_rows
from filters.core.types import GaussianState, ParticleState

__all__ = [
    "check_particles",
    "covariance",
    "ess",
    "healthy",
    "log_and_linear_weights",
    "logsumexp",
    "mean",
    "mean_and_covariance",
    "normalize_log_weights",
    "weights",
]


def check_particles(state: ParticleState, name: str = "state") -> tuple[int, int, int]:
    """Check a :class:`ParticleState` (shapes, ``N >= 1``, log-weights); return ``(B, N, n)``.

    Particle positions are not checked for finiteness (that is the health flag's job); the
    log-weights must not contain NaN or ``+inf`` and each row needs one finite entry.
    """
    x = state.x
    if not isinstance(x, np.ndarray) or x.ndim != 3:
        raise ValueError(f"{name}.x must be an array of shape (B, N, n); got {np.shape(x)}")
    B, N, n = x.shape
    if N < 1:
        raise ValueError(f"{name}.x must hold N >= 1 particles; got shape {x.shape}")
    lw = np.asarray(state.log_w)
    if lw.shape != (B, N):
        raise ValueError(f"{name}.log_w must have shape (B, N) = {(B, N)}; got {lw.shape}")
    check_log_weights(lw, f"{name}.log_w")
    return B, N, n


def logsumexp(a: np.ndarray, axis: int = -1) -> np.ndarray:
    """``log sum exp a`` along ``axis`` with max-subtraction; all ``-inf`` gives ``-inf``.

    Args:
        a: log-values; ``-inf`` allowed.
        axis: the reduced axis.

    Returns:
        ``max a + log sum exp(a - max a)``, the reduced shape.
    """
    amax = np.max(a, axis=axis, keepdims=True)
    amax = np.where(np.isfinite(amax), amax, 0.0)
    s = exp_weights(a - amax).sum(axis=axis)
    with np.errstate(divide="ignore"):
        return np.log(s) + np.squeeze(amax, axis=axis)


def normalize_log_weights(log_w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalize log-weights per row (Carvalho et al. 1997, eq. 6 in the log domain).

    ``log w_i <- log w_i - log sum_j exp(log w_j)``.

    Args:
        log_w: unnormalized log-weights ``(B, N)``.

    Returns:
        ``(normalized log-weights (B, N), log normalizer (B,))``. Rows whose normalizer is
        ``-inf`` (all weights zero) are returned as they are.
    """
    c = logsumexp(log_w, axis=1)
    safe = np.where(np.isfinite(c), c, 0.0)
    return log_w - safe[:, None], c


def log_and_linear_weights(log_w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalized log-weights and linear weights of valid log-weights ``(B, N)`` in one pass set.

    ``m = max_i l_i``, ``e_i = exp(l_i - m)``, ``w_i = e_i / sum_j e_j``,
    ``log w_i = l_i - m - log sum_j e_j``. Rows must have a finite maximum (checked inputs).

    Returns:
        ``(log_w (B, N), w (B, N))``.

    """
    mx = log_w.max(axis=1, keepdims=True)
    w = log_w - mx
    exp_weights(w, out=w)
    total = w.sum(axis=1, keepdims=True)
    w /= total
    out = log_w - (mx + np.log(total))
    return out, w


def weights(log_w: np.ndarray) -> np.ndarray:
    """Normalized linear weights ``w_i = exp(log w_i - logsumexp(log w))``, shape ``(B, N)``.

    The max-shifted form of :func:`filters.core.resampling.normalized_weights`.
    """
    return normalized_weights(log_w)


def ess(log_w: np.ndarray) -> np.ndarray:
    """Effective sample size ``1 / sum_i w_i^2`` of normalized weights (Kong, Liu & Wong 1994).

    Args:
        log_w: log-weights ``(B, N)`` (normalized or not).

    Returns:
        ``(B,)`` values in ``[1, N]``.
    """
    w = weights(np.asarray(log_w, dtype=np.float64))
    return 1.0 / np.einsum("bn,bn->b", w, w)


def _weights_like(state: ParticleState) -> np.ndarray:
    """Normalized weights in the particles' precision (float32 clouds: no float64 copy of x)."""
    return weights_in(weights(np.asarray(state.log_w, dtype=np.float64)), cloud_dtype(state.x))


def _mean(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    return matmul(w[:, None, :], x)[:, 0, :]


def _covariance(x: np.ndarray, w: np.ndarray, m: np.ndarray) -> np.ndarray:
    mx = m.astype(x.dtype)
    if compiled_enabled() and is_component_major(x) and w.dtype == x.dtype:
        # d and d w in one compiled pass: the same element-wise values in the same (B, n, N)
        # layout as the NumPy lines below, so the same product (half the passes over the cloud)
        B, N, n = x.shape
        xT, P = x.transpose(0, 2, 1), np.empty((B, n, n), dtype=x.dtype)
        dT, dwT = np.empty((B, n, N), dtype=x.dtype), np.empty((B, n, N), dtype=x.dtype)

        def filters(a: int, b: int) -> None:  # each filter's covariance from its own cloud alone
            _centred_pass(xT[a:b], mx[a:b], w[a:b], dT[a:b], dwT[a:b])
            np.matmul(dwT[a:b], dT[a:b].transpose(0, 2, 1), out=P[a:b])

        over_rows(B, n * N, filters)
    else:
        d = x - mx[:, None, :]
        dw = d * w[:, :, None]
        P = np.swapaxes(dw, 1, 2) @ d
    return symmetrize(P.astype(np.float64, copy=False))


@njit(cache=True, nogil=True)
def _centred_pass(xT, m, w, dT, dwT):  # pragma: no cover - compiled
    """``dT = xT - m`` and ``dwT = dT w`` for a component-major cloud ``xT (B, n, N)``.

    In the cloud's precision, each operation rounded as NumPy's ``x - m`` and ``d * w`` round it.
    """
    B, n, N = xT.shape
    for b in range(B):
        for j in range(n):
            mj = m[b, j]
            x = xT[b, j]
            d = dT[b, j]
            dw = dwT[b, j]
            wb = w[b]
            for i in range(N):
                v = x[i] - mj
                d[i] = v
                dw[i] = v * wb[i]


def mean(state: ParticleState) -> np.ndarray:
    """Weighted mean ``sum_i w_i x_i`` (Carvalho et al. 1997, eq. 7), shape ``(B, n)``, float64."""
    return _mean(state.x, _weights_like(state)).astype(np.float64, copy=False)


def covariance(state: ParticleState, m: np.ndarray | None = None) -> np.ndarray:
    """Weighted covariance ``sum_i w_i (x_i - m)(x_i - m)^T`` about the weighted mean.

    Args:
        state: particles ``(B, N, n)`` and log-weights ``(B, N)``.
        m: the weighted mean if already computed, ``(B, n)``.

    Returns:
        ``(B, n, n)`` symmetric positive semi-definite matrices (float64; float32 particles are
        reduced in float32).
    """
    w = _weights_like(state)
    if m is None:
        m = _mean(state.x, w)
    return _covariance(state.x, w, m)


def mean_and_covariance(state: ParticleState, weights: np.ndarray | None = None) -> GaussianState:
    """Weighted mean ``(B, n)`` and covariance ``(B, n, n)`` as a :class:`GaussianState`.

    One weight normalization for both moments; none when ``weights``, the normalized linear
    weights ``exp(state.log_w)`` ``(B, N)``, are given (e.g. by
    :func:`filters.particle.bootstrap.update_weighted`; not re-checked).
    """
    if weights is None:
        w = _weights_like(state)
    elif np.shape(weights) != np.shape(state.log_w):
        raise ValueError(
            f"weights must have shape {np.shape(state.log_w)} like log_w; got {np.shape(weights)}"
        )
    else:
        w = weights_in(np.asarray(weights, dtype=np.float64), cloud_dtype(state.x))
    m = _mean(state.x, w)
    return GaussianState(m.astype(np.float64, copy=False), _covariance(state.x, w, m))


def healthy(state: ParticleState) -> np.ndarray:
    """Per-filter health: finite particles and log-weights with a positive total weight.

    Returns:
        ``(B,)`` booleans.
    """
    B = state.x.shape[0]
    finite_x = np.isfinite(state.x.reshape(B, -1).sum(axis=1))
    lw = np.asarray(state.log_w)
    ok_w = ~np.isnan(lw).any(axis=1) & ~(lw == np.inf).any(axis=1) & np.isfinite(lw).any(axis=1)
    return finite_x & ok_w
