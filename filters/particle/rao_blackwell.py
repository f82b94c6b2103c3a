"""Rao-Blackwellized (marginalized) particle filter: a Kalman filter per particle.

Model (Schön, Gustafsson & Nordlund, "Marginalized particle filters for mixed linear/nonlinear
state-space models", IEEE T-SP 53(7), 2005, eq. 18; the "random Dirac-Gauss" filter
(Dirac-Gauss DPF n.d., §2.1) is the same construction with an EKF per particle and a discrete mode:
:mod:`filters.particle.dirac_gauss`): the state splits into a nonlinear part
``x^n`` (sampled by particles) and a part ``x^l`` that is linear-Gaussian given ``x^n``::

    x^n_{k+1} = f_n(x^n_k) + A_n(x^n_k) x^l_k + w^n_k,    w^n ~ N(0, Q_n)
    x^l_{k+1} = f_l(x^n_k) + A_l(x^n_k) x^l_k + w^l_k,    w^l ~ N(0, Q_l)
    z_k       = h(x^n_k)   + C(x^n_k) x^l_k   + v_k,      v   ~ N(0, R)

with ``w^n``, ``w^l``, ``v`` independent (the cross covariance ``Q_ln`` of the paper is taken as
zero). The posterior is ``sum_i w_i delta(x^n - x^n_i) N(x^l; m_i, P_i)``.

Steps (Schön et al. 2005, Algorithm 1 with ``Q_ln = 0``):

* update: ``w_i <- w_i N(z; h_i + C_i m_i, C_i P_i C_i^T + R)`` (eq. 24a), then each particle's
  Kalman update ``K_i = P_i C_i^T S_i^-1``, ``m_i += K_i (z - h_i - C_i m_i)``, ``P_i`` in Joseph
  form (eq. 22);
* predict: sample ``x^n_{k+1} ~ N(f_n + A_n m_i, A_n P_i A_n^T + Q_n)`` (eq. 25b), then the
  Kalman time update that also conditions ``x^l`` on the sampled ``x^n_{k+1}`` through the
  pseudo-measurement ``zeta = x^n_{k+1} - f_n = A_n x^l + w^n`` (eq. 23):
  ``N_i = A_n P_i A_n^T + Q_n``, ``L_i = A_l P_i A_n^T N_i^-1``,
  ``m_i <- A_l m_i + f_l + L_i (zeta - A_n m_i)``,
  ``P_i <- (A_l - L_i A_n) P_i (A_l - L_i A_n)^T + Q_l + L_i Q_n L_i^T`` (Joseph form of eq. 23c).

Model interface (duck-typed, :class:`ConditionallyLinearModel`): functions of ``x^n``
broadcasting over ``(B, N, n_n)``; each matrix-valued function may return a constant matrix,
one per filter ``(B, r, c)`` or one per particle ``(B, N, r, c)``. :func:`split_linear_model`
turns a :class:`~filters.core.models.LinearGaussianModel` into this form (for tests and for
linear sub-blocks of larger models). Components of ``x^n`` with zero process noise and no
coupling to ``x^l`` (zero rows of ``A_n`` and ``Q_n``) carry no information and are skipped in
``N_i^-1``.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from filters.core.conditioning import masked_covariance
from filters.core.linalg import LOG_2PI, spd_inverse, symmetrize
from filters.core.models import LinearGaussianModel
from filters.core.resampling import RESAMPLERS, Rng, check_decision, check_rng, exp_weights, standard_normal
from filters.core.resampling import resample as resample_ancestors
from filters.core.types import GaussianState, ParticleState, UpdateInfo
from filters.core.validation import check_measurement
from filters.particle.bootstrap import gather, psd_sqrt
from filters.particle.estimates import check_particles, normalize_log_weights
from filters.particle.estimates import weights as _weights

__all__ = [
    "ConditionallyLinearModel",
    "LinearSplitModel",
    "RBParticleState",
    "from_gaussian",
    "mean_and_covariance",
    "predict",
    "resample",
    "split_linear_model",
    "update",
]


class RBParticleState(NamedTuple):
    """Batch of Rao-Blackwellized particle clouds.

    Attributes:
        xn: nonlinear-part particles ``(B, N, n_n)``.
        m: per-particle Kalman means of the linear part ``(B, N, n_l)``.
        P: per-particle Kalman covariances ``(B, N, n_l, n_l)``.
        log_w: normalized log-weights ``(B, N)``.

    """

    xn: np.ndarray
    m: np.ndarray
    P: np.ndarray
    log_w: np.ndarray


@runtime_checkable
class ConditionallyLinearModel(Protocol):
    """The conditionally linear-Gaussian model of the module docstring (Schön et al. eq. 18)."""

    Q_n: np.ndarray  # (n_n, n_n) or (B, n_n, n_n)
    Q_l: np.ndarray  # (n_l, n_l) or (B, n_l, n_l)
    R: np.ndarray  # (m, m) or (B, m, m)

    def f_n(self, xn: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray: ...

    def A_n(self, xn: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray: ...

    def f_l(self, xn: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray: ...

    def A_l(self, xn: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray: ...

    def h(self, xn: np.ndarray) -> np.ndarray: ...

    def C(self, xn: np.ndarray) -> np.ndarray: ...


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _lift(A: object, B: int, N: int, shape: tuple[int, int], name: str) -> np.ndarray:
    """Accept ``shape``, ``(B, *shape)`` or ``(B, N, *shape)``; return a broadcastable array."""
    A = np.asarray(A, dtype=np.float64)
    if A.shape == shape or A.shape == (B, N, *shape):
        return A
    if A.shape == (B, *shape):
        return A[:, None]
    raise ValueError(f"{name} must have shape {shape}, {(B, *shape)} or {(B, N, *shape)}; got {A.shape}")


def _T(A: np.ndarray) -> np.ndarray:
    return np.swapaxes(A, -1, -2)


def _mv(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A x`` for ``x (..., c)`` and ``A`` broadcastable to ``(..., r, c)``."""
    return (A @ x[..., None])[..., 0]


