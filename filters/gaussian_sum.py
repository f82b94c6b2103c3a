"""Gaussian-sum filters: mixture measurement noise and mixture states (Benzerrouk 2014, §2.5-2.6).

**Mixture measurement noise** (Benzerrouk 2014, eq. 71)::

    v ~ sum_j pi_j N(0, R_j),   e.g. (1 - eps) N(0, R_1) + eps N(0, R_2)

is handled by a bank of K parallel Gaussian updates of the same prior, one per noise
component (eq. 72: ``S_j = P_yy + R_j``), combined by their posterior weights and moment
matching (eq. 73-76)::

    gamma_j = N(e_j; 0, S_j),   alpha_j = pi_j gamma_j / sum_l pi_l gamma_l
    m_R = sum_j alpha_j m_j,    P_R = sum_j alpha_j (P_j + (m_j - m_R)(m_j - m_R)^T)

(:func:`update`). Any filter of :mod:`filters.registry` is the base (``"ekf"``, ``"ukf"``,
``"ckf"``, ``"ghkf"``, ``"dd2"``, ... giving GM-EKF, GM-UKF, GM-CKF, GM-GHKF, GM-DD2): the K
components are stacked into the batch axis, ``(B, K, ...) -> (B*K, ...)``, and the base update
is called **once**; there is no Python loop over K. A base filter with a noise-free
measurement prediction has a bank of its own (``GaussianFilter.update_bank``: sigma-point
and divided-difference filters from their ``moments``, the KF and EKF from ``h`` and ``H``)
evaluates it once per filter, as eq. 72 shares ``P_yy``, and only the K conditionings are
stacked (the same numbers). The prior weights ``pi (B, K)`` are an argument
of every step (the agent's knob).

**Mixture states** (:class:`~filters.core.types.MixtureState`): :func:`mixture_predict`
predicts every component (stacked the same way), :func:`mixture_update` conditions each of
the ``K_state`` components on each of the ``K_noise`` noise components
(``K_state * K_noise`` posterior components, weights ``w_i pi_j gamma_ij``), :func:`reduce`
keeps K bounded by Runnalls' greedy KL-based pairwise merging, and :func:`collapse` moment
matches a mixture into one Gaussian (eq. 75-76).

**Hybrid GM adaptive CKF** (Benzerrouk 2014, §2.6, "GM-ACKF"): :func:`adaptive_update` combines the
GM-CKF bank with the adaptive fading factor of eq. 63 applied on the update side (eq. 65-66).

Models whose parameters are batched over B (aligned with the first axis of ``x``) must follow
the stacking: :class:`~filters.core.models.LinearGaussianModel` and
:class:`~filters.core.models.LinearTransition` are tiled automatically; any
other model may provide ``repeat_batch(K)`` returning the model with each batched parameter
repeated K times along its first axis (``np.repeat(a, K, axis=0)``). Models with unbatched
parameters need nothing.
"""

from __future__ import annotations

from itertools import product
from typing import Any, NamedTuple

import numpy as np

from filters.adaptive import CUBATURE, FadingMemory, innovation_fading_factor
from filters.core.conditioning import condition_bank, health, masked_covariance
from filters.core.linalg import symmetrize
from filters.core.models import LinearGaussianModel, LinearTransition, ObservationModel, TransitionModel
from filters.core.quadrature import Quadrature
from filters.core.types import GaussianState, MixtureState
from filters.core.validation import (
    as_float_array,
    batched_matrix,
    check_gaussian,
    check_measurement,
    fading_factor,
)
from filters.registry import GaussianFilter
from filters.registry import get as get_filter
from filters.sigma_point import predict_measurement

__all__ = [
    "GaussianSumInfo",
    "adaptive_update",
    "channel_mixture",
    "check_mixture",
    "collapse",
    "mixture_log_weights",
    "mixture_predict",
    "mixture_update",
    "reduce",
    "to_mixture",
    "update",
    "update_checked",
]

#: Tolerance on ``|sum(weights) - 1|`` (and on ``logsumexp(log_weights)``).
WEIGHT_SUM_TOL = 1e-8


