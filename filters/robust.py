"""Robust (M-estimation) EKF and iterated-EKF updates with Huber and Tukey weights (Belles et al. 2022).

The robust update solves (Belles et al. 2022, eq. 18-20)::

    x+ = argmin |x - m-|^2_{P-} + |h(x) - z|^2_{R_bar},
    R_bar = R^{1/2} W^-1 R^{T/2},   W = diag w(R^{-1/2} (z - h(x)))

by iterative reweighting (Algorithm 1): start with ``W = I`` (the plain update), then
alternately recompute the weights from the whitened residuals at the current estimate and
re-solve with those weights, until the weights stop changing. Weights multiply ``R^-1`` per
whitened residual component, as in the robust information filter (eq. 21-22, 26-28)::

    Z = Z- + H^T R^{-T/2} W R^{-1/2} H,   x = m- + Z^-1 dz.

We evaluate the information update in its equivalent whitened covariance form (Woodbury):
with ``H_w = W^{1/2} R^{-1/2} H`` and ``r_w = W^{1/2} R^{-1/2} r``, the Kalman update with
observation matrix ``H_w`` and unit noise gives exactly ``P+ = Z^-1`` and the same mean, without
inverting ``P-``. A zero weight (Tukey's redescending function) zeroes a row of ``H_w`` and
``r_w``: the observation contributes exactly nothing, as a masked row, so redescending weights are
safe -- nothing is divided by a weight.

* :func:`update`: EKF linearization at ``m-`` (one Gauss-Newton step per weighting).
* :func:`iterated_update`: the robust iterated EKF of Algorithm 1, where each weighting is
  solved by the Gauss-Newton recursion eq. 26-28 (relinearizing ``H`` at every inner step).

The threshold ``c (B,)`` is a knob (an argument per filter and step); ``c = inf`` gives
weights 1 and returns the plain :func:`filters.kalman.update` /
:func:`~filters.kalman.iterated_update` exactly. Defaults are the 95 %-efficiency constants of
Belles et al. 2022, Table 1: Huber 1.345, Tukey 4.685.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal, NamedTuple

import numpy as np

from filters import kalman
from filters.core.conditioning import condition, health, masked_covariance
from filters.core.linalg import cholesky
from filters.core.models import LinearizedObservation, innovation
from filters.core.types import GaussianState
from filters.core.validation import (
    batched_matrix,
    batched_vector,
    check_gaussian,
    check_measurement,
)

__all__ = [
    "DEFAULT_THRESHOLDS",
    "RobustInfo",
    "huber_weights",
    "iterated_update",
    "tukey_weights",
    "update",
]


def huber_weights(e: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Huber weights: 1 for ``|e| <= c``, else ``c / |e|`` (Huber 1964; Belles et al. 2022, Fig. 2).

    Args:
        e: whitened residuals ``(B, m)``.
        c: thresholds ``(B,)`` (``inf`` gives 1 everywhere).

    """
    a = np.abs(e)
    c = np.asarray(c)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a <= c, 1.0, c / a)


