"""Bootstrap (SIR) particle filter, batched over B filters and N particles, log-weights.

The bootstrap filter of Gordon, Salmond & Smith (1993) as written in Touil & Ghadi 2012, §3.2 and
Carvalho et al. 1997, §III-A ("a priori exploration"):

* prediction (Touil & Ghadi 2012, eq. 15): ``x_k^i = f(x_{k-1}^i, u, dt) + w_k^i``, ``w_k^i ~ p_w``;
* update (Touil & Ghadi 2012, eq. 16; Carvalho et al. 1997, eq. 6):
  ``log w_k^i = log w_{k-1}^i + log p(z_k | x_k^i) - log sum_j w_{k-1}^j p(z_k | x_k^j)``;
* resampling (Touil & Ghadi 2012, eq. 17; Carvalho et al. 1997, §III-D "redistribution") as a
  per-filter decision ``(B,)`` supplied by the caller, so a rule (:mod:`filters.particle.triggers`)
  or an agent decides when.

Model interface (duck-typed, see :mod:`filters.core.models`): ``f(x, u, dt)`` and ``h(x)``
broadcast over ``x (B, N, n)``; ``Q`` (``(n, n)`` or ``(B, n, n)``, may be singular) and ``R``
(``(m, m)`` or ``(B, m, m)``). Optional hooks:

* ``sample_noise(generator, shape) -> (*shape, n)`` replaces the Gaussian ``N(0, Q)`` process
  noise (non-Gaussian or low-rank noise); ``shape`` is ``(k, N)`` for ``k`` filters;
* ``log_likelihood(z, x, mask) -> (B, N)`` replaces the Gaussian measurement likelihood
  ``N(z; h(x), R)`` (e.g. Gaussian-mixture noise, Benzerrouk 2014, eq. 71); it must ignore masked rows.

Randomness: ``rng`` is one ``np.random.Generator`` or a sequence of B (one per filter); see
:mod:`filters.core.resampling` for the batching and determinism semantics.

Memory layout: ``x`` may be any ``(B, N, n)`` array, including the transposed view of a
``(B, n, N)`` buffer ("structure of arrays"). The steps keep the layout they are given
(element-wise NumPy operations use ``order="K"``; :func:`gather` resamples along the contiguous
axis), so a model whose ``f``, ``sample_noise`` and ``h`` return that layout gets every
element-wise pass running along the N particles instead of along the short state or
measurement axis (``navgym bench particles`` measures both); ``from_gaussian(...,
layout="soa")`` creates such a cloud. Normals are drawn component-major
(:func:`component_major_normals`), so both layouts receive the same numbers.

Precision: a float32 cloud stays float32 through predict, update and resampling (its noise,
likelihood products and moments are computed in float32); log-weights, ``S``, NIS and the
log-likelihood stay float64. Use it where the state is metres-sized (error states, local
frames) and the measurement model returns residual-sized numbers ("observed minus computed",
e.g. :class:`navgym.gps_ins.models.ReducedPseudorangeModel`).
"""

from __future__ import annotations

from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from filters.core.compiled import compiled_enabled
from filters.core.conditioning import diagonal_noise, masked_covariance
from filters.core.layout import cloud_dtype, is_component_major, weights_in
from filters.core.linalg import LOG_2PI, cholesky, spd_inverse, symmetrize
from filters.core.models import ObservationModel, TransitionModel
from filters.core.resampling import (
    EXP_FLUSH,
    RESAMPLERS,
    Rng,
    check_decision,
    check_rng,
    draw,
    exp_weights,
    normalized_weights,
    standard_normal,
    uniform,
)
from filters.core.resampling import resample as resample_ancestors
from filters.core.threads import over_rows
from filters.core.types import ParticleState, UpdateInfo
from filters.core.validation import batched_matrix, batched_vector, check_measurement
from filters.particle import kernels
from filters.particle.estimates import check_particles, log_and_linear_weights