class GaussianSumInfo(NamedTuple):
    """Diagnostics of a Gaussian-sum update (the fields of ``UpdateInfo`` plus the weights).

    Attributes:
        innovation: ``z - z_hat`` of the mixture prediction, ``(B, m)`` (zero on masked rows).
        S: moment-matched predictive covariance of ``z`` (noise mixture included), ``(B, m, m)``.
        nis: prior-weighted mean of the components' NIS ``sum_c w_c v_c^T S_c^-1 v_c``, ``(B,)``.
        log_likelihood: exact log-likelihood of the Gaussian-sum predictive density
            ``log sum_c w_c N(z; z_hat_c, S_c)``, ``(B,)``.
        healthy: finite outputs, every component healthy, ``(B,)``.
        n_meas: unmasked rows, ``(B,)``.
        ess: None (particle filters only).
        resampled: None (particle filters only).
        log_weights: normalized posterior log-weights ``log alpha`` of the components (eq. 74),
            ``(B, K)`` (``K = K_state * K_noise`` for :func:`mixture_update`).
        component_log_likelihood: ``log gamma`` of each component (eq. 73), ``(B, K)``.

    """

    innovation: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    log_likelihood: np.ndarray
    healthy: np.ndarray
    n_meas: np.ndarray
    ess: np.ndarray | None
    resampled: np.ndarray | None
    log_weights: np.ndarray
    component_log_likelihood: np.ndarray


# --------------------------------------------------------------------------------------------
# Weights and noise components
# --------------------------------------------------------------------------------------------


def mixture_log_weights(
    weights: object | None,
    log_weights: object | None,
    B: int,
    K: int | None = None,
    name: str = "weights",
) -> np.ndarray:
    """Validate mixture weights given either linearly or as log-weights; return ``log w (B, K)``.

    ``weights`` must be finite, non-negative and sum to 1 along K (within ``WEIGHT_SUM_TOL``);
    ``log_weights`` must be finite or ``-inf`` with ``logsumexp = 0``. Shapes ``(K,)`` are
    broadcast to ``(B, K)``.
    """
    if (weights is None) == (log_weights is None):
        raise ValueError(f"give exactly one of {name} and log_{name}")
    arg = f"log_{name}" if weights is None else name
    w = as_float_array(weights if weights is not None else log_weights, arg)
    if w.ndim == 1:
        w = np.broadcast_to(w, (B, w.shape[0]))
    if w.ndim != 2 or w.shape[0] != B or (K is not None and w.shape[1] != K):
        want = f"({B}, {K if K is not None else 'K'})"
        raise ValueError(f"{arg} must have shape {want} or ({K if K is not None else 'K'},); got {w.shape}")
    if w.shape[1] < 1:
        raise ValueError(f"{arg} must have K >= 1 components; got {w.shape[1]}")
    if weights is not None:
        if not np.isfinite(w).all():
            raise ValueError(f"{arg} must be finite")
        if (w < 0).any():
            raise ValueError(f"{arg} must be non-negative")
        if not np.allclose(w.sum(axis=1), 1.0, rtol=0.0, atol=WEIGHT_SUM_TOL):
            raise ValueError(
                f"{arg} must sum to 1 along K; sums range {w.sum(axis=1).min()}..{w.sum(axis=1).max()}"
            )
        with np.errstate(divide="ignore"):
            return np.log(w)
    if np.isnan(w).any() or (w == np.inf).any():
        raise ValueError(f"{arg} must be finite or -inf (no NaN or +inf)")
    lse = _logsumexp(w)
    if not np.allclose(lse, 0.0, rtol=0.0, atol=WEIGHT_SUM_TOL):
        raise ValueError(f"{arg} must be normalized (logsumexp = 0 along K); got {lse.min()}..{lse.max()}")
    return w


