"""Adaptive Gaussian filtering: fading factors, strong tracking and Sage-Husa noise estimation.

The fading factor ``lambda (B,)`` is a *knob*: every predict in :mod:`filters.registry` takes
``fading=`` and forms ``P- = lambda * spread + Q`` (Benzerrouk 2014, eq. 64 and 67-69). This module
holds the two other pieces an adaptive filter needs, as pure functions on small NamedTuple
states that a baseline (or an agent's feature extractor) carries between steps:

* the **classical formulas** that compute ``lambda`` from innovations:

  - :func:`suboptimal_fading_factor`, Benzerrouk 2014, eq. 67-70 (Xia et al. 1994 form):
    ``lambda = max(1, tr N / tr M)``, ``N = gamma V - beta R - H Q H^T``,
    ``M = H Phi P Phi^T H^T``, ``V_k = (rho V_{k-1} + v v^T) / (1 + rho)``;
  - :func:`strong_tracking_factor`, the single-factor strong tracking filter of
    Zhou & Frank (1996), the same structure with ``gamma = 1`` and a softening ``beta >= 1``;
  - :func:`innovation_fading_factor`, the sigma-point form of Benzerrouk 2014, eq. 63,
    ``lambda = max(1, tr[eta V - eps R] / tr[P_yy])``, that pairs with the update-side form;

  with :func:`fading_terms` computing ``v``, ``M`` and ``H Q H^T`` for *any* filter of the
  registry (EKF: Jacobians; sigma-point and divided-difference filters: their own moment rule,
  see its docstring for the sigma-point equivalent of ``H Phi P Phi^T H^T``);

* the **update-side** fading of Benzerrouk 2014, eq. 65-66 for sigma-point filters
  (:func:`fading_update`, :func:`adaptive_fading_update`), and

* **Sage-Husa** noise estimation with forgetting factor ``b`` (Sage & Husa 1969):
  :func:`sage_husa_init`, :func:`sage_husa_update` recursively estimate ``R`` (and
  optionally ``Q``) to pass as the ``R=`` / ``Q=`` overrides of the registry's steps.

A typical predict-side adaptive EKF/CKF step (Benzerrouk 2014 "AF-EKF", "AF-CKF")::

    flt = registry.get("ckf")
    terms = fading_terms(flt, state, z, trans, obs, mask=mask)
    lam, memory = suboptimal_fading_factor(memory, terms, rho=0.95, beta=1.0)
    state, info = flt.update(flt.predict(state, trans, fading=lam), z, obs, mask)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from filters.core.conditioning import condition_moments
from filters.core.linalg import symmetrize
from filters.core.models import ObservationModel, TransitionModel
from filters.core.quadrature import Cubature, Quadrature
from filters.core.types import GaussianState, UpdateInfo
from filters.core.validation import (
    batched_matrix,
    batched_vector,
    check_gaussian,
    check_measurement,
    fading_factor,
)
from filters.registry import GaussianFilter
from filters.registry import get as get_filter
from filters.sigma_point import predict_measurement

#: Default rule (a module-level instance: the rules are frozen dataclasses).
CUBATURE = Cubature()

__all__ = [
    "FadingMemory",
    "FadingTerms",
    "SageHusaState",
    "adaptive_fading_update",
    "fading_terms",
    "fading_update",
    "init_fading_memory",
    "innovation_covariance",
    "innovation_fading_factor",
    "sage_husa_init",
    "sage_husa_update",
    "strong_tracking_factor",
    "suboptimal_fading_factor",
]


# --------------------------------------------------------------------------------------------
# Innovation covariance memory (Benzerrouk 2014, eq. 70)
# --------------------------------------------------------------------------------------------


class FadingMemory(NamedTuple):
    """State carried between steps by the innovation-based fading formulas.

    Attributes:
        V: running innovation covariance estimate ``V_k`` (Benzerrouk 2014, eq. 70), ``(B, m, m)``.
        k: number of innovations absorbed so far, ``(B,)`` int.

    """

    V: np.ndarray
    k: np.ndarray


class FadingTerms(NamedTuple):
    """What the predict-side formulas need at step k (see :func:`fading_terms`).

    Attributes:
        v: innovation of the measurement against the (unfaded) predicted mean, ``(B, m)``.
        M: ``H Phi P Phi^T H^T`` or its sigma-point equivalent (Benzerrouk 2014, eq. 69), ``(B, m, m)``.
        HQH: ``H Q H^T`` or its sigma-point equivalent, ``(B, m, m)``.
        R: measurement noise covariance used, ``(B, m, m)``.
        mask: ``(B, m)`` booleans, rows used.

    """

    v: np.ndarray
    M: np.ndarray
    HQH: np.ndarray
    R: np.ndarray
    mask: np.ndarray


def init_fading_memory(B: int, m: int) -> FadingMemory:
    """Empty memory for B filters with m measurement rows (``V`` is set by the first innovation)."""
    if B < 1 or m < 1:
        raise ValueError(f"B and m must be >= 1; got B={B}, m={m}")
    return FadingMemory(np.zeros((B, m, m)), np.zeros(B, dtype=np.int64))


def innovation_covariance(
    memory: FadingMemory,
    v: np.ndarray,
    rho: np.ndarray | float = 0.95,
    mask: np.ndarray | None = None,
) -> FadingMemory:
    """Fading-memory innovation covariance (Benzerrouk 2014, eq. 70; Zhou & Frank 1996 eq. 14).

    ``V_0 = v_0 v_0^T``, ``V_k = (rho V_{k-1} + v_k v_k^T) / (1 + rho)`` for ``k >= 1``.

    Masked rows enter with a zero innovation (their entries of ``V`` decay), and are ignored by
    the formulas that read ``V``.

    Args:
        memory: previous :class:`FadingMemory`.
        v: innovations ``(B, m)``.
        rho: forgetting factor, ``0 < rho < 1``, scalar or ``(B,)``.
        mask: ``(B, m)`` booleans or None.

    Returns:
        The updated memory.

    """
    V_prev, k = _check_memory(memory)
    B, m = V_prev.shape[:2]
    v, mask = check_measurement(v, mask, B, m)
    rho = _in_open_interval(rho, B, "rho", 0.0, 1.0)
    v = np.where(mask, v, 0.0)
    vvT = v[:, :, None] * v[:, None, :]
    r = rho[:, None, None]
    V = np.where((k == 0)[:, None, None], vvT, (r * V_prev + vvT) / (1.0 + r))
    return FadingMemory(V, k + 1)


# --------------------------------------------------------------------------------------------
# Predict-side formulas (Benzerrouk 2014, eq. 67-70; Zhou & Frank 1996)
# --------------------------------------------------------------------------------------------


def fading_terms(
    flt: GaussianFilter | str,
    state: GaussianState,
    z: np.ndarray,
    transition: TransitionModel,
    observation: ObservationModel,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    mask: np.ndarray | None = None,
    Q: np.ndarray | None = None,
    R: np.ndarray | None = None,
) -> FadingTerms:
    """Innovation, ``M`` and ``H Q H^T`` of Benzerrouk 2014, eq. 68-69 for any registered filter.

    With ``m-``, ``P- = C + Q`` the filter's own unfaded prediction (``C`` the propagated spread,
    ``Phi P Phi^T`` for the EKF), the filter's own update moments give::

        S(P-) = P_zz(P-) + R,   S(C) = P_zz(C) + R,
        M = S(C) - R = P_zz(C),   H Q H^T = S(P-) - S(C),   v = z - z_hat(P-).

    For the EKF ``P_zz(C) = H C H^T = H Phi P Phi^T H^T`` and ``S(P-) - S(C) = H Q H^T``
    exactly (eq. 69). For sigma-point (UKF, CKF, GHKF) and divided-difference filters, ``M`` is
    the measurement spread of the rule's points placed on ``N(m-, Phi P Phi^T)`` -- the
    sigma-point image of the propagated covariance without process noise -- and ``H Q H^T``
    the extra spread that ``Q`` adds; both reduce to the EKF terms for a linear model.

    Args:
        flt: a :class:`~filters.registry.GaussianFilter` or its registry name.
        state: filtered beliefs at ``k - 1``.
        z: measurements at ``k``, ``(B, m)``.
        transition: transition model.
        observation: observation model.
        u: control of the prediction, or None.
        dt: time step of the prediction.
        mask: ``(B, m)`` booleans or None.
        Q: process noise override (as in the filter's own predict).
        R: measurement noise override (as in the filter's own update).

    Returns:
        :class:`FadingTerms` with masked rows and columns of ``M``, ``HQH`` and ``R`` zeroed.

    """
    flt = get_filter(flt) if isinstance(flt, str) else flt
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    Qm = batched_matrix(transition.Q if Q is None else Q, B, (n, n), "Q")
    Rm = np.broadcast_to(
        batched_matrix(observation.R if R is None else R, B, (mdim, mdim), "R"), (B, mdim, mdim)
    )
    pred = flt.predict(state, transition, u, dt, Q=Qm)
    spread = GaussianState(pred.m, symmetrize(pred.P - Qm))
    _, info = flt.update(pred, z, observation, mask=mask, R=Rm)
    _, info0 = flt.update(spread, z, observation, mask=mask, R=Rm)
    w = mask.astype(np.float64)
    ww = w[:, :, None] * w[:, None, :]
    M = (info0.S - Rm) * ww
    HQH = (info.S - info0.S) * ww
    return FadingTerms(info.innovation, M, HQH, Rm * ww, mask)


def suboptimal_fading_factor(
    memory: FadingMemory,
    terms: FadingTerms,
    rho: np.ndarray | float = 0.95,
    beta: np.ndarray | float = 1.0,
    gamma: np.ndarray | float = 1.0,
) -> tuple[np.ndarray, FadingMemory]:
    """Suboptimal fading factor (Benzerrouk 2014, eq. 67-70; Xia, Rao, Ying & Shen 1994).

    ::

        V_k = (rho V_{k-1} + v_k v_k^T) / (1 + rho)        (eq. 70, V_0 = v_0 v_0^T)
        N_k = gamma V_k - beta R_k - H_k Q_k H_k^T          (eq. 68)
        M_k = H_k Phi_k P_k Phi_k^T H_k^T                   (eq. 69)
        lambda_k = max(1, tr N_k / tr M_k)                  (eq. 67)

    to be used as ``fading=lambda_k`` in the predict of step k (``P- = lambda F P F^T + Q``).
    Traces run over unmasked rows; ``lambda = 1`` where ``tr M <= 0``.

    Args:
        memory: :class:`FadingMemory` (from :func:`init_fading_memory` at the first step).
        terms: :func:`fading_terms` of this step.
        rho: forgetting factor ``0 < rho < 1`` (scalar or ``(B,)``).
        beta: softening factor ``> 0`` on ``R`` (larger: fewer false alarms, slower reaction).
        gamma: weight ``> 0`` on ``V`` (eq. 68).

    Returns:
        ``(lambda (B,), updated memory)``, ``lambda >= 1``.

    """
    memory = innovation_covariance(memory, terms.v, rho, terms.mask)
    B = terms.v.shape[0]
    beta = _positive(beta, B, "beta")
    gamma = _positive(gamma, B, "gamma")
    w = terms.mask.astype(np.float64)
    tr = lambda A: np.einsum("bii,bi->b", A, w)  # noqa: E731  (trace over unmasked rows)
    trN = gamma * tr(memory.V) - beta * tr(terms.R) - tr(terms.HQH)
    return _ratio_at_least_one(trN, tr(terms.M)), memory


def strong_tracking_factor(
    memory: FadingMemory,
    terms: FadingTerms,
    rho: np.ndarray | float = 0.95,
    beta: np.ndarray | float = 1.0,
) -> tuple[np.ndarray, FadingMemory]:
    """Single-factor strong tracking filter (Zhou & Frank 1996, *Int. J. Control* 65(2)).

    The STF enforces the orthogonality of innovations by the suboptimal fading factor::

        V_0 = v_0 v_0^T,   V_k = (rho V_{k-1} + v_k v_k^T) / (1 + rho)
        N_k = V_k - H Q H^T - beta R,   M_k = H F P F^T H^T
        c_k = tr N_k / tr M_k,   lambda_k = c_k if c_k > 1 else 1

    with forgetting factor ``rho`` (0.95 in the paper) and softening factor ``beta >= 1``. It is
    :func:`suboptimal_fading_factor` with ``gamma = 1`` (the multiple-factor variant with
    weights ``alpha_i`` per state needs a diagonal fading matrix, which the predict steps do not
    take). Zhou & Frank's nonlinear STF linearizes like the EKF; with :func:`fading_terms` of a
    sigma-point filter this gives the sigma-point STF.

    Args:
        memory: :class:`FadingMemory`.
        terms: :func:`fading_terms` of this step.
        rho: forgetting factor, ``0 < rho < 1``.
        beta: softening factor, ``>= 1``.

    Returns:
        ``(lambda (B,), updated memory)``.

    """
    B = terms.v.shape[0]
    beta_v = batched_vector(beta, B, "beta")
    if not (np.isfinite(beta_v).all() and (beta_v >= 1.0).all()):
        raise ValueError("beta (softening factor) must be finite and >= 1")
    return suboptimal_fading_factor(memory, terms, rho=rho, beta=beta_v, gamma=1.0)


def innovation_fading_factor(
    memory: FadingMemory,
    v: np.ndarray,
    P_yy: np.ndarray,
    R: np.ndarray,
    mask: np.ndarray | None = None,
    rho: np.ndarray | float = 0.95,
    eta: np.ndarray | float = 1.0,
    eps: np.ndarray | float = 1.0,
) -> tuple[np.ndarray, FadingMemory]:
    """Sigma-point fading factor of Benzerrouk 2014, eq. 63.

    ::

        V_k = (rho V_{k-1} + v_k v_k^T) / (1 + rho)
        lambda_k = max(1, tr[eta V_k - eps R_k] / tr[P_yy])

    where ``P_yy = sum wc (Y_i - y_hat)(Y_i - y_hat)^T`` is the measurement spread of the
    predicted sigma points (without ``R``). ``lambda`` is the factor for which
    ``tr(lambda P_yy + R) = tr(V)`` (``eta = eps = 1``): it pairs with the update-side form of
    eq. 65-66 (:func:`fading_update`), which scales ``P_yy`` and ``P_xy`` by ``lambda``.

    Args:
        memory: :class:`FadingMemory`.
        v: innovations ``(B, m)``.
        P_yy: measurement spreads ``(B, m, m)``.
        R: measurement noise ``(m, m)`` or ``(B, m, m)``.
        mask: ``(B, m)`` booleans or None.
        rho: forgetting factor, ``0 < rho < 1``.
        eta: weight ``> 0`` of ``V`` (eq. 63).
        eps: weight ``> 0`` of ``R`` (eq. 63).

    Returns:
        ``(lambda (B,), updated memory)``.

    """
    memory = innovation_covariance(memory, v, rho, mask)
    B, mdim = memory.V.shape[:2]
    w = (np.ones((B, mdim)) if mask is None else np.asarray(mask, dtype=bool)).astype(np.float64)
    P_yy = np.broadcast_to(batched_matrix(P_yy, B, (mdim, mdim), "P_yy"), (B, mdim, mdim))
    R = np.broadcast_to(batched_matrix(R, B, (mdim, mdim), "R"), (B, mdim, mdim))
    eta = _positive(eta, B, "eta")
    eps = _positive(eps, B, "eps")
    tr = lambda A: np.einsum("bii,bi->b", A, w)  # noqa: E731
    return _ratio_at_least_one(eta * tr(memory.V) - eps * tr(R), tr(P_yy)), memory


# --------------------------------------------------------------------------------------------
# Update-side fading (Benzerrouk 2014, eq. 65-66)
# --------------------------------------------------------------------------------------------


def fading_update(
    state: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    fading: np.ndarray | float | None = None,
    rule: Quadrature = CUBATURE,
    R: np.ndarray | None = None,
) -> tuple[GaussianState, UpdateInfo]:
    """Sigma-point update with the fading factor on the update side (Benzerrouk 2014, eq. 65-66).

    Sigma points ``X_i`` are placed on the (unfaded) predicted ``N(m-, P-)``, ``Y_i = h(X_i)``,
    and ``lambda`` scales the spreads::

        S    = lambda sum wc (Y_i - y_hat)(Y_i - y_hat)^T + R          (eq. 65)
        P_xy = lambda sum wc (X_i - m-)(Y_i - y_hat)^T                 (eq. 66)
        W = P_xy S^-1,  m+ = m- + W v,  P+ = lambda P- - W S W^T        (eq. 60-62)

    Our reading of eq. 62: the prior covariance whose spreads eq. 65-66 scale is ``lambda P-``,
    and only with it is ``P+`` a Kalman update (positive semi-definite for every ``lambda``;
    with ``P-`` itself, ``P+`` turns indefinite for large ``lambda``). For a linear model this
    is exactly the Kalman update from the inflated prior ``N(m-, lambda P-)`` -- ``Q``
    included, unlike the predict-side eq. 64 which inflates only the propagated spread. Use one
    side or the other in a step, not both. ``fading=None`` or 1 is
    :func:`filters.sigma_point.update` exactly.

    Args:
        state: predicted beliefs (unfaded).
        z: measurements ``(B, m)``.
        model: observation model (``h`` broadcasting over ``(B, S, n)``, ``R``).
        mask: ``(B, m)`` booleans or None.
        fading: ``lambda``, scalar or ``(B,)``, positive; None means 1.
        rule: quadrature rule (default cubature: the AF-CKF).
        R: measurement noise override.

    Returns:
        ``(filtered state, UpdateInfo)``; ``info.S`` is the faded innovation covariance.

    """
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    lam = fading_factor(fading, B)
    R = batched_matrix(model.R if R is None else R, B, (z.shape[1], z.shape[1]), "R")
    mom = predict_measurement(state, z, model, rule)
    P = state.P
    if lam is not None:
        mom, P = mom.faded(lam), lam[:, None, None] * P
    return condition_moments(state.m, P, mom, R, mask)


def adaptive_fading_update(
    state: GaussianState,
    memory: FadingMemory,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    rule: Quadrature = CUBATURE,
    R: np.ndarray | None = None,
    rho: np.ndarray | float = 0.95,
    eta: np.ndarray | float = 1.0,
    eps: np.ndarray | float = 1.0,
) -> tuple[GaussianState, UpdateInfo, FadingMemory, np.ndarray]:
    """Adaptive fading sigma-point update, Benzerrouk 2014, eq. 63 with eq. 65-66 (AF-CKF, AF-UKF).

    Computes the measurement moments once, ``lambda`` by :func:`innovation_fading_factor`, then
    the update of :func:`fading_update` with that ``lambda``.

    Args:
        state: predicted beliefs (unfaded).
        memory: :class:`FadingMemory`.
        z: measurements ``(B, m)``.
        model: observation model.
        mask: ``(B, m)`` booleans or None.
        rule: quadrature rule (default cubature).
        R: measurement noise override.
        rho: forgetting factor of eq. 63.
        eta: weight of ``V`` in eq. 63.
        eps: weight of ``R`` in eq. 63.

    Returns:
        ``(filtered state, UpdateInfo, updated memory, lambda (B,))``.

    """
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    R = np.broadcast_to(batched_matrix(model.R if R is None else R, B, (mdim, mdim), "R"), (B, mdim, mdim))
    mom = predict_measurement(state, z, model, rule)
    lam, memory = innovation_fading_factor(memory, mom.v, mom.C, R, mask, rho, eta, eps)
    post, info = condition_moments(state.m, lam[:, None, None] * state.P, mom.faded(lam), R, mask)
    return post, info, memory, lam


# --------------------------------------------------------------------------------------------
# Sage-Husa noise estimation
# --------------------------------------------------------------------------------------------


class SageHusaState(NamedTuple):
    """Running Sage-Husa estimates (Sage & Husa 1969).

    Attributes:
        R: measurement noise estimate ``(B, m, m)`` (pass as ``R=``).
        Q: process noise estimate ``(B, n, n)`` (pass as ``Q=``), or None when not estimated.
        k: steps absorbed, ``(B,)`` int (``d_k = (1 - b) / (1 - b^(k+1))``).
        floor: smallest eigenvalue allowed in ``R``, ``(B,)`` (``Q`` is kept positive
            semi-definite: its own scale, possibly with noise-free states, is unrelated to R's).

    """

    R: np.ndarray
    Q: np.ndarray | None
    k: np.ndarray
    floor: np.ndarray


def sage_husa_init(
    R0: np.ndarray,
    B: int,
    Q0: np.ndarray | None = None,
    k0: int = 0,
    floor: float | None = None,
) -> SageHusaState:
    """Build the initial Sage-Husa state.

    Args:
        R0: initial ``R`` guess, ``(m, m)`` or ``(B, m, m)``.
        B: batch size.
        Q0: initial ``Q`` guess ``(n, n)`` or ``(B, n, n)``; None estimates ``R`` only.
        k0: starting step count. ``d_k`` weighs the guesses like ``k0`` past samples; the
            classical recursion (``k0 = 0``) discards them at the first step (``d_0 = 1``).
        floor: smallest eigenvalue kept in the ``R`` estimate (positive-definiteness guard);
            default ``1e-6`` times the mean diagonal of ``R0``. The ``Q`` estimate is projected
            onto the positive semi-definite matrices instead (a floor sized from ``R`` would
            swamp a small ``Q`` and give noise to noise-free states).

    """
    if B < 1:
        raise ValueError(f"B must be >= 1; got {B}")
    R0 = _square_batched(R0, B, "R0")
    Q = None if Q0 is None else _square_batched(Q0, B, "Q0")
    if k0 < 0:
        raise ValueError(f"k0 must be >= 0; got {k0}")
    mean_var = np.trace(R0, axis1=1, axis2=2) / R0.shape[1]
    fl = 1e-6 * mean_var if floor is None else np.full(B, float(floor))
    if not (np.isfinite(fl).all() and (fl > 0).all()):
        raise ValueError("floor must be finite and > 0 (and R0 must have a positive diagonal)")
    return SageHusaState(R0, Q, np.full(B, k0, dtype=np.int64), fl)


def sage_husa_update(
    estimate: SageHusaState,
    predicted: GaussianState,
    filtered: GaussianState,
    info: UpdateInfo,
    b: np.ndarray | float = 0.98,
    mask: np.ndarray | None = None,
    estimate_R: bool = True,
) -> SageHusaState:
    """One Sage-Husa step with forgetting factor ``b`` (Sage & Husa 1969).

    With ``d_k = (1 - b) / (1 - b^(k+1))``, the innovation ``v = z - h(m-)`` and its predicted
    spread ``H P- H^T = S - R_hat`` (``S = info.S`` from the update that used ``R = R_hat``)::

        R_k = (1 - d_k) R_{k-1} + d_k (v v^T - H P- H^T)
        Q_k = (1 - d_k) Q_{k-1} + d_k (dx dx^T + P+ - (P- - Q_{k-1})),   dx = m+ - m- = K v

    (``P- - Q_{k-1}`` is the propagated spread ``F P F^T``: the predict must have used
    ``Q = Q_hat`` and no fading). The innovation-based ``R`` recursion can leave the positive
    definite cone; ``R`` is projected back by clipping its eigenvalues at ``estimate.floor``,
    ``Q`` by clipping them at 0 (positive semi-definite). Entries of ``R`` on masked rows or
    columns keep their previous value.

    Args:
        estimate: previous :class:`SageHusaState`.
        predicted: the predicted state of this step (that the update started from).
        filtered: the filtered state returned by the update.
        info: the :class:`UpdateInfo` of that update.
        b: forgetting factor, ``0 < b < 1`` (scalar or ``(B,)``).
        mask: the ``(B, m)`` mask of the update, or None.
        estimate_R: False keeps ``R`` fixed (estimate ``Q`` only).

    Returns:
        The updated :class:`SageHusaState`.

    """
    R_prev, Q_prev, k, floor = estimate
    B, mdim = R_prev.shape[:2]
    b = _in_open_interval(b, B, "b", 0.0, 1.0)
    v, mask = check_measurement(info.innovation, mask, B, mdim)
    d = (1.0 - b) / (1.0 - b ** (k + 1))
    D = d[:, None, None]
    HPH = info.S - R_prev
    sample = v[:, :, None] * v[:, None, :] - HPH
    R_new = (1.0 - D) * R_prev + D * sample
    both = mask[:, :, None] & mask[:, None, :]
    R_new = _eig_floor(np.where(both, R_new, R_prev), floor) if estimate_R else R_prev
    Q_new = None
    if Q_prev is not None:
        n = Q_prev.shape[1]
        check_gaussian(predicted, "predicted")
        check_gaussian(filtered, "filtered")
        if predicted.m.shape != (B, n) or filtered.m.shape != (B, n):
            raise ValueError(f"predicted and filtered must have n = {n} states and B = {B}")
        dx = filtered.m - predicted.m
        spread = predicted.P - Q_prev
        Q_new = _eig_floor(
            (1.0 - D) * Q_prev + D * (dx[:, :, None] * dx[:, None, :] + filtered.P - spread), np.zeros(B)
        )
    return SageHusaState(R_new, Q_new, k + 1, floor)


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------


def _eig_floor(A: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Symmetric ``A`` with eigenvalues clipped at ``floor (B,)`` (identity where already above)."""
    A = symmetrize(A)
    lam, U = np.linalg.eigh(A)
    low = lam < floor[:, None]
    if not low.any():
        return A
    lam = np.maximum(lam, floor[:, None])
    fixed = symmetrize((U * lam[:, None, :]) @ np.swapaxes(U, -1, -2))
    return np.where(low.any(axis=1)[:, None, None], fixed, A)


def _ratio_at_least_one(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = num / den
    ok = np.isfinite(ratio) & (den > 0)
    return np.where(ok, np.maximum(ratio, 1.0), 1.0)


def _check_memory(memory: FadingMemory) -> tuple[np.ndarray, np.ndarray]:
    V = np.asarray(memory.V, dtype=np.float64)
    k = np.asarray(memory.k)
    if V.ndim != 3 or V.shape[1] != V.shape[2]:
        raise ValueError(f"memory.V must have shape (B, m, m); got {V.shape}")
    if k.shape != (V.shape[0],):
        raise ValueError(f"memory.k must have shape ({V.shape[0]},); got {k.shape}")
    if not np.isfinite(V).all():
        raise ValueError("memory.V has non-finite entries")
    return V, k


def _in_open_interval(x: object, B: int, name: str, lo: float, hi: float) -> np.ndarray:
    x = batched_vector(x, B, name)
    if not (np.isfinite(x).all() and (x > lo).all() and (x < hi).all()):
        raise ValueError(f"{name} must lie in ({lo}, {hi}); got {x.min()}..{x.max()}")
    return x


def _positive(x: object, B: int, name: str) -> np.ndarray:
    x = batched_vector(x, B, name)
    if not (np.isfinite(x).all() and (x > 0).all()):
        raise ValueError(f"{name} must be finite and > 0")
    return x


def _square_batched(A: object, B: int, name: str) -> np.ndarray:
    A = np.asarray(A, dtype=np.float64)
    if A.ndim == 2:
        A = np.broadcast_to(A, (B, *A.shape))
    if A.ndim != 3 or A.shape[0] != B or A.shape[1] != A.shape[2]:
        raise ValueError(f"{name} must have shape (d, d) or ({B}, d, d); got {A.shape}")
    if not np.isfinite(A).all():
        raise ValueError(f"{name} has non-finite entries")
    return symmetrize(A.copy())