def _check_rb(state: RBParticleState) -> tuple[int, int, int, int]:
    xn, m, P = state.xn, state.m, state.P
    if not isinstance(xn, np.ndarray) or xn.ndim != 3:
        raise ValueError(f"state.xn must have shape (B, N, n_n); got {np.shape(xn)}")
    B, N, nn = xn.shape
    if not isinstance(m, np.ndarray) or m.ndim != 3 or m.shape[:2] != (B, N):
        raise ValueError(f"state.m must have shape (B, N, n_l) with (B, N) = {(B, N)}; got {np.shape(m)}")
    nl = m.shape[2]
    if np.shape(P) != (B, N, nl, nl):
        raise ValueError(f"state.P must have shape {(B, N, nl, nl)}; got {np.shape(P)}")
    check_particles(ParticleState(xn, state.log_w))
    return B, N, nn, nl


def _safe_inverse(Nm: np.ndarray) -> np.ndarray:
    """Inverse of PSD ``N`` whose exactly-zero diagonal entries mark uninformative rows."""
    zero = np.einsum("...ii->...i", Nm) <= 0.0
    if zero.any():
        Nm = Nm + zero[..., None] * np.eye(Nm.shape[-1])
    try:
        np.linalg.cholesky(Nm)
        return np.linalg.inv(Nm)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(symmetrize(Nm), hermitian=True)