@runtime_checkable
class NoiseSampler(Protocol):
    """A transition model that draws its own process noise (e.g. heavy-tailed), not ``N(0, Q)``."""

    def sample_noise(self, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        """Noise ``(*shape, n)`` from generator ``rng`` (``shape = (k, N)``: k filters, N particles)."""
        ...


@runtime_checkable
class LikelihoodModel(Protocol):
    """An observation model with its own log-likelihood instead of the Gaussian ``N(z; h(x), R)``."""

    def log_likelihood(self, z: np.ndarray, x: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """``log p(z | x_i)`` ``(B, N)`` of measurements ``z (B, m)`` over the unmasked rows."""
        ...


@runtime_checkable
class NoisyModel(Protocol):
    """An observation model with a Gaussian noise covariance ``R`` (a likelihood model may lack one)."""

    R: np.ndarray | None


__all__ = [
    "LikelihoodModel",
    "NoiseSampler",
    "NoisyModel",
    "component_major_normals",
    "from_gaussian",
    "gather",
    "is_component_major",
    "particle_log_likelihood",
    "predict",
    "process_noise",
    "psd_sqrt",
    "resample",
    "update",
    "update_weighted",
    "weigh",
    "WeightedUpdate",
]


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def psd_sqrt(Q: np.ndarray, name: str | None = None) -> np.ndarray:
    """A square root ``L`` with ``L L^T = Q`` of symmetric PSD matrices ``(..., n, n)``.

    Cholesky when it succeeds; otherwise (singular ``Q``, e.g. noise-free components) the
    symmetric root ``V sqrt(max(lambda, 0)) V^T`` from ``eigh``, which is exact for PSD input.
    With ``name`` (a user-supplied covariance), a matrix with an eigenvalue below ``-1e-9``
    times its largest is not PSD beyond rounding and raises ``ValueError`` naming it.
    """
    try:
        return np.linalg.cholesky(Q)
    except np.linalg.LinAlgError:
        lam, V = np.linalg.eigh(symmetrize(Q))
        if name is not None and (lam[..., 0] < -1e-9 * np.abs(lam).max(axis=-1)).any():
            raise ValueError(
                f"{name} must be positive semi-definite; an eigenvalue is {lam[..., 0].min():.3g}"
            ) from None
        return (V * np.sqrt(np.maximum(lam, 0.0))[..., None, :]) @ np.swapaxes(V, -1, -2)


def gather(a: np.ndarray, ancestors: np.ndarray) -> np.ndarray:
    """``out[b, j] = a[b, ancestors[b, j]]`` for ``a (B, N, ...)``, one flat ``np.take``.

    Keeps the memory layout: a C-ordered ``(B, N, n)`` array is gathered row-wise; a
    "structure of arrays" view (``a.transpose(0, 2, 1)`` C-contiguous, i.e. a ``(B, n, N)``
    buffer) is gathered along its contiguous particle axis and returned in the same layout.
    """
    B, N = ancestors.shape
    Na = a.shape[1]
    if is_component_major(a):
        n = a.shape[2]
        aT = a.transpose(0, 2, 1)
        idx = ancestors[:, None, :] + (np.arange(B * n) * Na).reshape(B, n, 1)
        return np.take(aT.reshape(-1), idx).transpose(0, 2, 1)
    flat = ancestors + (np.arange(B) * Na)[:, None]
    out = np.take(np.ascontiguousarray(a).reshape(B * Na, *a.shape[2:]), flat.ravel(), axis=0)
    return out.reshape(B, N, *a.shape[2:])


def process_noise(
    model: TransitionModel,
    B: int,
    N: int,
    n: int,
    rng: Rng,
    Q: np.ndarray | None = None,
    dtype: type | np.dtype = np.float64,
) -> np.ndarray:
    """Process-noise samples ``w (B, N, n)`` for Touil & Ghadi 2012, eq. 15.

    ``model.sample_noise(generator, (k, N))`` when the model has it and no ``Q`` override is
    given; otherwise ``w = L e`` with ``e ~ N(0, I)`` and ``L L^T = Q`` (:func:`psd_sqrt`).
    A diagonal ``Q`` scales ``e`` by its standard deviations; when it is shared by the batch
    (``(n, n)``) and has zero-variance components (error states driven by a few noise
    sources, e.g. Carvalho et al. 1997, eq. 13 where only the biases and the clock drift are driven),
    normals are drawn for the driven components only: the same distribution, fewer draws.

    The normals are drawn component-major (:func:`component_major_normals`), so ``w`` is the
    ``(B, N, n)`` view of a ``(B, n, N)`` buffer whatever the particles' layout; ``dtype`` is
    the particles' precision (float32 clouds get float32 noise).
    """
    support, e = _noise_draw(model, B, N, n, rng, Q, dtype)
    if support is None:
        return e
    wT = np.zeros((B, n, N), dtype=dtype)
    wT[:, support] = e
    return wT.transpose(0, 2, 1)


def _noise_draw(
    model: TransitionModel, B: int, N: int, n: int, rng: Rng, Q: np.ndarray | None, dtype: type | np.dtype
) -> tuple[np.ndarray | None, np.ndarray]:
    """The draws of :func:`process_noise`: ``(None, w (B, N, n))``, or ``(support, e)``.

    ``(support, e)`` for a shared diagonal ``Q`` with noise-free components: the noise of the
    driven components ``support (k,)`` only, component-major ``e (B, k, N)``; the others are
    exactly zero, so :func:`predict` adds ``e`` to those components alone.
    """
    if isinstance(model, NoiseSampler) and Q is None:
        sampler = model.sample_noise
        w = draw(rng, B, lambda g, k: sampler(g, (k, N)))
        if w.shape != (B, N, n):
            raise ValueError(f"model.sample_noise returned shape {w.shape}; expected {(B, N, n)}")
        return None, w
    Qm = batched_matrix(model.Q if Q is None else Q, B, (n, n), "Q")
    q = diagonal_noise(Qm)
    if q is not None:
        if (q < 0).any():
            raise ValueError(f"Q must be positive semi-definite; a variance is {q.min():.3g}")
        sd = np.sqrt(q)
        if sd.ndim == 1 and not sd.all():
            support = np.flatnonzero(sd)
            e = component_major_normals(rng, B, N, support.size, dtype=dtype).transpose(0, 2, 1)
            _scale_rows(e, sd[support].astype(dtype)[:, None])
            return support, e
        e = component_major_normals(rng, B, N, n, dtype=dtype).transpose(0, 2, 1)
        _scale_rows(e, (sd[:, None] if sd.ndim == 1 else sd[:, :, None]).astype(dtype))
        return None, e.transpose(0, 2, 1)
    e = component_major_normals(rng, B, N, n, dtype=dtype).transpose(0, 2, 1)
    L = psd_sqrt(Qm, "Q").astype(dtype)
    return None, (L @ e).transpose(0, 2, 1)


def _scale_rows(e: np.ndarray, s: np.ndarray) -> None:
    """``e *= s`` for ``e (B, k, N)`` and a scale ``(k, 1)`` or ``(B, k, 1)``, rows split over threads."""
    per_row = s.ndim == 3

    def rows(a: int, b: int) -> None:  # element-wise: the same values on any split
        ea = e[a:b]
        np.multiply(ea, s[a:b] if per_row else s, out=ea)

    over_rows(e.shape[0], e.shape[1] * e.shape[2], rows)


def component_major_normals(
    rng: Rng, B: int, N: int, n: int, rows: np.ndarray | None = None, dtype: type | np.dtype = np.float64
) -> np.ndarray:
    """Standard normals for ``N`` particles of ``n`` components, ``(len(rows), N, n)``.

    Drawn as ``(n, N)`` blocks per filter (:func:`filters.core.resampling.standard_normal`) and
    returned as their transposed view, so the values given to particle ``i``, component ``j``
    do not depend on the particles' memory layout, and a "structure of arrays" cloud adds
    them with contiguous passes (``.transpose(0, 2, 1)`` gives the ``(len(rows), n, N)``
    block back without a copy). ``dtype``: float64 or float32.
    """
    return standard_normal(rng, B, (n, N), rows, dtype).transpose(0, 2, 1)


def from_gaussian(m: np.ndarray, P: np.ndarray, N: int, rng: Rng, layout: str = "aos") -> ParticleState:
    """Initial particles ``x_0^i ~ N(m, P)`` with weights ``1/N`` (Carvalho et al. 1997, §III-A step a).

    Args:
        m: means ``(B, n)``.
        P: covariances ``(B, n, n)`` or ``(n, n)`` (PSD; singular allowed).
        N: particles per filter (>= 1).
        rng: one Generator or a sequence of B.
        layout: ``"aos"`` for a C-ordered ``(B, N, n)`` array, ``"soa"`` for the ``(B, N, n)``
            view of a ``(B, n, N)`` buffer ("structure of arrays": element-wise passes run along
            the particles; the module docstring). The values are the same for both.

    Returns:
        A :class:`ParticleState` with ``x (B, N, n)`` and ``log_w = -log N``.
    """
    m = np.asarray(m, dtype=np.float64)
    if m.ndim != 2:
        raise ValueError(f"m must have shape (B, n); got {m.shape}")
    B, n = m.shape
    if not isinstance(N, (int, np.integer)) or N < 1:
        raise ValueError(f"N must be an integer >= 1; got {N!r}")
    if layout not in ("aos", "soa"):
        raise ValueError(f"layout must be 'aos' or 'soa'; got {layout!r}")
    P = batched_matrix(P, B, (n, n), "P")
    L = psd_sqrt(P, "P")
    xT = L @ component_major_normals(rng, B, int(N), n).transpose(0, 2, 1)  # (B, n, N)
    xT += m[:, :, None]
    x = xT.transpose(0, 2, 1)
    return ParticleState(x if layout == "soa" else np.ascontiguousarray(x), np.full((B, int(N)), -np.log(N)))


def _whitening(R: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, bool, np.ndarray]:
    """Whitening of the masked noise and its log-determinant.

    Masked rows of ``R`` are replaced as in :func:`filters.core.conditioning.mask_moments`
    (identity diagonal, zero cross terms), so a masked residual that is zeroed contributes
    exactly nothing.

    Returns:
        ``(W, diagonal, logdet)``: ``W`` is ``(B, m)`` inverse standard deviations (zero on
        masked rows) when ``R`` is diagonal, else ``(B, m, m)`` with ``W R_used W^T = I`` on the
        used block and zero masked columns; ``logdet (B,)`` of the used block.
    """
    B, mdim = mask.shape
    wmask = mask.astype(np.float64)
    diag = np.einsum("...ii->...i", R)
    if not (R - diag[..., None] * np.eye(mdim)).any():
        var = np.broadcast_to(diag, (B, mdim))
        if (var[mask] <= 0).any() or not np.isfinite(var).all():
            raise ValueError("R must be positive definite on the unmasked rows")
        with np.errstate(divide="ignore"):
            logv = np.where(mask, np.log(np.where(mask, var, 1.0)), 0.0)
        return wmask / np.sqrt(np.where(mask, var, 1.0)), True, logv.sum(axis=1)
    Rm = masked_covariance(np.asarray(R), wmask)
    L, ok = cholesky(Rm)
    if not ok.all():
        raise ValueError("R must be positive definite on the unmasked rows")
    W = np.linalg.inv(L) * wmask[:, None, :]
    logdet = 2.0 * np.log(np.einsum("bii->bi", L)).sum(axis=1)
    return W, False, logdet


def _gaussian_loglik(
    d: np.ndarray,
    v: np.ndarray | None,
    W: np.ndarray,
    diagonal: bool,
    logdet: np.ndarray,
    n_meas: np.ndarray,
) -> np.ndarray:
    """``log N(h(x_i) - z; 0, R)`` per particle from ``d_i = h(x_i) - c`` and ``v = z - c``.

    ``c`` is any per-filter reference (the predictive mean in :func:`weigh`, where ``d`` is
    centred; ``z`` itself with ``v = None``). With diagonal ``R`` the quadratic form is expanded,
    ``sum_j W_j^2 (d_ij - v_j)^2 = (d_i^2) . W^2 - 2 d_i . (W^2 v) + (W^2 v) . v``, two
    matrix-vector products and one squaring pass (``d`` is overwritten); with centred ``d`` the
    expansion loses no accuracy.
    """
    const = 0.5 * (logdet + n_meas * LOG_2PI)
    dt = d.dtype  # float32 particles stay float32 (the small per-filter factors are cast)
    if diagonal:
        W2 = W * W
        quad = np.zeros(d.shape[:2], dtype=dt)
        if v is not None:
            W2v = W2 * v
            quad = (d @ (-2.0 * W2v).astype(dt)[:, :, None])[:, :, 0]
            quad += (W2v * v).sum(axis=1)[:, None]
        np.multiply(d, d, out=d)
        quad += (d @ W2.astype(dt)[:, :, None])[:, :, 0]
    else:
        e = d if v is None else d - v.astype(dt)[:, None, :]
        e = e @ np.swapaxes(W, -1, -2).astype(dt)
        np.multiply(e, e, out=e)
        quad = e @ np.ones(e.shape[-1], dtype=dt)
    quad *= -0.5
    quad -= const[:, None]
    return quad


def _noise_matrix(model: ObservationModel, R: np.ndarray | None, B: int, mdim: int):
    if R is None and isinstance(model, NoisyModel):
        R = model.R
    if R is None:
        return None
    return batched_matrix(R, B, (mdim, mdim), "R")


def _predicted_measurements(model: ObservationModel, x: np.ndarray, mdim: int) -> np.ndarray:
    zhat = model.h(x)
    if zhat.shape != (*x.shape[:2], mdim):
        raise ValueError(f"model.h returned shape {zhat.shape}; expected {(*x.shape[:2], mdim)}")
    return zhat


def particle_log_likelihood(
    x: np.ndarray,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
) -> np.ndarray:
    """Per-particle measurement log-likelihood ``log p(z | x_i)`` (Touil & Ghadi 2012, eq. 16 numerator).

    Gaussian ``N(z; h(x_i), R)`` over the unmasked rows (Carvalho et al. 1997, eq. 3), or the model's
    ``log_likelihood(z, x, mask)`` when it has one.

    Args:
        x: particles ``(B, N, n)``.
        z: measurements ``(B, m)``; masked entries may be NaN.
        model: observation model.
        mask: ``(B, m)`` booleans; None uses every row.
        R: noise override ``(m, m)`` or ``(B, m, m)``.

    Returns:
        ``(B, N)`` log-likelihoods.
    """
    B = x.shape[0]
    z, mask = check_measurement(z, mask, B)
    if isinstance(model, LikelihoodModel) and R is None:
        return _custom_loglik(model.log_likelihood, z, x, mask)
    mdim = z.shape[1]
    Rm = _noise_matrix(model, R, B, mdim)
    if Rm is None:
        raise ValueError("R must be given (the model has neither R nor log_likelihood)")
    d = _predicted_measurements(model, x, mdim) - z[:, None, :]
    W, diagonal, logdet = _whitening(Rm, mask)
    return _gaussian_loglik(d, None, W, diagonal, logdet, mask.sum(axis=1))


def _custom_loglik(fn, z: np.ndarray, x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    ll = np.array(fn(z, x, mask), dtype=np.float64)  # a copy: weigh() edits it in place
    if ll.shape != x.shape[:2]:
        raise ValueError(f"model.log_likelihood returned shape {ll.shape}; expected {x.shape[:2]}")
    return ll


# --------------------------------------------------------------------------------------------
# steps
# --------------------------------------------------------------------------------------------
def predict(
    state: ParticleState,
    model: TransitionModel,
    u: np.ndarray | None = None,
    dt: float = 1.0,
    rng: Rng | None = None,
    Q: np.ndarray | None = None,
) -> ParticleState:
    """Bootstrap prediction (Touil & Ghadi 2012, eq. 15; Carvalho et al. 1997, §III-A step b "evolution").

    ``x_k^i = f(x_{k-1}^i, u, dt) + w_k^i`` with ``w_k^i ~ N(0, Q)`` (or ``model.sample_noise``);
    the weights are unchanged.

    Args:
        state: particles ``x (B, N, n)``, log-weights ``(B, N)``.
        model: transition model with ``f`` and ``Q`` (or ``sample_noise``).
        u: control input, passed to ``f`` unchanged (e.g. ``(B, p)``), or None.
        dt: time step [s].
        rng: one Generator or a sequence of B (required).
        Q: process noise override ``(n, n)`` or ``(B, n, n)`` (an agent's noise scale, say).

    Returns:
        The predicted :class:`ParticleState`.
    """
    B, N, n = check_particles(state)
    if rng is None:
        raise ValueError("rng must be a numpy.random.Generator or a sequence of B of them")
    check_rng(rng, B)
    x = model.f(state.x, u, dt)
    if x.shape != (B, N, n):
        raise ValueError(f"model.f returned shape {x.shape}; expected {(B, N, n)}")
    dtype = cloud_dtype(state.x)
    if x.dtype != dtype and dtype == np.float32:
        x = x.astype(np.float32)  # a float32 cloud stays float32 whatever f promotes to
    support, w = _noise_draw(model, B, N, n, rng, Q, dtype)
    if np.may_share_memory(x, state.x) or not x.flags.writeable:
        if support is None:
            return ParticleState(x + w, state.log_w)
        x = x.copy(order="K")
    if support is None:

        def rows(a: int, b: int) -> None:  # element-wise: the same values on any split
            xa = x[a:b]
            np.add(xa, w[a:b], out=xa)

    else:  # noise-free components: x + 0 is x, so only the driven ones are touched
        xT = x.transpose(0, 2, 1)

        def rows(a: int, b: int) -> None:
            for j, c in enumerate(support):
                xc = xT[a:b, c]
                np.add(xc, w[a:b, j], out=xc)

    over_rows(B, N * n, rows)
    return ParticleState(x, state.log_w)


def weigh(
    x: np.ndarray,
    prior_log_w: np.ndarray,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray,
    R: np.ndarray | None = None,
    prior_w: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, UpdateInfo]:
    """Bayes correction of normalized prior log-weights (see :func:`_weigh`)."""
    post, ll, info, _ = _weigh(x, prior_log_w, z, model, mask, R, prior_w)
    return post, ll, info


def _weigh(
    x: np.ndarray,
    prior_log_w: np.ndarray,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray,
    R: np.ndarray | None = None,
    prior_w: np.ndarray | None = None,
    need_ll: bool = True,
) -> tuple[np.ndarray, np.ndarray, UpdateInfo, np.ndarray]:
    """Bayes correction of prior log-weights (Touil & Ghadi 2012, eq. 16; Carvalho et al. 1997, eq. 6).

    Computes the per-particle log-likelihoods ``l_i = log p(z | x_i)``, the posterior
    ``log w_i = log w0_i + l_i - log p(z | past)`` with ``log p(z | past) = logsumexp(log w0 + l)``
    and the predictive moments ``z_hat = sum_i w0_i h(x_i)``, ``S = sum_i w0_i (h(x_i) - z_hat)
    (h(x_i) - z_hat)^T + R`` (masked rows neutralized as in :mod:`filters.core.conditioning`).

    Steps: :func:`_predictive_mean` (``z_hat``, zero weight for non-finite particles),
    :func:`_centred_spread` (``h(x_i) - z_hat`` and ``P_zz``), :func:`_measurement_log_likelihood`
    (``l_i``), :func:`_innovation_statistics` (``S``, NIS), :func:`_joint_log_weights`
    (``log w0_i + l_i``), :func:`_normalize_log_weights` (``log p(z | past)``, posterior log and
    linear weights) and :func:`_effective_sample_size`.

    Args:
        x: particles ``(B, N, n)``.
        prior_log_w: normalized prior log-weights ``(B, N)``.
        z: checked measurements ``(B, m)`` (masked entries zeroed).
        model: observation model.
        mask: ``(B, m)`` booleans.
        R: noise override.
        prior_w: ``exp(prior_log_w)`` if the caller has it (saves one pass).
        need_ll: False lets the compiled path skip the particle log-likelihoods (then None).

    Returns:
        ``(posterior log-weights (B, N), particle log-likelihoods (B, N), UpdateInfo,
        posterior linear weights (B, N))``; the info's ``ess`` is the posterior ESS and
        ``resampled`` is all False.
    """
    B = x.shape[0]
    mdim = z.shape[1]
    n_meas = mask.sum(axis=1)
    Rm = _noise_matrix(model, R, B, mdim)
    zhat = _predicted_measurements(model, x, mdim)
    w0 = normalized_weights(prior_log_w) if prior_w is None else prior_w
    compiled = _compiled_weigh(x, zhat, w0, prior_log_w, z, model, mask, R, Rm, n_meas, need_ll)
    if compiled is not None:
        return compiled
    zhat, w0, wd, zbar, finite_x, dead = _predictive_mean(x, zhat, w0)
    d, Pzz = _centred_spread(x, zhat, zbar, wd)
    zbar = zbar.astype(np.float64, copy=False)
    v = (z - zbar) * mask
    ll = _measurement_log_likelihood(model, z, x, mask, R, Rm, d, v, n_meas)  # overwrites d
    S, nis, ok = _innovation_statistics(Pzz, Rm, v, mask)
    post, mx = _joint_log_weights(prior_log_w, ll, dead)  # sets ll to -inf where impossible
    post, e, log_norm, bad = _normalize_log_weights(post, mx, prior_log_w, w0)
    healthy = finite_x & ~bad & ok & np.isfinite(zbar).all(axis=1)
    info = UpdateInfo(
        v, S, nis, log_norm, healthy, n_meas, _effective_sample_size(e), np.zeros(B, dtype=bool)
    )
    return post, ll, info, e


def _compiled_weigh(
    x: np.ndarray,
    zhat: np.ndarray,
    w0: np.ndarray,
    prior_log_w: np.ndarray,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray,
    R: np.ndarray | None,
    Rm: np.ndarray | None,
    n_meas: np.ndarray,
    need_ll: bool = True,
) -> tuple[np.ndarray, np.ndarray | None, UpdateInfo, np.ndarray] | None:
    """:func:`_weigh` by the compiled kernels of :mod:`filters.particle.kernels`, or None.

    Applies to a component-major cloud (float32 or float64) whose ``h`` returns the same layout
    and dtype, with the Gaussian likelihood and a diagonal ``R``, when the switch of
    :mod:`filters.core.compiled` allows it. None (the NumPy path runs) otherwise, and for the
    rare paths the kernel leaves to NumPy (a non-finite particle or prediction, every weight
    of a filter vanished). The results equal the NumPy path's to rounding.
    """
    if not compiled_enabled() or Rm is None:
        return None
    if isinstance(model, LikelihoodModel) and R is None:
        return None
    xT = kernels.component_major_buffer(x, x.dtype)
    hT = kernels.component_major_buffer(zhat, x.dtype)
    if hT is None and xT is not None and zhat.dtype == x.dtype:
        # predictions in another layout (e.g. a model writing (m, B, N)): one copy. A one-filter
        # batch is component-major in any layout, so declining here would make a filter's path,
        # and its rounding, depend on the batch size (vector env = single env would break).
        hT = np.ascontiguousarray(zhat.transpose(0, 2, 1))
    if xT is None or hT is None:
        return None
    W, diagonal, logdet = _whitening(Rm, mask)
    if not diagonal:
        return None
    B, N = prior_log_w.shape
    mdim = z.shape[1]
    info32 = np.finfo(np.float32)
    floor = float(info32.tiny / info32.eps) if x.dtype == np.float32 else 0.0
    post, e = np.empty((B, N)), np.empty((B, N))
    ll = np.empty((B, N) if need_ll else (B, 0))
    zbar, Pzz = np.empty((B, mdim)), np.empty((B, mdim, mdim), dtype=x.dtype)
    S, nis = np.empty((B, mdim, mdim)), np.empty(B)
    mx, ok = np.empty(B), np.empty(B, dtype=bool)
    used = mask.astype(np.float64)
    var = np.ascontiguousarray(np.broadcast_to(np.einsum("...ii->...i", Rm), (B, mdim)))
    inv_var, const = W * W, 0.5 * (logdet + n_meas * LOG_2PI)  # (B, m) and (B,)
    w0, prior_log_w = np.ascontiguousarray(w0), np.ascontiguousarray(prior_log_w)
    log_norm, ess = np.empty(B), np.empty(B)

    def rows(a: int, b: int) -> None:  # filters a:b, each from its own rows alone
        kernels.weigh_pass(
            xT[a:b], hT[a:b], w0[a:b], prior_log_w[a:b], z[a:b], inv_var[a:b], var[a:b], used[a:b],
            const[a:b], floor, post[a:b], ll[a:b], zbar[a:b], Pzz[a:b], S[a:b], nis[a:b], mx[a:b], ok[a:b],
        )  # fmt: skip
        if ok[a:b].all():  # else the NumPy path redoes the whole batch
            ea = e[a:b]
            np.subtract(post[a:b], mx[a:b, None], out=ea)
            exp_weights(ea, out=ea)
            kernels.normalize_pass(post[a:b], ea, mx[a:b], log_norm[a:b], ess[a:b])

    over_rows(B, N * (xT.shape[1] + mdim), rows)
    if not ok.all():
        return None
    v = (z - zbar) * mask
    info = UpdateInfo(v, S, nis, log_norm, np.ones(B, dtype=bool), n_meas, ess, np.zeros(B, dtype=bool))
    return post, ll if need_ll else None, info, e


def _predictive_mean(
    x: np.ndarray, zhat: np.ndarray, w0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Predictive measurement mean under the prior weights, ``z_bar = sum_i w0_i h(x_i)``.

    The product runs in the particles' precision (float32 particles: no float64 copy of
    ``h(x)``; subnormal weights flushed, :func:`filters.core.layout.weights_in`). Rare path:
    particles with a non-finite state or prediction get zero weight, ``w0_i = 0`` and
    ``w0 <- w0 / sum_j w0_j``, and a zero prediction, so they poison neither the moments nor the
    weights (the filter is flagged unhealthy through ``finite_x``).

    Returns:
        ``(zhat, w0, wd, zbar, finite_x, dead)``: predictions ``(B, N, m)`` and prior weights
        ``(B, N)`` (both replaced on the rare path), ``wd`` the weights in the predictions'
        dtype, ``zbar (B, m)`` in that dtype, ``finite_x (B,)`` whether every particle of a
        filter is finite, ``dead (B, N)`` the zero-weighted particles (None when there are none).
    """
    wd = weights_in(w0, zhat.dtype)
    zbar = (wd[:, None, :] @ zhat)[:, 0, :]
    finite_x = np.isfinite(x.sum(axis=(1, 2)))
    dead = None
    if not (finite_x.all() and np.isfinite(zbar).all()):
        dead = ~(np.isfinite(x).all(axis=2) & np.isfinite(zhat).all(axis=2))
        zhat = np.where(dead[:, :, None], 0.0, zhat)
        w0 = np.where(dead, 0.0, w0)
        w0 /= np.maximum(w0.sum(axis=1, keepdims=True), 1e-300)
        wd = weights_in(w0, zhat.dtype)
        zbar = (wd[:, None, :] @ zhat)[:, 0, :]
    return zhat, w0, wd, zbar, finite_x, dead


def _centred_spread(
    x: np.ndarray, zhat: np.ndarray, zbar: np.ndarray, wd: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Centred predictions ``d_i = h(x_i) - z_bar`` and their spread ``P_zz = sum_i w0_i d_i d_i^T``.

    ``d`` is ``zhat`` centred in place (a copy when ``zhat`` shares memory with ``x``). For a
    component-major ``d`` (the ``(B, m, N)`` buffer seen as ``(B, N, m)``) the broadcasts run
    along the contiguous N axis (the same numbers; the timing is in ``docs/performance.md``).

    Returns:
        ``(d (B, N, m), P_zz (B, m, m) float64)``.
    """
    d = zhat.copy(order="K") if np.may_share_memory(zhat, x) else zhat
    dT = d.transpose(0, 2, 1)
    if dT.flags.c_contiguous:
        dT -= zbar[:, :, None]
        wdT = dT * wd[:, None, :]
    else:
        d -= zbar[:, None, :]
        wdT = np.swapaxes(d * wd[:, :, None], 1, 2)
    return d, (wdT @ d).astype(np.float64, copy=False)


def _measurement_log_likelihood(
    model: ObservationModel,
    z: np.ndarray,
    x: np.ndarray,
    mask: np.ndarray,
    R: np.ndarray | None,
    Rm: np.ndarray | None,
    d: np.ndarray,
    v: np.ndarray,
    n_meas: np.ndarray,
) -> np.ndarray:
    """Per-particle log-likelihood of the measurement rows, ``l_i = log p(z | x_i)``.

    The model's ``log_likelihood(z, x, mask)`` when it has one and no ``R`` override is given;
    else the Gaussian over the ``n_meas`` unmasked rows (Carvalho et al. 1997, eq. 3)::

        l_i = -1/2 (h(x_i) - z)^T R^-1 (h(x_i) - z) - 1/2 (log det R + n_meas log 2 pi)

    evaluated from the centred ``d_i = h(x_i) - z_bar`` and ``v = z - z_bar``
    (:func:`_gaussian_loglik`, which overwrites ``d``).

    Returns:
        ``(B, N)`` float64 log-likelihoods (a fresh array: the caller edits it in place).
    """
    if isinstance(model, LikelihoodModel) and R is None:
        return _custom_loglik(model.log_likelihood, z, x, mask)
    if Rm is None:
        raise ValueError("R must be given (the model has neither R nor log_likelihood)")
    W, diagonal, logdet = _whitening(Rm, mask)
    return _gaussian_loglik(d, v, W, diagonal, logdet, n_meas)


def _innovation_statistics(
    Pzz: np.ndarray, Rm: np.ndarray | None, v: np.ndarray, mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Innovation covariance ``S = P_zz + R`` and the NIS ``v^T S^-1 v``.

    ``S`` is symmetrized and its masked rows neutralized as in :mod:`filters.core.conditioning`
    (identity diagonal, zero cross terms; with a custom likelihood and no ``R``, ``S = P_zz``).

    Returns:
        ``(S (B, m, m), nis (B,), ok (B,))``, ``ok`` False where ``S`` is not positive definite.
    """
    S = Pzz if Rm is None else Pzz + Rm
    S = masked_covariance(symmetrize(S), mask.astype(np.float64))
    S_inv, _, ok = spd_inverse(S)
    return S, np.einsum("bi,bij,bj->b", v, S_inv, v), ok


def _joint_log_weights(
    prior_log_w: np.ndarray, ll: np.ndarray, dead: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """Unnormalized posterior log-weights ``log w0_i + l_i`` and their maximum per filter.

    Dead particles (:func:`_predictive_mean`) and NaN sums get ``l_i = log w_i = -inf`` (``ll`` is
    edited in place), so the maximum is finite unless every weight of a filter vanished.

    Returns:
        ``(post (B, N), max (B,))``.
    """
    if dead is not None:
        ll[dead] = -np.inf
    post = prior_log_w + ll
    mx = post.max(axis=1)
    if not np.isfinite(mx).all():
        nan = np.isnan(post)
        ll[nan] = -np.inf
        post[nan] = -np.inf
        mx = post.max(axis=1)
    return post, mx


def _normalize_log_weights(
    post: np.ndarray, mx: np.ndarray, prior_log_w: np.ndarray, w0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Normalization (Touil & Ghadi 2012, eq. 16), one ``exp`` for the log and linear weights.

    ``log p(z | past) = logsumexp_i(log w0_i + l_i) = mx + log sum_i exp(log w0_i + l_i - mx)``,
    ``log w_i = log w0_i + l_i - log p(z | past)``, ``w_i = exp(log w0_i + l_i - mx) / sum``.
    A filter whose every weight vanished (``mx`` not finite) keeps its prior weights and gets
    ``log p(z | past) = -inf``. ``post`` is normalized in place.

    Returns:
        ``(log w (B, N), w (B, N), log p(z | past) (B,), vanished (B,))``.
    """
    bad = ~np.isfinite(mx)
    mx[bad] = 0.0
    e = post - mx[:, None]
    exp_weights(e, out=e)
    total = e.sum(axis=1)
    with np.errstate(divide="ignore"):
        log_norm = mx + np.log(total)
    if bad.any():
        log_norm[bad] = -np.inf
        post[bad] = prior_log_w[bad]
        e[bad] = w0[bad]
        total[bad] = 1.0
        log_norm_safe = np.where(bad, 0.0, log_norm)
    else:
        log_norm_safe = log_norm
    post -= log_norm_safe[:, None]
    e /= total[:, None]
    return post, e, log_norm, bad


def _effective_sample_size(w: np.ndarray) -> np.ndarray:
    """Effective sample size of normalized weights ``(B, N)``, ``ESS = 1 / sum_i w_i^2`` ``(B,)``."""
    return 1.0 / np.einsum("bn,bn->b", w, w)


def update(
    state: ParticleState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
    forgetting: np.ndarray | float | None = None,
    decision: np.ndarray | bool | None = None,
    rng: Rng | None = None,
    method: str = "systematic",
) -> tuple[ParticleState, UpdateInfo]:
    """Bootstrap measurement update (Touil & Ghadi 2012, eq. 16; Carvalho et al. 1997, eq. 6 and Example 1).

    ``log w_k^i = gamma log w_{k-1}^i + log p(z_k | x_k^i) - log c_k`` where ``gamma`` is the
    age-weighting factor of Carvalho et al. 1997, Example 1 (``alpha(k, l) = gamma^(k-l)``; ``gamma = 1`` is
    the plain filter) and ``c_k`` normalizes. Because the log-weights are renormalized every
    step, the recursion reproduces Example 1's ``sum_i gamma^(k-i) ||Y_i - h(X_i)||^2`` up to a
    particle-independent constant. Optionally resamples afterwards (Touil & Ghadi 2012, eq. 17) where
    ``decision`` is True.

    Diagnostics, with the (tempered) prior weights ``w0``: ``innovation = z - z_hat`` with the
    particle predictive mean ``z_hat = sum_i w0_i h(x_i)``; ``S = sum_i w0_i (h(x_i) - z_hat)
    (h(x_i) - z_hat)^T + R``; NIS ``v^T S^-1 v``; ``log_likelihood = log sum_i w0_i p(z | x_i)``,
    the particle estimate of ``log p(z_k | z_{1:k-1})``; ``ess`` after the Bayes correction
    (before any resampling); ``healthy`` False when a particle is non-finite, every weight
    vanished (the prior weights are then kept) or ``S`` is not positive definite.

    Args:
        state: predicted particles ``(B, N, n)`` and log-weights ``(B, N)``.
        z: measurements ``(B, m)``; masked entries may be NaN.
        model: observation model (``h`` and ``R``, or ``log_likelihood``).
        mask: ``(B, m)`` booleans; a False row contributes exactly nothing. None uses all rows.
        R: measurement noise override ``(m, m)`` or ``(B, m, m)`` (forces the Gaussian
            likelihood).
        forgetting: age-weighting factor ``gamma`` in ``(0, 1]``, scalar or ``(B,)``; None is 1.
        decision: resample afterwards where True, ``(B,)`` or scalar; None never resamples.
        rng: generator(s), required when ``decision`` is given.
        method: resampling scheme (a key of :data:`filters.core.resampling.RESAMPLERS`).

    Returns:
        ``(filtered state, UpdateInfo)``; ``info.resampled`` is the applied decision.
    """
    new, info, wpost = _update(state, z, model, mask, R, forgetting, None)
    if decision is not None:
        if rng is None:
            raise ValueError("rng must be given when decision is")
        d = check_decision(decision, state.x.shape[0])
        new = resample(new, d, rng, method, weights=wpost)
        info = info._replace(resampled=d)
    return new, info


class WeightedUpdate(NamedTuple):
    """:func:`update_weighted`'s result: the filtered state, its diagnostics and linear weights."""

    state: ParticleState  #: the filtered particles and normalized log-weights
    info: UpdateInfo  #: the update's diagnostics (``resampled`` all False)
    weights: np.ndarray  #: ``(B, N)`` the normalized linear weights, ``exp(state.log_w)``


def update_weighted(
    state: ParticleState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None = None,
    R: np.ndarray | None = None,
    prior_weights: np.ndarray | None = None,
) -> WeightedUpdate:
    """:func:`update` without resampling that also returns the posterior's linear weights.

    The same Bayes correction (Touil & Ghadi 2012, eq. 16); the update computes the normalized
    linear weights ``w_i = exp(log w_i)`` anyway (its normalization and ESS), so a caller that
    needs them next (moments, a trigger, the next resampling or update) takes them from here
    instead of exponentiating the log-weights again, one pass over ``(B, N)`` each.

    Args:
        state: predicted particles ``(B, N, n)`` and log-weights ``(B, N)``.
        z: measurements ``(B, m)``; masked entries may be NaN.
        model: observation model (``h`` and ``R``, or ``log_likelihood``).
        mask: ``(B, m)`` booleans; a False row contributes exactly nothing. None uses all rows.
        R: measurement noise override ``(m, m)`` or ``(B, m, m)``.
        prior_weights: ``(B, N)`` the normalized linear weights of ``state.log_w`` if the caller
            has them (what this function returned last step, ``1/N`` on resampled rows); not
            re-checked. None computes them.

    Returns:
        :class:`WeightedUpdate` ``(state, info, weights)``.
    """
    return WeightedUpdate(*_update(state, z, model, mask, R, None, prior_weights))


def _update(
    state: ParticleState,
    z: np.ndarray,
    model: ObservationModel,
    mask: np.ndarray | None,
    R: np.ndarray | None,
    forgetting: np.ndarray | float | None,
    prior_weights: np.ndarray | None,
) -> tuple[ParticleState, UpdateInfo, np.ndarray]:
    """The Bayes correction of :func:`update` and :func:`update_weighted`: ``(state, info, weights)``."""
    B, N, n = check_particles(state)
    z, mask = check_measurement(z, mask, B)
    prior = np.asarray(state.log_w, dtype=np.float64)
    if forgetting is not None:
        gamma = batched_vector(forgetting, B, "forgetting")
        if not (np.isfinite(gamma).all() and (gamma > 0).all() and (gamma <= 1).all()):
            raise ValueError("forgetting must lie in (0, 1]")
        prior = prior * gamma[:, None]
    if prior_weights is not None:
        if np.shape(prior_weights) != (B, N):
            raise ValueError(
                f"prior_weights must have shape {(B, N)} like log_w; got {np.shape(prior_weights)}"
            )
        w0 = np.asarray(prior_weights, dtype=np.float64)
    else:
        # equal weights (after resampling): 1/N and -log N, what the normalization gives to
        # rounding; decided per filter, so that a filter's result does not depend on the other
        # rows of the batch
        equal = (prior[:, :1] == prior).all(axis=1) if compiled_enabled() else np.zeros(B, dtype=bool)
        if equal.all():
            prior, w0 = np.full(prior.shape, -np.log(N)), np.full(prior.shape, 1.0 / N)
        else:
            prior, w0 = _prior_weights(prior)
            if equal.any():
                prior[equal], w0[equal] = -np.log(N), 1.0 / N
    post, _, info, wpost = _weigh(state.x, prior, z, model, mask, R, prior_w=w0, need_ll=False)
    return ParticleState(state.x, post), info, wpost


def _prior_weights(log_w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalized log and linear prior weights; cheap when ``log_w`` is (nearly) normalized.

    ``w = exp(log_w) / s``, ``log w = log_w - log s`` with ``s = sum exp(log_w)``: two passes
    fewer than the max-shifted form, which is used when ``s`` is not a safe number or some
    log-weight is below -700 (where ``exp`` is slow; :func:`filters.core.resampling.exp_weights`).
    """
    if log_w.size and log_w.min() >= EXP_FLUSH:
        w = np.exp(log_w)
        total = w.sum(axis=1, keepdims=True)
        if np.isfinite(total).all() and (total > 1e-200).all():
            w /= total
            return log_w - np.log(total), w
    return log_and_linear_weights(log_w)


def resample(
    state: ParticleState,
    decision: np.ndarray | bool | None,
    rng: Rng,
    method: str = "systematic",
    weights: np.ndarray | None = None,
) -> ParticleState:
    """Resample where ``decision`` is True (Touil & Ghadi 2012, eq. 17; Carvalho et al. 1997, §III-D).

    Particles of a resampled filter are drawn by ``method`` and reset to weight ``1/N``
    ("reinitializing all of them with weight 1/N", Carvalho et al. 1997, §III-D); other filters keep their
    particles and weights unchanged and draw no random numbers.

    Args:
        state: particles ``(B, N, n)`` and log-weights ``(B, N)``.
        decision: ``(B,)`` booleans (or a scalar); None resamples every filter.
        rng: one Generator or a sequence of B.
        method: a key of :data:`filters.core.resampling.RESAMPLERS`.
        weights: ``exp(state.log_w)`` normalized, if already computed (not re-checked).

    Returns:
        The resampled :class:`ParticleState` (new arrays; the input is not modified).
    """
    B, N, n = check_particles(state)
    if method not in RESAMPLERS:
        raise ValueError(f"method must be one of {sorted(RESAMPLERS)}; got {method!r}")
    d = check_decision(decision, B)
    if not d.any():
        return state
    compiled = _compiled_systematic(state, d, rng, method, weights)
    if compiled is not None:
        return compiled
    anc = resample_ancestors(state.log_w, rng, method, d, weights=weights)
    if d.all():
        return ParticleState(gather(state.x, anc), np.full((B, N), -np.log(N)))
    x = state.x.copy(order="K")
    x[d] = gather(state.x[d], anc[d])
    log_w = np.array(state.log_w, dtype=np.float64, copy=True)
    log_w[d] = -np.log(N)
    return ParticleState(x, log_w)


def _compiled_systematic(
    state: ParticleState, d: np.ndarray, rng: Rng, method: str, weights: np.ndarray | None
) -> ParticleState | None:
    """:func:`resample` by :func:`filters.particle.kernels.systematic_pass`, or None.

    Applies to systematic resampling of a component-major cloud (float32 or float64) when the
    switch of :mod:`filters.core.compiled` allows it. The uniforms are drawn as
    :func:`filters.core.resampling.resample` draws them (one per resampled filter, in the same
    order, from the same generators), so the ancestors are the NumPy path's for the same weights.
    """
    if method != "systematic" or not compiled_enabled():
        return None
    xT = kernels.component_major_buffer(state.x, state.x.dtype)
    if xT is None:
        return None
    B, N = d.shape[0], state.x.shape[1]
    check_rng(rng, B)
    if weights is not None and np.shape(weights) != (B, N):
        raise ValueError(f"weights must have shape {(B, N)} like log_w; got {np.shape(weights)}")
    rows = np.flatnonzero(d)
    lw = np.asarray(state.log_w, dtype=np.float64)
    if weights is not None:
        w = np.ascontiguousarray(weights, dtype=np.float64)
    elif rows.size == B:
        w = normalized_weights(lw)
    else:
        w = np.zeros((B, N))
        w[rows] = normalized_weights(lw[rows])
    U = np.zeros(B)
    U[rows] = uniform(rng, B, (1,), rows)[:, 0]
    out = np.empty(xT.shape, dtype=xT.dtype)
    ancestors = np.empty((B, N), dtype=np.int64)
    d = np.ascontiguousarray(d)

    def filters(a: int, b: int) -> None:  # each filter's resampling reads its own row alone
        kernels.systematic_pass(w[a:b], U[a:b], d[a:b], xT[a:b], out[a:b], ancestors[a:b])

    over_rows(B, N * (xT.shape[1] + 2), filters)
    if rows.size == B:
        log_w = np.full((B, N), -np.log(N))
    else:
        log_w = np.array(lw, copy=True)
        log_w[d] = -np.log(N)
    return ParticleState(out.transpose(0, 2, 1), log_w)
