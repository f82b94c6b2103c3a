"""Regularization of particle weights (Carvalho et al. 1997, §III-B) and of particle positions (jitter).

Weights. Carvalho et al. 1997, §III-B shows that the likelihood ratios of different exploration paths
degenerate as ``k`` grows (``E[r_k^q] -> inf``) and regularizes the Radon-Nikodym derivative with
a function ``alpha(k, l)`` that tempers old measurements, ``[R^alpha]^-1 = alpha(k, l) R^-1``:

* Example 1, age-weighting ``alpha(k, l) = gamma^(k-l)``: ``log Z_k^alpha = -1/2 sum_{i<=k}
  gamma^(k-i) ||Y_i - h(X_i)||^2_R`` (up to a particle-independent constant, the denominator
  of eq. 3). Its recursion is ``log w_k = gamma log w_{k-1} + log p(Y_k | X_k)``: use
  :func:`age_weight`, or ``forgetting=gamma`` in :func:`filters.particle.bootstrap.update`.
* Example 2, window: only the last measurements count, ``log Z_k^alpha = -1/2 sum_{i=k-T}^{k}
  ||Y_i - h(X_i)||^2_R``. :class:`LikelihoodWindow` keeps each particle's last ``T``
  log-likelihood increments in a ``(B, N, T)`` ring buffer and :func:`window_update` sets
  ``log w_k = sum of the window`` (normalized). Here ``T`` counts the terms kept: the paper's
  sum over ``i = k-T..k`` has ``T + 1`` terms, so pass ``T_paper + 1`` to reproduce it.

For a Gaussian likelihood ``log p(Y | X) = -1/2 ||Y - h(X)||^2_R + const``, where the constant
does not depend on the particle and cancels in eq. 6, so both recursions equal the paper's
``Z^alpha`` exactly after normalization. With non-Gaussian likelihoods the same tempering is
applied to ``log p``.

Resampling ("redistribution", Carvalho et al. 1997, §III-D) reinitializes every weight to ``1/N``; the
window of a resampled filter is therefore cleared (:func:`window_resample`): its old terms are
already represented by the particle positions.

Positions. After resampling, copies of one particle coincide; jitter restores diversity:

* :func:`roughen`: Gordon, Salmond & Smith (1993) roughening, ``x_ij += sigma_j e``, ``sigma_j
  = K E_j N^(-1/n)`` with ``E_j`` the range of component ``j`` and ``K`` a tuning constant
  (0.2 in the paper); a component-major cloud is roughened by a compiled kernel
  (:func:`_roughen_kernel`, one pass over the cloud) whose values equal the NumPy path's bit for
  bit on the same normals (``filters.core.compiled.numpy_only`` forces the NumPy path);
* :func:`kernel_jitter`: regularized PF with a Gaussian kernel (Musso, Oudjane & Le Gland 2001):
  ``x_i += h_opt L e``, ``L L^T`` the empirical covariance, ``h_opt = (4 / (N (n + 2)))^(1/(n +
  4))`` the bandwidth that minimizes the mean integrated squared error for a Gaussian target.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from filters.core.compiled import compiled_enabled
from filters.core.layout import cloud_dtype, is_component_major
from filters.core.models import ObservationModel
from filters.core.resampling import Rng, check_decision, check_rng
from filters.core.threads import over_rows
from filters.core.types import ParticleState, UpdateInfo
from filters.core.validation import batched_vector, check_measurement
from filters.particle.bootstrap import component_major_normals, psd_sqrt, weigh
from filters.particle.bootstrap import resample as _resample
from filters.particle.estimates import check_particles, covariance, normalize_log_weights

__all__ = [
    "LikelihoodWindow",
    "age_weight",
    "kernel_jitter",
    "optimal_bandwidth",
    "roughen",
    "window_init",
    "window_resample",
    "window_update",
]


def age_weight(log_w: np.ndarray, log_lik: np.ndarray, gamma: np.ndarray | float) -> np.ndarray:
    """Age-weighted log-weights (Carvalho et al. 1997, §III-B Example 1, ``alpha(k, l) = gamma^(k-l)``).

    ``log w_k^i = gamma log w_{k-1}^i + log p(Y_k | X_k^i) - log c_k`` (normalized).

    Args:
        log_w: previous log-weights ``(B, N)``.
        log_lik: per-particle log-likelihoods of the new measurement ``(B, N)``.
        gamma: forgetting factor in ``(0, 1]``, scalar or ``(B,)`` (1: no regularization).

    Returns:
        Normalized log-weights ``(B, N)``.

    """
    log_w = np.asarray(log_w, dtype=np.float64)
    log_lik = np.asarray(log_lik, dtype=np.float64)
    if log_w.ndim != 2 or log_lik.shape != log_w.shape:
        raise ValueError(f"log_lik must have the shape of log_w {log_w.shape}; got {log_lik.shape}")
    g = batched_vector(gamma, log_w.shape[0], "gamma")
    if not (np.isfinite(g).all() and (g > 0).all() and (g <= 1).all()):
        raise ValueError("gamma must lie in (0, 1]")
    out, _ = normalize_log_weights(g[:, None] * log_w + log_lik)
    return out


class LikelihoodWindow(NamedTuple):
    """Per-particle log-likelihood increments of the last ``T`` updates (Carvalho et al. 1997, Example 2).

    Attributes:
        log_lik: ring buffer ``(B, N, T)``; unused or cleared slots hold 0.
        head: ``(B,)`` int, the slot the next increment overwrites (the oldest one).

    """

    log_lik: np.ndarray
    head: np.ndarray


def window_init(B: int, N: int, T: int) -> LikelihoodWindow:
    """An empty window of ``T >= 1`` terms for ``B`` filters of ``N`` particles."""
    if not isinstance(T, (int, np.integer)) or T < 1:
        raise ValueError(f"T must be an integer >= 1; got {T!r}")
    if not isinstance(N, (int, np.integer)) or N < 1:
        raise ValueError(f"N must be an integer >= 1; got {N!r}")
    return LikelihoodWindow(np.zeros((B, N, int(T))), np.zeros(B, dtype=np.int64))


def _check_window(window: LikelihoodWindow, B: int, N: int) -> int:
    buf = window.log_lik
    if not isinstance(buf, np.ndarray) or buf.ndim != 3 or buf.shape[:2] != (B, N):
        raise ValueError(f"window.log_lik must have shape (B, N, T) with (B, N) = {(B, N)}")
    T = buf.shape[2]
    head = np.asarray(window.head)
    if head.shape != (B,) or (head < 0).any() or (head >= T).any():
        raise ValueError(f"window.head must have shape ({B},) with values in [0, {T})")
    return T


def window_update(
    state: ParticleState,
    window: LikelihoodWindow,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
) -> tuple[ParticleState, LikelihoodWindow, UpdateInfo]:
    """Measurement update with a window of ``T`` terms (Carvalho et al. 1997, §III-B Example 2).

    ``log w_k^i = sum_{l=k-T+1}^{k} log p(Y_l | X_l^i) - log c_k``: the oldest increment leaves
    the window, the new one enters. The prior weights of the Bayes step are the normalized sum of
    the ``T - 1`` terms that stay, so the diagnostics (``S``, NIS, ``log p(z | past)``, ESS) are
    those of the update actually applied. ``state.log_w`` is not read: the window determines the
    weights (it starts empty, i.e. uniform weights, and is cleared by :func:`window_resample`).

    Args:
        state: predicted particles ``(B, N, n)``.
        window: the filter's :class:`LikelihoodWindow`.
        z: measurements ``(B, m)``.
        model: observation model.
        mask: ``(B, m)`` booleans; None uses every row.
        R: measurement noise override.

    Returns:
        ``(state, window, UpdateInfo)`` after the update.

    """
    B, N, _ = check_particles(state)
    T = _check_window(window, B, N)
    z, mask = check_measurement(z, mask, B)
    head = np.asarray(window.head, dtype=np.int64)[:, None, None]
    buf = window.log_lik.copy()
    np.put_along_axis(buf, head, 0.0, axis=2)  # the oldest term leaves the window
    prior, _ = normalize_log_weights(buf.sum(axis=2))
    post, ll, info = weigh(state.x, prior, z, model, mask, R)
    # a measurement no particle explains (all weights vanish) is skipped, and flagged unhealthy
    skipped = ~np.isfinite(info.log_likelihood)
    np.put_along_axis(buf, head, np.where(skipped[:, None], 0.0, ll)[:, :, None], axis=2)
    head = head[:, 0, 0]
    return ParticleState(state.x, post), LikelihoodWindow(buf, (head + 1) % T), info


def window_resample(
    state: ParticleState,
    window: LikelihoodWindow,
    decision: np.ndarray | bool | None,
    rng: Rng,
    method: str = "systematic",
) -> tuple[ParticleState, LikelihoodWindow]:
    """Resample where ``decision`` is True and clear those filters' windows (Carvalho et al. 1997, §III-D).

    Returns:
        ``(state, window)``; untouched filters keep particles, weights and window.

    """
    B, N, _ = check_particles(state)
    _check_window(window, B, N)
    d = check_decision(decision, B)
    if not d.any():
        return state, window
    new = _resample(state, d, rng, method)
    buf = window.log_lik.copy()
    buf[d] = 0.0
    return new, LikelihoodWindow(buf, np.asarray(window.head, dtype=np.int64).copy())


def _jitter_rows(
    state: ParticleState, decision: np.ndarray | bool | None, rng: Rng
) -> tuple[int, int, int, np.ndarray]:
    B, N, n = check_particles(state)
    check_rng(rng, B)
    return B, N, n, np.flatnonzero(check_decision(decision, B))


def roughen(
    state: ParticleState,
    rng: Rng,
    K: np.ndarray | float = 0.2,
    decision: np.ndarray | bool | None = None,
) -> ParticleState:
    """Roughening of Gordon, Salmond & Smith (1993), applied where ``decision`` is True.

    ``x_ij <- x_ij + sigma_j e_ij``, ``e ~ N(0, 1)``, ``sigma_j = K E_j N^(-1/n)`` where ``E_j``
    is the range (max - min) of component ``j`` over the particles of the filter.

    Args:
        state: particles ``(B, N, n)`` (typically just resampled).
        rng: one Generator or a sequence of B.
        K: tuning constant ``>= 0``, scalar or ``(B,)`` (Gordon et al. use 0.2).
        decision: ``(B,)`` booleans (e.g. the resampling decision); None jitters every filter.

    Returns:
        The roughened state (weights unchanged).

    """
    B, N, n, rows = _jitter_rows(state, decision, rng)
    Kb = batched_vector(K, B, "K")
    if not (np.isfinite(Kb).all() and (Kb >= 0).all()):
        raise ValueError("K must be finite and >= 0")
    if rows.size == 0:
        return state
    e = component_major_normals(rng, B, N, n, rows, cloud_dtype(state.x))  # (k, N, n)
    scale = Kb[rows] * float(N) ** (-1.0 / n)  # (k,) float64
    if compiled_enabled() and is_component_major(state.x) and state.x.dtype == e.dtype:
        return _roughen_compiled(state, e, scale, rows)
    return _roughen_numpy(state, e, scale, rows)


def _roughen_numpy(state: ParticleState, e: np.ndarray, scale: np.ndarray, rows: np.ndarray) -> ParticleState:
    """:func:`roughen`'s arithmetic in NumPy (the reference): normals ``e (k, N, n)`` of ``rows``.

    ``e`` is scaled in place.
    """
    every = rows.size == state.x.shape[0]
    x = state.x if every else state.x[rows]
    sigma = (x.max(axis=1) - x.min(axis=1)) * scale[:, None]
    e *= sigma[:, None, :].astype(cloud_dtype(state.x))
    if every:
        return ParticleState(x + e, state.log_w)
    out = state.x.copy(order="K")
    out[rows] += e
    return ParticleState(out, state.log_w)


def _roughen_compiled(
    state: ParticleState, e: np.ndarray, scale: np.ndarray, rows: np.ndarray
) -> ParticleState:
    """:func:`_roughen_numpy` of a component-major cloud by :func:`_roughen_kernel` (the same values).

    One pass over the cloud instead of the NumPy path's gather of the rows, two range
    reductions, scaling, copy and scattered addition (timings in ``docs/performance.md``).
    """
    B = state.x.shape[0]
    xT = state.x.transpose(0, 2, 1)  # (B, n, N) C-contiguous
    slot = np.full(B, -1, dtype=np.int64)
    slot[rows] = np.arange(rows.size)
    out = np.empty_like(xT)
    eT = np.ascontiguousarray(e.transpose(0, 2, 1), dtype=xT.dtype)  # (k, n, N): no copy
    scale = np.ascontiguousarray(scale, dtype=np.float64)

    def filters(a: int, b: int) -> None:  # filter b reads its own cloud and its slot's normals
        _roughen_kernel(xT[a:b], eT, slot[a:b], scale, out[a:b])

    over_rows(B, xT.shape[1] * xT.shape[2], filters)
    return ParticleState(out.transpose(0, 2, 1), state.log_w)


@njit(cache=True, nogil=True)
def _roughen_kernel(xT, e, slot, scale, out):  # pragma: no cover - compiled
    """``out[b] = xT[b] + e[slot[b]] * sigma_b`` where ``slot[b] >= 0``, else ``xT[b]`` (``(B, n, N)``).

    ``sigma_bj = float(float(max_i x_bji - min_i x_bji) * scale[slot[b]])`` in the cloud's
    precision, rounded where :func:`roughen`'s NumPy path rounds (range in the cloud's
    precision, the product in float64, then cast), the product with the normal and the sum in
    the cloud's precision (no fused multiply-add); a NaN in a component gives a NaN range, as
    ``np.max``/``np.min`` do.
    """
    B, n, N = xT.shape
    sig = np.empty(1, dtype=xT.dtype)  # the cast to the cloud's precision (round to nearest)
    for b in range(B):
        r = slot[b]
        if r < 0:
            out[b] = xT[b]
            continue
        for j in range(n):
            x = xT[b, j]
            hi = x[0]
            lo = hi
            nan = False
            for i in range(1, N):  # branch-free (vectorised) range and NaN test
                v = x[i]
                hi = v if v > hi else hi
                lo = v if v < lo else lo
                nan |= v != v
            sig[0] = np.float64(hi - lo) * scale[r]
            if nan or hi != hi:  # np.max and np.min propagate a NaN
                sig[0] = np.nan
            sigma = sig[0]
            o = out[b, j]
            ej = e[r, j]
            for i in range(N):
                o[i] = x[i] + ej[i] * sigma
    return out


def optimal_bandwidth(N: int, n: int) -> float:
    """Optimal Gaussian-kernel bandwidth ``(4 / (N (n + 2)))^(1 / (n + 4))`` (Musso et al. 2001).

    It minimizes the mean integrated squared error of the kernel density estimate when the
    target is Gaussian with unit covariance (Silverman 1986, eq. 4.14).
    """
    if N < 1 or n < 1:
        raise ValueError(f"N and n must be >= 1; got N={N}, n={n}")
    return float((4.0 / (N * (n + 2.0))) ** (1.0 / (n + 4.0)))


def kernel_jitter(
    state: ParticleState,
    rng: Rng,
    decision: np.ndarray | bool | None = None,
    bandwidth_scale: np.ndarray | float = 1.0,
    cov: np.ndarray | None = None,
) -> ParticleState:
    """Regularized-PF Gaussian kernel jitter (Musso, Oudjane & Le Gland 2001).

    ``x_i <- x_i + c h_opt L e_i``, ``e_i ~ N(0, I)``, ``L L^T = cov`` (the weighted empirical
    covariance of the cloud by default: pass the pre-resampling covariance for the textbook
    post-regularized filter), ``h_opt`` from :func:`optimal_bandwidth` and ``c`` the
    ``bandwidth_scale`` knob.

    Args:
        state: particles ``(B, N, n)``.
        rng: one Generator or a sequence of B.
        decision: ``(B,)`` booleans; None jitters every filter.
        bandwidth_scale: ``c >= 0``, scalar or ``(B,)``.
        cov: ``(B, n, n)`` covariance to shape the kernel; None uses :func:`covariance`.

    Returns:
        The jittered state (weights unchanged).

    """
    B, N, n, rows = _jitter_rows(state, decision, rng)
    c = batched_vector(bandwidth_scale, B, "bandwidth_scale")
    if not (np.isfinite(c).all() and (c >= 0).all()):
        raise ValueError("bandwidth_scale must be finite and >= 0")
    if cov is not None:
        cov = np.asarray(cov, dtype=np.float64)
        if cov.shape != (B, n, n) or not np.isfinite(cov).all():
            raise ValueError(f"cov must be finite with shape {(B, n, n)}; got {cov.shape}")
    if rows.size == 0:
        return state
    sub = ParticleState(state.x[rows], np.asarray(state.log_w)[rows])
    C = covariance(sub) if cov is None else cov[rows]
    L = psd_sqrt(C) * (optimal_bandwidth(N, n) * c[rows])[:, None, None]
    dtype = cloud_dtype(state.x)
    e = component_major_normals(rng, B, N, n, rows, dtype)  # (k, N, n) view of (k, n, N)
    out = state.x.copy(order="K")
    out[rows] += (L.astype(dtype) @ e.transpose(0, 2, 1)).transpose(0, 2, 1)
    return ParticleState(out, state.log_w)