def tukey_weights(e: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Tukey bisquare weights: ``(1 - (e/c)^2)^2`` for ``|e| < c``, else 0 (Belles et al. 2022, Fig. 2).

    Args:
        e: whitened residuals ``(B, m)``.
        c: thresholds ``(B,)`` (``inf`` gives 1 everywhere).

    """
    u = e / np.asarray(c)[:, None]
    return np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)


#: Weight functions by name and their default thresholds (95 % Gaussian efficiency,
#: Belles et al. 2022, Table 1).
WEIGHT_FUNCTIONS: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    "huber": huber_weights,
    "tukey": tukey_weights,
}
DEFAULT_THRESHOLDS: dict[str, float] = {"huber": 1.345, "tukey": 4.685}


class RobustInfo(NamedTuple):
    """Diagnostics of a robust update: the fields of ``UpdateInfo`` plus the weights.

    ``innovation``, ``S``, ``nis`` and ``log_likelihood`` are those of the nominal (``W = I``)
    update, i.e. of :func:`filters.kalman.update` (or ``iterated_update``), so they stay
    comparable across thresholds; ``healthy`` also checks the robust posterior.

    Attributes:
        weights: final weights ``w`` per (whitened) measurement row, ``(B, m)`` (1 on masked rows).
        iterations: solves performed per filter, ``(B,)``: the reweighted ones, plus one for
            the plain update that ``start="plain"`` begins with.

    """

    innovation: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    log_likelihood: np.ndarray
    healthy: np.ndarray
    n_meas: np.ndarray
    ess: np.ndarray | None
    resampled: np.ndarray | None
    weights: np.ndarray
    iterations: np.ndarray


WeightArg = str | Callable[[np.ndarray, np.ndarray], np.ndarray]


Start = Literal["plain", "prior"]


def update(
    state: GaussianState,
    z: np.ndarray,
    model: LinearizedObservation,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
    *,
    threshold: np.ndarray | float | None = None,
    weight: WeightArg = "huber",
    start: Start = "plain",
    max_iter: int = 20,
    tol: float = 1e-6,
) -> tuple[GaussianState, RobustInfo]:
    """Robust EKF update by iteratively reweighted least squares (Belles et al. 2022, eq. 18-22, Algorithm 1).

    ``H = dh/dx`` at ``m-``. Iteration p: ``e = R^{-1/2} (z - h(x^(p)))``, ``W = diag w(e)``
    (eq. 20), then ``x^(p+1), P^(p+1)`` = the information update eq. 21-22 with weights ``W``
    (evaluated in whitened covariance form, see the module docstring). Stops when no weight moved
    more than ``tol`` or after ``max_iter`` reweighted solves (with ``start="plain"`` they follow
    the plain update, so at most ``1 + max_iter`` solves).

    ``start="plain"`` is Algorithm 1 as written: ``W^(0) = I``, so ``x^(1)`` is the plain EKF
    update and the first weights are computed from its residuals. ``start="prior"`` computes the
    first weights at ``x^(0) = m-`` from the normalized innovations ``v_i / sqrt(S_ii)`` instead
    (not in Belles et al. 2022). For Huber's convex cost both reach the same fixed point. Tukey's
    redescending cost has local minima: when gross outliers hit while the prior is still weak,
    the plain update is dragged far and Algorithm 1 may then zero the good observations; the
    ``"prior"`` start avoids part of that. With a converged prior (Belles et al. 2022's scenario) both
    starts agree.

    Args:
        state: predicted beliefs.
        z: measurements ``(B, m)``.
        model: observation model with ``h``, ``H`` and ``R``.
        mask: ``(B, m)`` booleans or None.
        R: measurement noise override.
        threshold: ``c``, scalar or ``(B,)``, ``> 0`` (``inf`` allowed: the plain update);
            None uses the default of ``weight`` (Huber 1.345, Tukey 4.685).
        weight: ``"huber"``, ``"tukey"`` or a function ``w(e (B, m), c (B,)) -> (B, m)`` in [0, 1].
        start: ``"plain"`` (Algorithm 1) or ``"prior"``, see above.
        max_iter: maximum reweighted solves (>= 1), after the plain one of ``start="plain"``.
        tol: convergence tolerance on the weights.

    Returns:
        ``(filtered state, RobustInfo)``.

    """
    return _robust(state, z, model, mask, R, threshold, weight, start, max_iter, tol, iterated=False)


def iterated_update(
    state: GaussianState,
    z: np.ndarray,
    model: LinearizedObservation,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
    *,
    threshold: np.ndarray | float | None = None,
    weight: WeightArg = "huber",
    start: Start = "plain",
    max_iter: int = 20,
    tol: float = 1e-6,
    max_inner: int = 10,
    inner_tol: float = 1e-8,
) -> tuple[GaussianState, RobustInfo]:
    """Robust iterated EKF update (Belles et al. 2022, Algorithm 1 with eq. 26-28).

    For each weighting ``W``, the Gauss-Newton recursion (eq. 26-28, vector-space form)::

        x^(0) = m-,
        x^(i+1) = m- + K_W^(i) (r_W(x^(i)) + H_W^(i) (x^(i) - m-)),
        H_W^(i) = W^{1/2} R^{-1/2} H(x^(i)),  r_W(x) = W^{1/2} R^{-1/2} (z - h(x)),
        K_W^(i) = P- H_W^T (H_W P- H_W^T + I)^-1   (= (Z^(i+1))^-1 H_W^T)

    runs until the step is below ``inner_tol`` (relative) or ``max_inner`` steps; the weights are
    then recomputed at the solution (outer loop of Algorithm 1). With ``start="plain"`` the
    first weighting ``W = I`` is :func:`filters.kalman.iterated_update`.

    Args:
        state: predicted beliefs.
        z: measurements ``(B, m)``.
        model: observation model with ``h``, ``H`` and ``R``.
        mask: ``(B, m)`` booleans or None.
        R: measurement noise override.
        threshold: ``c`` as in :func:`update`.
        weight: ``"huber"``, ``"tukey"`` or a weight function, as in :func:`update`.
        start: ``"plain"`` or ``"prior"``, as in :func:`update`.
        max_iter: maximum reweighted solves (>= 1), after the plain one of ``start="plain"``.
        tol: convergence tolerance on the weights.
        max_inner: Gauss-Newton iterations per weighting (>= 1).
        inner_tol: Gauss-Newton tolerance on ``|dx| / (1 + |x|)``.

    Returns:
        ``(filtered state, RobustInfo)``.

    """
    if max_inner < 1:
        raise ValueError(f"max_inner must be >= 1; got {max_inner}")
    return _robust(
        state,
        z,
        model,
        mask,
        R,
        threshold,
        weight,
        start,
        max_iter,
        tol,
        iterated=True,
        max_inner=max_inner,
        inner_tol=inner_tol,
    )


def _robust(
    state: GaussianState,
    z: np.ndarray,
    model: LinearizedObservation,
    mask: np.ndarray | None,
    R: np.ndarray | None,
    threshold: np.ndarray | float | None,
    weight: WeightArg,
    start: Start,
    max_iter: int,
    tol: float,
    iterated: bool,
    max_inner: int = 10,
    inner_tol: float = 1e-8,
) -> tuple[GaussianState, RobustInfo]:
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    R = batched_matrix(model.R if R is None else R, B, (mdim, mdim), "R")
    wfun, c = _weight_function(weight, threshold, B)
    if start not in ("plain", "prior"):
        raise ValueError(f"start must be 'plain' or 'prior'; got {start!r}")
    if max_iter < 1:
        raise ValueError(f"max_iter must be >= 1; got {max_iter}")
    if not tol >= 0:
        raise ValueError(f"tol must be >= 0; got {tol}")

    # W = I: the plain (iterated) EKF update (Algorithm 1 initialization; also the c = inf result).
    if iterated:
        plain, info = kalman.iterated_update(
            state, z, model, mask=mask, R=R, max_iter=max_inner, tol=inner_tol
        )
    else:
        plain, info = kalman.update(state, z, model, mask=mask, R=R)

    m0, P0 = state
    w_row = mask.astype(np.float64)
    Rm = masked_covariance(np.asarray(R), w_row)
    chol_R, r_ok = cholesky(Rm)
    L_inv = np.linalg.inv(chol_R)  # R^{-1/2}, block-diagonal on masked rows

    def whitened_residual(x: np.ndarray) -> np.ndarray:
        r = innovation(model, z, model.h(x))
        return (L_inv @ (r * w_row)[:, :, None])[:, :, 0]

    def jacobian(x: np.ndarray) -> np.ndarray:
        H = np.broadcast_to(batched_matrix(model.H(x), B, (mdim, n), "H"), (B, mdim, n))
        return L_inv @ (H * w_row[:, :, None])

    H0 = np.broadcast_to(batched_matrix(model.H(m0), B, (mdim, n), "H"), (B, mdim, n)) * w_row[:, :, None]
    r0 = innovation(model, z, model.h(m0)) * w_row
    J0 = L_inv @ H0
    e0 = (L_inv @ r0[:, :, None])[:, :, 0]
    steps = max_inner if iterated else 1

    def solve(W: np.ndarray, idx: np.ndarray) -> GaussianState:
        """Weighted information update (eq. 26-28) of the filters ``idx``."""
        sw = np.sqrt(W[idx])
        m0s, P0s, mask_s = m0[idx], P0[idx], mask[idx]
        xs = m0s
        x_full = m0.copy()  # models see the whole batch (parameters may be batched over B)
        live = np.ones(idx.size, dtype=bool)
        P_out = P0s  # replaced at the first step (every filter is live there)
        for i in range(steps):
            if i == 0:  # x = m-: the EKF linearization
                J, e = J0[idx], e0[idx]
            else:  # eq. 26: z - h(x) + H (x - m-), whitened
                x_full[idx] = xs
                J = jacobian(x_full)[idx]
                e = whitened_residual(x_full)[idx] + (J @ (xs - m0s)[:, :, None])[:, :, 0]
            Hw = sw[:, :, None] * J
            PHt = P0s @ np.swapaxes(Hw, -1, -2)
            post, _ = condition(m0s, P0s, sw * e, Hw @ PHt + np.eye(mdim), PHt, mask_s)
            step = np.linalg.norm(post.m - xs, axis=1) / (1.0 + np.linalg.norm(xs, axis=1))
            # a converged filter keeps its result (xs and P_out): the batch equals separate runs
            xs = np.where(live[:, None], post.m, xs)
            P_out = np.where(live[:, None, None], post.P, P_out)
            live = live & (step > inner_tol)
            if not live.any():
                break
        return GaussianState(xs, P_out)

    if start == "plain":  # Algorithm 1: W^(0) = I, x^(1) = the plain update
        x, P = plain.m.copy(), plain.P.copy()
        W_used = np.ones((B, mdim))
        iters = np.ones(B, dtype=np.int64)
    else:  # first weights at x^(0) = m-, from the normalized innovations v_i / sqrt(S_ii)
        x, P = m0.copy(), P0.copy()
        W_used = np.full((B, mdim), -1.0)
        iters = np.zeros(B, dtype=np.int64)
        S_diag = np.einsum("bin,bnk,bik->bi", H0, P0, H0) + np.diagonal(Rm, axis1=1, axis2=2)
        e_first = r0 / np.sqrt(S_diag)
    active = np.ones(B, dtype=bool)
    for p in range(max_iter):
        e = e_first if (p == 0 and start == "prior") else whitened_residual(x)
        W = np.where(mask, _checked_weights(wfun(e, c), B, mdim), 1.0)
        active = active & (np.abs(W - W_used).max(axis=1) > tol)
        if not active.any():
            break
        idx = np.flatnonzero(active)
        post = solve(W, idx)
        x[idx], P[idx], W_used[idx] = post.m, post.P, W[idx]
        iters[idx] += 1
    # Members that never left W = I keep the plain update bit for bit (c = inf, no outliers).
    nominal = (W_used == 1.0).all(axis=1)
    x = np.where(nominal[:, None], plain.m, x)
    P = np.where(nominal[:, None, None], plain.P, P)
    healthy = info.healthy & health(x, P) & r_ok
    rinfo = RobustInfo(
        info.innovation,
        info.S,
        info.nis,
        info.log_likelihood,
        healthy,
        info.n_meas,
        None,
        None,
        W_used,
        iters,
    )
    return GaussianState(x, P), rinfo


def _weight_function(
    weight: WeightArg, threshold: np.ndarray | float | None, B: int
) -> tuple[Callable[[np.ndarray, np.ndarray], np.ndarray], np.ndarray]:
    if callable(weight):
        wfun, default = weight, None
    else:
        if weight not in WEIGHT_FUNCTIONS:
            raise ValueError(
                f"weight must be one of {sorted(WEIGHT_FUNCTIONS)} or a function; got {weight!r}"
            )
        wfun, default = WEIGHT_FUNCTIONS[weight], DEFAULT_THRESHOLDS[weight]
    if threshold is None:
        if default is None:
            raise ValueError("threshold is required with a custom weight function")
        threshold = default
    c = batched_vector(threshold, B, "threshold")
    if np.isnan(c).any() or (c <= 0).any():
        raise ValueError(f"threshold must be > 0 (inf allowed) and not NaN; got {c.min()}..{c.max()}")
    return wfun, c


def _checked_weights(W: np.ndarray, B: int, mdim: int) -> np.ndarray:
    W = np.asarray(W, dtype=np.float64)
    if W.shape != (B, mdim):
        raise ValueError(f"weight function returned shape {W.shape}; expected {(B, mdim)}")
    if not (np.isfinite(W).all() and (W >= 0).all() and (W <= 1).all()):
        raise ValueError("weight function must return finite weights in [0, 1]")
    return W
