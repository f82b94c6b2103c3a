"""n-conditional exploration with M auxiliary particles per base particle (Carvalho et al. 1997, §III-C).

The a priori exploration of an unstable system drifts away from the observed path; the
exploration of Carvalho et al. 1997, §III-C, conditions each base particle's next trajectory
section on the section's observations:

1. each of the N base particles ``x^{e,j}_{k-L}`` spawns M auxiliary particles at its position;
2. the auxiliary particles move L steps ahead by the dynamics (Carvalho et al. 1997, eq. 1) with independent
   noises, accumulating their measurement log-likelihoods over the section,
   ``log p^{a,i} = sum_{l} log p(y_l | x_l^{a,i})``;
3. one auxiliary trajectory per base particle is selected at random with probability
   ``p^{a,i} / sum_{i'} p^{a,i'}`` (the "discrete representation of the probability law");
4. the base weight is multiplied by the Monte Carlo estimate of ``dP(y_[k] | x_[k-1])``,
   ``(1/M) sum_i p^{a,i}`` (Carvalho et al. 1997, §III-C step c), i.e. ``p^{e,j} proportional to
   w^{e,j} sum_i {p^{a,i}}^j`` normalized over the base particles (the last display of §III-C).

The paper takes the section length ``L = n = dim(X)`` ("n is always sufficient if the system
is uniformly observable"); here ``L`` is the number of measurements passed in one call, and
``L = 1`` gives one-step conditional exploration after every measurement. ``M = 1`` is the
bootstrap filter. Only the final positions of the selected sections are kept (the filter is
Markov).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from filters.core.models import ObservationModel, TransitionModel
from filters.core.resampling import Rng, check_rng, exp_weights, uniform
from filters.core.types import ParticleState, UpdateInfo
from filters.core.validation import check_measurement
from filters.particle.bootstrap import particle_log_likelihood, predict, weigh
from filters.particle.estimates import check_particles, logsumexp, normalize_log_weights

__all__ = ["explore"]


def _per_step(value: object, L: int, ndim_single: int, name: str) -> list:
    """``value`` for each of ``L`` steps: None, one array for all steps, or a sequence of L."""
    if value is None:
        return [None] * L
    if isinstance(value, (list, tuple)):
        if len(value) != L:
            raise ValueError(f"{name} must hold one entry per measurement ({L}); got {len(value)}")
        return list(value)
    arr = np.asarray(value)
    if arr.ndim == ndim_single + 1 and arr.shape[0] == L:
        return list(arr)
    return [value] * L


def explore(
    state: ParticleState,
    model: TransitionModel,
    z: np.ndarray | Sequence[np.ndarray],
    rng: Rng,
    M: int,
    u: np.ndarray | Sequence[np.ndarray] | None = None,
    dt: float = 1.0,
    mask: np.ndarray | Sequence[np.ndarray] | None = None,
    R: np.ndarray | None = None,
    observation: ObservationModel | None = None,
) -> tuple[ParticleState, UpdateInfo]:
    """One n-conditional section: predict and update with M auxiliary particles per particle.

    Replaces ``predict`` + ``update`` of the bootstrap filter over a section of ``L``
    measurements (Carvalho et al. 1997, §III-C, steps b-c of the modified algorithm).

    Args:
        state: filtered particles at the start of the section, ``(B, N, n)``.
        model: transition model (``f``, ``Q`` or ``sample_noise``), and the observation model
            too (``h``, ``R`` or ``log_likelihood``) unless ``observation`` is given.
        z: measurements of the section: ``(B, m)`` (``L = 1``) or ``(L, B, m)`` / a list of L.
        rng: one Generator or a sequence of B.
        M: auxiliary particles per base particle (>= 1).
        u: control per step: None, one array for every step, or ``(L, ...)`` / a list of L.
        dt: time step [s].
        mask: ``(B, m)`` for every step, ``(L, B, m)`` or a list of L; None uses every row.
        R: measurement noise override.
        observation: the observation model when it is not ``model`` (as the bootstrap
            filter's ``predict`` and ``update`` take their models apart).

    Returns:
        ``(state, UpdateInfo)``. The info's innovation, ``S`` and NIS are those of the last
        measurement of the section under the auxiliary predictive cloud (weights
        ``w_j / M`` times the section's earlier likelihoods); ``log_likelihood`` is the
        estimate of ``log p(y_section | past)``, ``logsumexp_j(log w_j + log (1/M) sum_i
        p^{a,i,j})``; ``ess`` is after the section.

    """
    B, N, n = check_particles(state)
    if not isinstance(M, (int, np.integer)) or M < 1:
        raise ValueError(f"M must be an integer >= 1; got {M!r}")
    check_rng(rng, B)
    zs = list(z) if isinstance(z, (list, tuple)) else None
    if zs is None:
        za = np.asarray(z, dtype=np.float64)
        if za.ndim == 2:
            zs = [za]
        elif za.ndim == 3:
            zs = list(za)
        else:
            raise ValueError(f"z must have shape (B, m) or (L, B, m); got {za.shape}")
    obs = model if observation is None else observation
    L = len(zs)
    if L < 1:
        raise ValueError("z must hold at least one measurement")
    us = _per_step(u, L, 2, "u")
    masks = _per_step(mask, L, 2, "mask")
    checked = [check_measurement(zs[i], masks[i], B) for i in range(L)]

    aux = ParticleState(np.repeat(state.x, M, axis=1), np.zeros((B, N * M)))
    log_p = np.zeros((B, N * M))
    info = None
    lw0, _ = normalize_log_weights(np.asarray(state.log_w, dtype=np.float64))
    prior_aux = np.repeat(lw0, M, axis=1) - np.log(M)
    for i, (zi, mi) in enumerate(checked):
        aux = predict(aux, model, us[i], dt, rng)
        if i == L - 1:
            # predictive of the last measurement given the section's earlier ones
            last_prior, _ = normalize_log_weights(prior_aux + log_p)
            _, ll, info = weigh(aux.x, last_prior, zi, obs, mi, R)
        else:
            ll = particle_log_likelihood(aux.x, zi, obs, mi, R)
        log_p += np.where(np.isnan(ll), -np.inf, ll)

    log_p = log_p.reshape(B, N, M)
    # step 4: pick one auxiliary section per base particle, P(i) = p^{a,i} / sum_i' p^{a,i'}
    lse = logsumexp(log_p, axis=2)  # (B, N)
    safe = np.where(np.isfinite(lse), lse, 0.0)
    cdf = np.cumsum(exp_weights(log_p - safe[:, :, None]), axis=2)
    cdf /= np.where(cdf[:, :, -1:] > 0, cdf[:, :, -1:], 1.0)
    U = uniform(rng, B, (N,))
    choice = np.minimum((cdf < U[:, :, None]).sum(axis=2), M - 1)
    x_aux = aux.x.reshape(B, N, M, n)
    x_new = np.take_along_axis(x_aux, choice[:, :, None, None], axis=2)[:, :, 0, :]
    # step c: base weight times (1/M) sum_i p^{a,i}
    post, log_norm = normalize_log_weights(lw0 + lse - np.log(M))
    bad = ~np.isfinite(log_norm)
    if bad.any():
        post[bad] = lw0[bad]
    w = exp_weights(post)
    info = info._replace(
        log_likelihood=log_norm,
        healthy=info.healthy & ~bad & np.isfinite(x_new.reshape(B, -1).sum(axis=1)),
        ess=1.0 / np.einsum("bn,bn->b", w, w),
    )
    return ParticleState(x_new, post), info