# --------------------------------------------------------------------------------------------
# model helper
# --------------------------------------------------------------------------------------------
class LinearSplitModel(NamedTuple):
    """A linear-Gaussian model in conditionally linear form (see :func:`split_linear_model`).

    Attributes:
        F: transition matrix ``(n, n)`` or ``(B, n, n)``.
        H: observation matrix ``(m, n)`` or ``(B, m, n)``.
        Q_n: process noise of the nonlinear part.
        Q_l: process noise of the linear part.
        R: measurement noise.
        n_nonlinear: size ``n_n`` of the sampled part (the first ``n_n`` components).
        G: control matrix ``(n, p)`` or None.

    """

    F: np.ndarray
    H: np.ndarray
    Q_n: np.ndarray
    Q_l: np.ndarray
    R: np.ndarray
    n_nonlinear: int
    G: np.ndarray | None = None

    def _blk(self, A: np.ndarray, rows: slice, cols: slice) -> np.ndarray:
        blk = A[..., rows, cols]
        return blk if blk.ndim == 2 else blk[:, None]

    def _ctrl(self, u: np.ndarray | None, rows: slice) -> np.ndarray | float:
        if u is None or self.G is None:
            return 0.0
        return (np.asarray(u) @ self.G[rows].T)[:, None, :]

    def f_n(self, xn: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        k = self.n_nonlinear
        return _mv(self._blk(self.F, slice(0, k), slice(0, k)), xn) + self._ctrl(u, slice(0, k))

    def A_n(self, xn: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        k = self.n_nonlinear
        return self._blk(self.F, slice(0, k), slice(k, None))

    def f_l(self, xn: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        k = self.n_nonlinear
        return _mv(self._blk(self.F, slice(k, None), slice(0, k)), xn) + self._ctrl(u, slice(k, None))

    def A_l(self, xn: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        k = self.n_nonlinear
        return self._blk(self.F, slice(k, None), slice(k, None))

    def h(self, xn: np.ndarray) -> np.ndarray:
        return _mv(self._blk(self.H, slice(None), slice(0, self.n_nonlinear)), xn)

    def C(self, xn: np.ndarray) -> np.ndarray:
        return self._blk(self.H, slice(None), slice(self.n_nonlinear, None))


def split_linear_model(model: LinearGaussianModel, n_nonlinear: int) -> LinearSplitModel:
    """Partition a linear-Gaussian model: the first ``n_nonlinear`` states become ``x^n``.

    ``F = [[A_nn, A_n], [A_ln, A_l]]`` gives ``f_n = A_nn x^n``, ``f_l = A_ln x^n``; ``H = [H_n,
    C]`` gives ``h = H_n x^n``. ``Q`` must be block diagonal (``Q_ln = 0``).

    Raises:
        ValueError: naming ``n_nonlinear`` or ``Q`` (non-zero cross block).

    """
    F = np.asarray(model.transition_matrix, dtype=np.float64)
    n = F.shape[-1]
    if not isinstance(n_nonlinear, (int, np.integer)) or not 0 <= n_nonlinear <= n:
        raise ValueError(f"n_nonlinear must be an integer in [0, {n}]; got {n_nonlinear!r}")
    k = int(n_nonlinear)
    Q = np.asarray(model.Q, dtype=np.float64)
    if np.any(Q[..., :k, k:]) or np.any(Q[..., k:, :k]):
        raise ValueError("Q must be block diagonal between the nonlinear and linear parts (Q_ln = 0)")
    return LinearSplitModel(
        F,
        np.asarray(model.observation_matrix, dtype=np.float64),
        Q[..., :k, :k],
        Q[..., k:, k:],
        np.asarray(model.R, dtype=np.float64),
        k,
        None if model.control_matrix is None else np.asarray(model.control_matrix, dtype=np.float64),
    )


# --------------------------------------------------------------------------------------------
# steps
# --------------------------------------------------------------------------------------------
def from_gaussian(m: np.ndarray, P: np.ndarray, n_nonlinear: int, N: int, rng: Rng) -> RBParticleState:
    """Initial RBPF state from a joint Gaussian prior ``N(m, P)`` on ``x = [x^n; x^l]``.

    ``x^n_i ~ N(m_n, P_nn)``; each particle's linear part is the exact conditional
    ``m_i = m_l + P_ln P_nn^+ (x^n_i - m_n)``, ``P_i = P_ll - P_ln P_nn^+ P_nl`` (pseudo-inverse:
    a known ``x^n`` has ``P_nn = 0``).

    Args:
        m: prior means ``(B, n)``.
        P: prior covariances ``(B, n, n)``.
        n_nonlinear: ``n_n``, the first components of ``x``.
        N: particles per filter.
        rng: one Generator or a sequence of B.

    Returns:
        An :class:`RBParticleState` with uniform weights.

    """
    m = np.asarray(m, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64)
    if m.ndim != 2:
        raise ValueError(f"m must have shape (B, n); got {m.shape}")
    B, n = m.shape
    if P.shape != (B, n, n) or not np.isfinite(P).all():
        raise ValueError(f"P must be finite with shape {(B, n, n)}; got {P.shape}")
    if not isinstance(N, (int, np.integer)) or N < 1:
        raise ValueError(f"N must be an integer >= 1; got {N!r}")
    if not isinstance(n_nonlinear, (int, np.integer)) or not 0 <= n_nonlinear <= n:
        raise ValueError(f"n_nonlinear must be an integer in [0, {n}]; got {n_nonlinear!r}")
    k, N = int(n_nonlinear), int(N)
    Pnn, Pln, Pll = P[:, :k, :k], P[:, k:, :k], P[:, k:, k:]
    e = standard_normal(rng, B, (N, k))
    xn = _mv(psd_sqrt(Pnn)[:, None], e) + m[:, None, :k]
    gain = Pln @ np.linalg.pinv(Pnn, hermitian=True) if k else np.zeros((B, n - k, 0))
    ml = m[:, None, k:] + _mv(gain[:, None], xn - m[:, None, :k])
    Pl = symmetrize(Pll - gain @ _T(Pln))
    Pl = np.broadcast_to(Pl[:, None], (B, N, n - k, n - k)).copy()
    return RBParticleState(xn, ml, Pl, np.full((B, N), -np.log(N)))


def predict(
    state: RBParticleState,
    model: ConditionallyLinearModel,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    rng: Rng | None = None,
) -> RBParticleState:
    """RBPF time update (Schön et al. 2005 eq. 23 and 25b, ``Q_ln = 0``).

    Samples ``x^n_{k+1}`` from its marginal transition ``N(f_n + A_n m_i, A_n P_i A_n^T + Q_n)``
    and runs each particle's Kalman time update conditioned on it (module docstring).

    Args:
        state: filtered RBPF state.
        model: a :class:`ConditionallyLinearModel`.
        u: control input passed to the model functions.
        dt: time step [s].
        rng: one Generator or a sequence of B (required).

    Returns:
        The predicted :class:`RBParticleState` (weights unchanged).

    """
    B, N, nn, nl = _check_rb(state)
    if rng is None:
        raise ValueError("rng must be a numpy.random.Generator or a sequence of B of them")
    check_rng(rng, B)
    xn, m, P = state.xn, state.m, state.P
    fn = np.asarray(model.f_n(xn, u, dt), dtype=np.float64)
    if fn.shape != (B, N, nn):
        raise ValueError(f"model.f_n returned shape {fn.shape}; expected {(B, N, nn)}")
    An = _lift(model.A_n(xn, u, dt), B, N, (nn, nl), "A_n")
    fl = np.asarray(model.f_l(xn, u, dt), dtype=np.float64)
    if fl.shape != (B, N, nl):
        raise ValueError(f"model.f_l returned shape {fl.shape}; expected {(B, N, nl)}")
    Al = _lift(model.A_l(xn, u, dt), B, N, (nl, nl), "A_l")
    Qn = _lift(model.Q_n, B, N, (nn, nn), "Q_n")
    Ql = _lift(model.Q_l, B, N, (nl, nl), "Q_l")

    PAnT = P @ _T(An)  # (B, N, nl, nn)
    Nm = symmetrize(An @ PAnT + Qn)
    e = standard_normal(rng, B, (N, nn))
    innov = _mv(psd_sqrt(Nm), e)  # zeta - A_n m, the sampled deviation
    xn_new = fn + _mv(An, m) + innov
    Lg = (Al @ PAnT) @ _safe_inverse(Nm)  # (B, N, nl, nn)
    m_new = _mv(Al, m) + fl + _mv(Lg, innov)
    A = Al - Lg @ An
    P_new = symmetrize(A @ P @ _T(A) + Ql + Lg @ Qn @ _T(Lg))
    return RBParticleState(xn_new, m_new, P_new, state.log_w)


def update(
    state: RBParticleState,
    z: np.ndarray,
    model: ConditionallyLinearModel,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
    decision: np.ndarray | bool | None = None,
    rng: Rng | None = None,
    method: str = "systematic",
) -> tuple[RBParticleState, UpdateInfo]:
    """RBPF measurement update (Schön et al. 2005 eq. 22 and 24a).

    Weights by the per-particle marginal likelihood ``N(z; h_i + C_i m_i, S_i)``,
    ``S_i = C_i P_i C_i^T + R``; then each particle's Kalman update (Joseph form). Masked rows
    contribute exactly nothing. Optionally resamples where ``decision`` is True.

    Diagnostics: ``z_hat = sum_i w0_i (h_i + C_i m_i)``, ``S = sum_i w0_i (S_i + (zhat_i - z_hat)
    (zhat_i - z_hat)^T)`` (moment-matched mixture), NIS, ``log p(z | past) = logsumexp(log w0 +
    l_i)``, ESS after the correction.

    Args:
        state: predicted RBPF state.
        z: measurements ``(B, m)``; masked entries may be NaN.
        model: a :class:`ConditionallyLinearModel`.
        mask: ``(B, m)`` booleans; None uses every row.
        R: measurement noise override ``(m, m)`` or ``(B, m, m)``.
        decision: resample afterwards where True; None never resamples.
        rng: generator(s), required with ``decision``.
        method: resampling scheme name.

    Returns:
        ``(state, UpdateInfo)``.

    """
    B, N, nn, nl = _check_rb(state)
    z, mask = check_measurement(z, mask, B)
    mdim = z.shape[1]
    xn, m, P = state.xn, state.m, state.P
    Rm = _lift(model.R if R is None else R, B, N, (mdim, mdim), "R")
    C = _lift(model.C(xn), B, N, (mdim, nl), "C")
    hn = np.asarray(model.h(xn), dtype=np.float64)
    if hn.shape != (B, N, mdim):
        raise ValueError(f"model.h returned shape {hn.shape}; expected {(B, N, mdim)}")
    wm = mask.astype(np.float64)[:, None, :]  # (B, 1, m)
    Cm = C * wm[..., None]
    Rmm = masked_covariance(Rm, wm)
    zhat = hn + _mv(C, m)
    v = (z[:, None, :] - zhat) * wm
    PCt = P @ _T(Cm)
    S = masked_covariance(symmetrize(Cm @ PCt + Rm), wm)
    S_inv, logdet, ok = spd_inverse(S)
    n_meas = mask.sum(axis=1)
    quad = np.einsum("bni,bnij,bnj->bn", v, S_inv, v)
    ll = -0.5 * (quad + logdet + (n_meas * LOG_2PI)[:, None])
    ll = np.where(ok & np.isfinite(ll), ll, -np.inf)

    K = PCt @ S_inv
    m_new = m + _mv(K, v)
    A = np.eye(nl) - K @ Cm
    P_new = symmetrize(A @ P @ _T(A) + K @ Rmm @ _T(K))

    lw0, _ = normalize_log_weights(np.asarray(state.log_w, dtype=np.float64))
    w0 = exp_weights(lw0)
    zbar = np.einsum("bn,bnm->bm", w0, zhat)
    dz = (zhat - zbar[:, None, :]) * wm
    S_mix = np.einsum("bn,bnij->bij", w0, S) + np.einsum("bn,bni,bnj->bij", w0, dz, dz)
    v_mix = (z - zbar) * mask
    S_mix_inv, _, ok_mix = spd_inverse(symmetrize(S_mix))
    nis = np.einsum("bi,bij,bj->b", v_mix, S_mix_inv, v_mix)

    post, log_norm = normalize_log_weights(lw0 + ll)
    bad = ~np.isfinite(log_norm)
    if bad.any():
        post[bad] = lw0[bad]
    wp = exp_weights(post)
    ess_val = 1.0 / np.einsum("bn,bn->b", wp, wp)
    finite = (
        np.isfinite(m_new.reshape(B, -1).sum(axis=1))
        & np.isfinite(P_new.reshape(B, -1).sum(axis=1))
        & np.isfinite(xn.reshape(B, -1).sum(axis=1))
    )
    healthy = finite & ~bad & ok_mix
    info = UpdateInfo(v_mix, S_mix, nis, log_norm, healthy, n_meas, ess_val, np.zeros(B, dtype=bool))
    new = RBParticleState(xn, m_new, P_new, post)
    if decision is not None:
        if rng is None:
            raise ValueError("rng must be given when decision is")
        d = check_decision(decision, B)
        new = resample(new, d, rng, method)
        info = info._replace(resampled=d)
    return new, info


def resample(
    state: RBParticleState,
    decision: np.ndarray | bool | None,
    rng: Rng,
    method: str = "systematic",
) -> RBParticleState:
    """Resample particles with their Kalman moments where ``decision`` is True (weights -> 1/N)."""
    B, N, _, _ = _check_rb(state)
    if method not in RESAMPLERS:
        raise ValueError(f"method must be one of {sorted(RESAMPLERS)}; got {method!r}")
    d = check_decision(decision, B)
    if not d.any():
        return state
    anc = resample_ancestors(state.log_w, rng, method, d)
    log_w = np.where(d[:, None], -np.log(N), np.asarray(state.log_w, dtype=np.float64))
    return RBParticleState(gather(state.xn, anc), gather(state.m, anc), gather(state.P, anc), log_w)


def mean_and_covariance(state: RBParticleState) -> GaussianState:
    """Mean and covariance of ``x = [x^n; x^l]`` under the RBPF mixture posterior.

    ``E[x^n] = sum w_i x^n_i``, ``E[x^l] = sum w_i m_i``; ``Cov(x^l) = sum w_i (P_i + (m_i - E)(m_i
    - E)^T)``; ``Cov(x^n, x^l) = sum w_i (x^n_i - E)(m_i - E)^T``.

    Returns:
        A :class:`GaussianState` with ``m (B, n_n + n_l)`` and ``P (B, n, n)``.

    """
    B, N, nn, nl = _check_rb(state)
    w = _weights(np.asarray(state.log_w, dtype=np.float64))
    y = np.concatenate([state.xn, state.m], axis=2)
    mean = np.einsum("bn,bnk->bk", w, y)
    d = y - mean[:, None, :]
    P = np.einsum("bn,bni,bnj->bij", w, d, d)
    P[:, nn:, nn:] += np.einsum("bn,bnij->bij", w, state.P)
    return GaussianState(mean, symmetrize(P))