def channel_mixture(var1: object, var2: object, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Product mixture for independent per-channel contamination (Benzerrouk 2014, eq. 71 per row).

    If each of the m rows independently has noise ``(1 - eps) N(0, var1_i) + eps N(0, var2_i)``,
    the joint noise is the ``2^m``-component mixture over contamination patterns: component
    ``c`` has ``R_c = diag(var1_i or var2_i)`` and weight ``prod (1 - eps or eps)``.

    Args:
        var1: nominal variances ``(m,)``.
        var2: contaminating variances ``(m,)``.
        eps: contamination probability in ``[0, 1]``.

    Returns:
        ``(R_components (2^m, m, m), weights (2^m,))``, nominal component first.

    """
    var1 = np.atleast_1d(as_float_array(var1, "var1"))
    var2 = np.atleast_1d(as_float_array(var2, "var2"))
    if var1.ndim != 1 or var2.shape != var1.shape:
        raise ValueError(f"var1 and var2 must have the same shape (m,); got {var1.shape}, {var2.shape}")
    if not (np.isfinite(var1).all() and np.isfinite(var2).all() and (var1 > 0).all() and (var2 > 0).all()):
        raise ValueError("var1 and var2 must be finite and > 0")
    if not 0.0 <= eps <= 1.0:
        raise ValueError(f"eps must lie in [0, 1]; got {eps}")
    mdim = var1.shape[0]
    if mdim > 12:
        raise ValueError(f"channel_mixture builds 2^m components; m = {mdim} is too many")
    pats = np.array(list(product((0, 1), repeat=mdim)), dtype=bool)  # (2^m, m)
    var = np.where(pats, var2, var1)
    R = var[:, :, None] * np.eye(mdim)
    w = np.prod(np.where(pats, eps, 1.0 - eps), axis=1)
    return R, w


# --------------------------------------------------------------------------------------------
# Single Gaussian prior, mixture noise (GM-EKF, GM-CKF, ... of Benzerrouk 2014, eq. 72-76)
# --------------------------------------------------------------------------------------------


def update(
    state: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    *,
    R_components: np.ndarray,
    weights: np.ndarray | None = None,
    log_weights: np.ndarray | None = None,
    base: GaussianFilter | str = "ckf",
) -> tuple[GaussianState, GaussianSumInfo]:
    """Gaussian-sum update of a Gaussian prior under mixture noise (Benzerrouk 2014, eq. 72-76).

    Each noise component j gives a base-filter update with ``R = R_j`` (eq. 72:
    ``S_j = P_yy + R_j``); ``gamma_j = N(e_j; 0, S_j)`` (eq. 73), ``alpha_j ∝ pi_j gamma_j``
    (eq. 74) and the posterior is moment matched (eq. 75-76). The K updates run as one base
    update on the stacked ``(B*K)`` batch. With K = 1 it equals the base update exactly.

    Args:
        state: predicted beliefs ``(B, n)``, ``(B, n, n)``.
        z: measurements ``(B, m)``.
        model: observation model of the base filter.
        mask: ``(B, m)`` booleans or None.
        R_components: noise covariances ``(K, m, m)`` or ``(B, K, m, m)``.
        weights: prior component weights ``pi``, ``(B, K)`` or ``(K,)``, summing to 1.
        log_weights: alternatively, normalized log-weights.
        base: base filter (registry name or :class:`~filters.registry.GaussianFilter`).

    Returns:
        ``(collapsed posterior GaussianState, GaussianSumInfo)``; ``info.log_weights`` holds
        ``log alpha_j``.

    """
    B, n = check_gaussian(state)
    post, info = _mixture_update(_wrap(state), z, model, mask, R_components, weights, log_weights, base)
    return _moment_match(post), info


def to_mixture(state: GaussianState) -> MixtureState:
    """Wrap a Gaussian as a one-component :class:`MixtureState`."""
    check_gaussian(state)
    return _wrap(state)


def _wrap(state: GaussianState) -> MixtureState:
    """:func:`to_mixture` of an already checked state."""
    B = state.m.shape[0]
    return MixtureState(state.m[:, None, :], state.P[:, None, :, :], np.zeros((B, 1)))


def collapse(state: MixtureState) -> GaussianState:
    """Moment-matched Gaussian of a mixture (Benzerrouk 2014, eq. 75-76).

    ``m = sum_k w_k m_k``, ``P = sum_k w_k (P_k + (m_k - m)(m_k - m)^T)``.
    """
    check_mixture(state)
    return _moment_match(state)


def _moment_match(state: MixtureState) -> GaussianState:
    """:func:`collapse` without validation, for mixtures this module has just computed.

    A posterior mixture is not re-checked: a non-finite component then gives a non-finite
    collapsed state, which the update's health flag reports, instead of a ``ValueError``.
    """
    K = state.m.shape[1]
    if K == 1:
        return GaussianState(state.m[:, 0], state.P[:, 0])
    w = np.exp(state.log_w)
    m = np.einsum("bk,bki->bi", w, state.m)
    dm = state.m - m[:, None, :]
    P = np.einsum("bk,bkij->bij", w, state.P) + np.swapaxes(dm * w[:, :, None], 1, 2) @ dm
    return GaussianState(m, symmetrize(P))


def check_mixture(state: MixtureState, name: str = "state") -> tuple[int, int, int]:
    """Validate a :class:`MixtureState`; return ``(B, K, n)``."""
    m, P, lw = np.asarray(state.m), np.asarray(state.P), np.asarray(state.log_w)
    if m.ndim != 3:
        raise ValueError(f"{name}.m must have shape (B, K, n); got {m.shape}")
    B, K, n = m.shape
    if K < 1:
        raise ValueError(f"{name} must have K >= 1 components; got K = {K}")
    if P.shape != (B, K, n, n):
        raise ValueError(f"{name}.P must have shape {(B, K, n, n)}; got {P.shape}")
    if lw.shape != (B, K):
        raise ValueError(f"{name}.log_w must have shape {(B, K)}; got {lw.shape}")
    if not (np.isfinite(m).all() and np.isfinite(P).all()):
        raise ValueError(f"{name}.m and {name}.P must be finite")
    if np.isnan(lw).any() or (lw == np.inf).any():
        raise ValueError(f"{name}.log_w must be finite or -inf")
    total = np.exp(lw).sum(axis=1)
    if not np.allclose(total, 1.0, rtol=0.0, atol=1e-8):
        worst = total[np.argmax(np.abs(total - 1.0))]
        raise ValueError(f"{name}.log_w must be normalized (weights summing to 1); a row sums to {worst:.6g}")
    return B, K, n


# --------------------------------------------------------------------------------------------
# Mixture states
# --------------------------------------------------------------------------------------------


def mixture_predict(
    state: MixtureState,
    model: TransitionModel,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    base: GaussianFilter | str = "ckf",
    fading: np.ndarray | float | None = None,
    Q: np.ndarray | None = None,
) -> MixtureState:
    """Predict every component with the base filter (one stacked ``(B*K)`` call); weights unchanged.

    Args:
        state: mixture ``(B, K, n)``.
        model: transition model.
        u: control ``(B, p)`` or None (shared by the components).
        dt: time step.
        base: base filter.
        fading: fading factor, scalar or ``(B,)`` (shared by a filter's components).
        Q: process noise override ``(n, n)`` or ``(B, n, n)``.

    Returns:
        The predicted :class:`MixtureState`.

    """
    flt = get_filter(base) if isinstance(base, str) else base
    B, K, n = check_mixture(state)
    Qm = batched_matrix(model.Q if Q is None else Q, B, (n, n), "Q")
    lam = fading_factor(fading, B)
    stacked = GaussianState(state.m.reshape(B * K, n), state.P.reshape(B * K, n, n))
    pred = flt.predict(
        stacked,
        tile_model(model, K, B),
        _repeat(u, K),
        dt,
        fading=None if lam is None else np.repeat(lam, K),
        Q=_repeat(Qm, K) if Qm.ndim == 3 else Qm,
    )
    return MixtureState(pred.m.reshape(B, K, n), pred.P.reshape(B, K, n, n), state.log_w)


def mixture_update(
    state: MixtureState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    *,
    R_components: np.ndarray,
    weights: np.ndarray | None = None,
    log_weights: np.ndarray | None = None,
    base: GaussianFilter | str = "ckf",
) -> tuple[MixtureState, GaussianSumInfo]:
    """Condition a K_s-component mixture on a K_n-component noise mixture (Benzerrouk 2014, eq. 72-74).

    Component ``(i, j)`` is the base update of state component i with ``R = R_j``; its weight
    is ``w_i pi_j gamma_ij`` normalized, ``gamma_ij = N(z; z_hat_i, S_ij)``. All
    ``K_s * K_n`` updates run as one base update on a ``(B * K_s * K_n)`` batch. Components are
    ordered state-major (index ``i * K_n + j``). Components whose likelihood is not finite get
    weight 0; a filter with no usable component keeps its prior weights and is flagged unhealthy.

    Args:
        state: prior mixture ``(B, K_s, n)``.
        z: measurements ``(B, m)``.
        model: observation model.
        mask: ``(B, m)`` booleans or None.
        R_components: noise covariances ``(K_n, m, m)`` or ``(B, K_n, m, m)``.
        weights: noise component weights ``pi (B, K_n)`` or ``(K_n,)``.
        log_weights: alternatively, their normalized logarithms.
        base: base filter.

    Returns:
        ``(posterior MixtureState with K_s * K_n components, GaussianSumInfo)``.

    """
    check_mixture(state)
    return _mixture_update(state, z, model, mask, R_components, weights, log_weights, base)


def _mixture_update(
    state: MixtureState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None,
    R_components: np.ndarray,
    weights: np.ndarray | None,
    log_weights: np.ndarray | None,
    base: GaussianFilter | str,
) -> tuple[MixtureState, GaussianSumInfo]:
    """:func:`mixture_update` of an already checked ``state``."""
    flt = get_filter(base) if isinstance(base, str) else base
    B = state.m.shape[0]
    z, mask = check_measurement(z, mask, B)
    Rc = _check_R_components(R_components, B, z.shape[1])
    log_pi = mixture_log_weights(weights, log_weights, B, Rc.shape[1])
    return _checked_mixture_update(state, z, model, mask, Rc, log_pi, flt)


def update_checked(
    state: GaussianState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray,
    R_components: np.ndarray,
    log_pi: np.ndarray,
    flt: GaussianFilter,
) -> tuple[GaussianState, GaussianSumInfo]:
    """:func:`update` of inputs its caller has checked: the same numbers, no validation.

    For loops that validate once and update many times (:func:`filters.row_mixture.update`,
    one update per measurement row): ``state`` a checked Gaussian, ``z (B, m)`` finite with
    ``mask (B, m)`` boolean, ``R_components (B, K, m, m)`` finite and symmetric, ``log_pi (B, K)``
    normalized log-weights, ``flt`` the base filter. The checks of :func:`update` cost about a
    third of a row's update at B = 16.
    """
    post, info = _checked_mixture_update(_wrap(state), z, model, mask, R_components, log_pi, flt)
    return _moment_match(post), info


def _checked_mixture_update(
    state: MixtureState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray,
    Rc: np.ndarray,
    log_pi: np.ndarray,
    flt: GaussianFilter,
) -> tuple[MixtureState, GaussianSumInfo]:
    """The body of :func:`_mixture_update` on checked inputs (``Rc (B, K_n, m, m)``, ``log_pi (B, K_n)``)."""
    B, Ks, n = state.m.shape
    mdim = z.shape[1]
    Kn = Rc.shape[1]
    K = Ks * Kn
    if Ks == 1 and flt.update_bank is not None:
        # One prior under K_n noise covariances, through the filter's own bank: its measurement
        # prediction (eq. 72's P_yy; h, H for the EKF, which also shares its observed-subspace
        # factorization) once per filter, only the K_n conditionings stacked (the same numbers
        # as K_n separate base updates)
        post, cinfo = flt.update_bank(GaussianState(state.m[:, 0], state.P[:, 0]), z, model, mask, Rc)
    else:
        R_st = np.broadcast_to(Rc[:, None], (B, Ks, Kn, mdim, mdim)).reshape(B * K, mdim, mdim)
        m_st, P_st = _stacked(state, Kn)
        post, cinfo = flt.update(
            GaussianState(m_st, P_st),
            _repeat(z, K),
            tile_model(model, K, B),
            mask=_repeat(mask, K),
            R=R_st,
        )
    log_prior = (state.log_w[:, :, None] + log_pi[:, None, :]).reshape(B, K)
    log_alpha, total, ll, comp_ok = _posterior_weights(
        log_prior, cinfo.log_likelihood.reshape(B, K), cinfo.healthy.reshape(B, K)
    )
    new = MixtureState(post.m.reshape(B, K, n), post.P.reshape(B, K, n, n), log_alpha)

    # Mixture-level predictive moments of z (prior weights) for the diagnostics.
    wp = np.exp(log_prior)
    v_c = cinfo.innovation.reshape(B, K, mdim)
    v = np.einsum("bk,bki->bi", wp, v_c) if Ks > 1 else v_c[:, 0]
    S = np.einsum("bk,bkij->bij", wp, cinfo.S.reshape(B, K, mdim, mdim))
    if Ks > 1:  # the state components predict different z: add the spread of their innovations
        dv = v_c - v[:, None, :]
        S = S + ((wp[:, :, None] * dv)[:, :, :, None] * dv[:, :, None, :]).sum(axis=1)
    finite_all = np.isfinite(new.m).all(axis=(1, 2)) & np.isfinite(new.P).all(axis=(1, 2, 3))
    info = GaussianSumInfo(
        innovation=v,
        S=S,
        nis=(wp * cinfo.nis.reshape(B, K)).sum(axis=1),
        log_likelihood=total,
        healthy=np.isfinite(total) & finite_all & comp_ok.all(axis=1),
        n_meas=mask.sum(axis=1),
        ess=None,
        resampled=None,
        log_weights=log_alpha,
        component_log_likelihood=ll,
    )
    return new, info


def reduce(state: MixtureState, max_components: int) -> MixtureState:
    """Runnalls' greedy KL-based mixture reduction to at most ``max_components`` components.

    Repeatedly merges, in every filter of the batch at once, the pair ``(i, j)`` with the
    smallest upper bound on the KL discrimination of the merge (Runnalls 2007,
    *IEEE T-AES* 43(3), eq. 21)::

        B(i, j) = 1/2 [(w_i + w_j) log det P_ij - w_i log det P_i - w_j log det P_j]

    where ``(w_ij, m_ij, P_ij)`` is the moment-preserving merge
    ``w_ij = w_i + w_j``, ``m_ij = (w_i m_i + w_j m_j) / w_ij``,
    ``P_ij = (w_i P_i + w_j P_j) / w_ij + w_i w_j / w_ij^2 (m_i - m_j)(m_i - m_j)^T``.
    Each merge preserves the mixture's mean and covariance exactly. The loop runs over merge
    iterations (``K - max_components`` of them), never over the batch.

    Args:
        state: mixture ``(B, K, n)``.
        max_components: K_max >= 1.

    Returns:
        A mixture with ``min(K, max_components)`` components.

    """
    B, K, n = check_mixture(state)
    if int(max_components) != max_components or max_components < 1:
        raise ValueError(f"max_components must be an integer >= 1; got {max_components}")
    m, P, lw = state.m, state.P, state.log_w
    ar = np.arange(B)
    while m.shape[1] > max_components:
        k = m.shape[1]
        w = np.exp(lw)
        iu, ju = np.triu_indices(k, 1)
        wi, wj = w[:, iu], w[:, ju]
        wij = wi + wj
        safe = np.where(wij > 0, wij, 1.0)
        ai = np.where(wij > 0, wi / safe, 0.5)
        aj = 1.0 - ai
        dm = m[:, iu] - m[:, ju]
        mij = ai[..., None] * m[:, iu] + aj[..., None] * m[:, ju]
        Pij = (
            ai[..., None, None] * P[:, iu]
            + aj[..., None, None] * P[:, ju]
            + (ai * aj)[..., None, None] * dm[..., :, None] * dm[..., None, :]
        )
        _, ld = np.linalg.slogdet(P)
        _, ldij = np.linalg.slogdet(Pij)
        cost = 0.5 * (wij * ldij - wi * ld[:, iu] - wj * ld[:, ju])
        cost = np.where(np.isfinite(cost), cost, np.inf)
        best = np.argmin(cost, axis=1)
        bi, bj = iu[best], ju[best]
        m = m.copy()
        P = P.copy()
        lw = lw.copy()
        m[ar, bi] = mij[ar, best]
        P[ar, bi] = symmetrize(Pij[ar, best])
        with np.errstate(divide="ignore"):
            lw[ar, bi] = np.logaddexp(lw[ar, bi], lw[ar, bj])
        keep = np.arange(k - 1)[None, :]
        idx = keep + (keep >= bj[:, None])
        m = np.take_along_axis(m, idx[:, :, None], axis=1)
        P = np.take_along_axis(P, idx[:, :, None, None], axis=1)
        lw = np.take_along_axis(lw, idx, axis=1)
    return MixtureState(m, P, lw - _logsumexp(lw)[:, None])


# --------------------------------------------------------------------------------------------
# Hybrid Gaussian-mixture adaptive CKF (Benzerrouk 2014, §2.6)
# --------------------------------------------------------------------------------------------


def adaptive_update(
    state: GaussianState,
    memory: FadingMemory,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    *,
    R_components: np.ndarray,
    weights: np.ndarray | None = None,
    log_weights: np.ndarray | None = None,
    rule: Quadrature = CUBATURE,
    rho: np.ndarray | float = 0.95,
    eta: np.ndarray | float = 1.0,
    eps: np.ndarray | float = 1.0,
    fading: np.ndarray | float | None = None,
) -> tuple[GaussianState, GaussianSumInfo, FadingMemory, np.ndarray]:
    """Gaussian-mixture adaptive sigma-point update, GM-ACKF (Benzerrouk 2014, §2.6, eq. 63-66 + 72-76).

    Our reading of the hybrid ("both methods ... combined", §2.5-2.6): the measurement moments
    ``z_hat``, ``P_yy``, ``P_xy`` of the sigma points of the (unfaded) prior are computed once;
    the fading factor is eq. 63 with the mixture's noise covariance ``R = sum_j pi_j R_j``::

        lambda = max(1, tr[eta V_k - eps R] / tr[P_yy])

    (or the ``fading`` argument, when an agent sets it); then each noise component j is the
    update-side fading update of eq. 65-66 with ``S_j = lambda P_yy + R_j``,
    ``P_xy = lambda P_xy``, prior ``lambda P-`` (see :func:`filters.adaptive.fading_update`),
    weighted and moment matched as in eq. 73-76. With ``lambda = 1`` this is the GM update
    :func:`update` with the same sigma-point rule.

    Behaviour worth knowing: ``V_k`` of eq. 70 gives the newest ``v v^T`` a weight
    ``1 / (1 + rho) > 1/2``, so a single impulsive outlier also raises ``lambda`` for that step,
    and the inflated prior then absorbs part of the outlier. On the range-tracking test
    (``tests/filters/test_gaussian_sum.py``) GM-CKF loses a velocity jump that GM-ACKF keeps,
    while GM-ACKF is less accurate than GM-CKF in nominal stretches -- the classical
    baseline that an agent setting ``fading`` per step is meant to beat.

    Args:
        state: predicted beliefs (unfaded).
        memory: :class:`~filters.adaptive.FadingMemory` for the innovation covariance ``V``.
        z: measurements ``(B, m)``.
        model: observation model (``h`` broadcasting over ``(B, S, n)``).
        mask: ``(B, m)`` booleans or None.
        R_components: noise covariances ``(K, m, m)`` or ``(B, K, m, m)``.
        weights: prior noise component weights ``(B, K)`` or ``(K,)``.
        log_weights: alternatively, their normalized logarithms.
        rule: quadrature rule (default cubature).
        rho: forgetting factor of eq. 63.
        eta: weight of ``V`` in eq. 63.
        eps: weight of ``R`` in eq. 63.
        fading: if given, this ``lambda (B,)`` is used instead of eq. 63 (the memory is still
            updated).

    Returns:
        ``(collapsed posterior, GaussianSumInfo, updated memory, lambda (B,))``.

    """
    B, n = check_gaussian(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    Rc = _check_R_components(R_components, B, mdim)
    K = Rc.shape[1]
    log_pi = mixture_log_weights(weights, log_weights, B, K)
    mom = predict_measurement(state, z, model, rule)
    R_mix = np.einsum("bk,bkij->bij", np.exp(log_pi), Rc)
    lam, memory = innovation_fading_factor(memory, mom.v, mom.C, R_mix, mask, rho, eta, eps)
    if fading is not None:
        lam = fading_factor(fading, B)
    faded = mom.faded(lam)
    # one faded prior under the K noise components
    post, cinfo = condition_bank(state.m, lam[:, None, None] * state.P, faded, Rc, mask)
    log_alpha, total, ll, comp_ok = _posterior_weights(
        log_pi, cinfo.log_likelihood.reshape(B, K), cinfo.healthy.reshape(B, K)
    )
    mix = MixtureState(post.m.reshape(B, K, n), post.P.reshape(B, K, n, n), log_alpha)
    out = _moment_match(mix)
    info = GaussianSumInfo(
        innovation=cinfo.innovation.reshape(B, K, mdim)[:, 0],
        S=masked_covariance(faded.C + R_mix, mask.astype(np.float64)),  # identity on masked rows
        nis=(np.exp(log_pi) * cinfo.nis.reshape(B, K)).sum(axis=1),
        log_likelihood=total,
        healthy=np.isfinite(total) & comp_ok.all(axis=1) & health(out.m, out.P),
        n_meas=mask.sum(axis=1),
        ess=None,
        resampled=None,
        log_weights=log_alpha,
        component_log_likelihood=ll,
    )
    return out, info, memory, lam


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------


def _logsumexp(a: np.ndarray) -> np.ndarray:
    """``log sum_k exp(a_k)`` over the last axis of ``(B, K)``; ``-inf`` where every entry is."""
    mx = a.max(axis=1)
    safe = np.where(np.isfinite(mx), mx, 0.0)
    with np.errstate(divide="ignore"):
        return safe + np.log(np.exp(a - safe[:, None]).sum(axis=1))


def _posterior_weights(
    log_prior: np.ndarray, ll: np.ndarray, ok: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Normalized ``log alpha ∝ log prior + log gamma`` (Benzerrouk 2014, eq. 74), all ``(B, K)``.

    Components that are unhealthy or have a non-finite likelihood get ``gamma = 0``; a filter with
    no usable component keeps its prior weights (and ``total = -inf`` flags it).

    Returns:
        ``(log_alpha, total = log sum prior * gamma (B,), ll with -inf where unusable, ok)``.

    """
    ok = ok & np.isfinite(ll)
    ll = np.where(ok, ll, -np.inf)
    joint = log_prior + ll
    total = _logsumexp(joint)
    usable = np.isfinite(total)
    log_alpha = np.where(usable[:, None], joint - np.where(usable, total, 0.0)[:, None], log_prior)
    return log_alpha, total, ll, ok


def tile_model(model: Any, K: int, B: int) -> Any:
    """Return the model seen by a ``(B*K)`` stacked batch (see the module docstring)."""
    if K == 1:
        return model
    # an attribute lookup, not isinstance against a runtime-checkable Protocol (far slower in a hot
    # path; docs/performance.md, "Figures behind the code")
    repeat_batch = getattr(model, "repeat_batch", None)
    if callable(repeat_batch):
        return repeat_batch(K)
    if isinstance(model, (LinearGaussianModel, LinearTransition)):
        return model._replace(
            **{
                f: np.repeat(a, K, axis=0)
                for f, a in model._asdict().items()
                if a is not None and np.ndim(a) == 3 and np.shape(a)[0] == B
            }
        )
    return model


def _stacked(state: MixtureState, Kn: int) -> tuple[np.ndarray, np.ndarray]:
    """Each state component repeated for the ``Kn`` noise components, as a ``(B*K)`` batch."""
    B, Ks, n = state.m.shape
    K = Ks * Kn
    return (
        np.repeat(state.m, Kn, axis=1).reshape(B * K, n),
        np.repeat(state.P, Kn, axis=1).reshape(B * K, n, n),
    )


def _repeat(a: np.ndarray | None, K: int) -> np.ndarray | None:
    if a is None or K == 1:
        return a
    return np.repeat(np.asarray(a), K, axis=0)


def _check_R_components(R_components: object, B: int, mdim: int) -> np.ndarray:
    """``(K, m, m)`` or ``(B, K, m, m)`` -> ``(B, K, m, m)``; K >= 1, finite, symmetric."""
    given = as_float_array(R_components, "R_components")
    Rc = np.broadcast_to(given, (B, *given.shape)) if given.ndim == 3 else given
    if Rc.ndim != 4 or Rc.shape[0] != B or Rc.shape[2:] != (mdim, mdim):
        raise ValueError(
            f"R_components must have shape (K, {mdim}, {mdim}) or ({B}, K, {mdim}, {mdim}); got {Rc.shape}"
        )
    if Rc.shape[1] < 1:
        raise ValueError("R_components must hold K >= 1 components; got K = 0")
    # on the components as given (before broadcasting): shared components are checked once
    if not np.isfinite(given).all():
        raise ValueError("R_components has non-finite entries")
    if not np.allclose(given, np.swapaxes(given, -1, -2), rtol=1e-12, atol=0.0):
        raise ValueError("R_components must be symmetric")
    return Rc
