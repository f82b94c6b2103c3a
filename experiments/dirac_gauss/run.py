"""Run the two Dirac-Gauss filters of Dirac-Gauss DPF n.d. on simulated correlator outputs."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from filters.particle import dirac_gauss as dg
from navgym.signal_tracking.models import (
    CHIP_M,
    CODES_PER_BIT,
    LAMBDA_L1,
    N_MODES,
    T_CODE,
    SignalConfig,
    SignalModel,
    Truth,
    observe,
)

#: Prior standard deviations of [A (relative), Phi, R, v, gamma] (after acquisition).
PRIOR_SIGMA = np.array([0.1, 0.2, 15.0, 0.5, 1.0])


class RunResult(NamedTuple):
    """Per-step estimates of B runs over T steps."""

    est: np.ndarray  # (B, T, 5) posterior means
    p_minus: np.ndarray  # (B, T) posterior probability of D = -1
    ess: np.ndarray  # (B, T)
    seconds: float


def prior(cfg: SignalConfig, truth: Truth, rngs: list[np.random.Generator]) -> tuple[np.ndarray, np.ndarray]:
    """Prior means (truth + one draw of the prior error per run) and covariances at step 0."""
    sig = PRIOR_SIGMA * np.array([cfg.amplitude, 1, 1, 1, 1])
    err = np.stack([g.standard_normal(5) for g in rngs]) * sig
    B = len(rngs)
    return truth.x[:, 0] + err, np.broadcast_to(np.diag(sig**2), (B, 5, 5)).copy()


def run(
    kind: str,
    cfg: SignalConfig,
    truth: Truth,
    noise: np.ndarray,
    m0: np.ndarray,
    P0: np.ndarray,
    N: int,
    rngs: list[np.random.Generator],
    alpha: float = 1.0 / 3.0,
    pbar=None,
) -> RunResult:
    """Filter every run with ``kind`` = "deterministic" or "random" and N particles.

    The correlators of each filter follow its own prediction of the range (the replica is
    steered by the estimate), so the observations are formed here from the truth and the shared
    noise draws ``noise (B, T, 2L)``.
    """
    import time

    model = SignalModel(cfg)
    B, T = truth.mode.shape
    # the unknown code phase: every index within the bit, the first bit's value known (+1)
    modes = np.broadcast_to(np.arange(N) % CODES_PER_BIT, (B, N))
    if kind == "random":
        modes = np.stack([g.integers(0, CODES_PER_BIT, N) for g in rngs])
    state = dg.initial_state(m0, P0, modes)
    est = np.empty((B, T, 5))
    p_minus = np.empty((B, T))
    ess = np.empty((B, T))
    t0 = time.perf_counter()
    prev = dg.mixture_moments(state).m
    for k in range(T):
        prompt = prev[:, 2] if k == 0 else prev[:, 2] + T_CODE * prev[:, 3]
        y = observe(model, truth.x[:, k], truth.mode[:, k], prompt, noise[:, k])
        if kind == "deterministic":
            state, info = dg.deterministic_step(state, y, model, k, aux=prompt, alpha=alpha)
        else:
            state, info = dg.random_step(state, y, model, k, rngs, aux=prompt)
        prev = dg.mixture_moments(state).m
        est[:, k] = prev
        p_minus[:, k] = dg.mode_probabilities(state, N_MODES)[:, CODES_PER_BIT:].sum(axis=1)
        ess[:, k] = info.ess
        if pbar is not None:
            pbar.update(1)
    return RunResult(est, p_minus, ess, time.perf_counter() - t0)


#: Bits decided within this time after an acceleration jump count as the jump's transient [s].
TRANSIENT_S = 0.5
#: A change of the true acceleration above this in one step is a jump [m/s^2] (the Gaussian
#: acceleration walk is 0.05 m/s^2 per step).
JUMP_DETECT = 1.0


def metrics(truth: Truth, res: RunResult, settle_s: float = 0.2) -> dict[str, np.ndarray]:
    """Per-run errors after ``settle_s``: range and Doppler RMSE, bit errors, half-cycle slips, lock.

    Bits are decided at each bit's last code (posterior probability of ``D = -1`` above 1/2).
    The carrier phase leaves a sign ambiguity (``D, Phi`` and ``-D, Phi + pi`` give the same
    signal), so a half-cycle slip inverts every later bit: ``bit_errors`` counts raw decisions,
    ``transition_errors`` the differentially decoded ones (a slip costs one), and
    ``transient_*`` the part of them and of the bits within ``TRANSIENT_S`` after a jump. A run
    has lost lock when its final range error exceeds half a chip.
    """
    B, T = truth.mode.shape
    k0 = int(settle_s / T_CODE)
    dR = res.est[:, k0:, 2] - truth.x[:, k0:, 2]
    dv = res.est[:, k0:, 3] - truth.x[:, k0:, 3]
    ends = np.zeros((B, T), dtype=bool)
    ends[:, :-1] = truth.bit_index[:, 1:] != truth.bit_index[:, :-1]
    ends[:, :k0] = False
    true_minus = truth.mode >= CODES_PER_BIT
    est_minus = res.p_minus > 0.5
    jump = np.zeros((B, T), dtype=bool)
    jump[:, 1:] = np.abs(np.diff(truth.x[..., 4], axis=1)) > JUMP_DETECT
    since = np.cumsum(jump, axis=1)  # transient: a jump within the last TRANSIENT_S
    lag = int(TRANSIENT_S / T_CODE)
    before = np.zeros_like(since)  # jumps up to lag steps ago
    if lag < T:
        before[:, lag:] = since[:, :-lag]
    transient = since - before > 0
    raw = np.empty(B, dtype=np.int64)
    diff = np.empty(B, dtype=np.int64)
    diff_tr = np.empty(B, dtype=np.int64)
    bits_tr = np.empty(B, dtype=np.int64)  # transitions decided in a jump's transient
    for b in range(B):  # per run: its decided bits (a few hundred), not a hot path
        d_true, d_est = true_minus[b, ends[b]], est_minus[b, ends[b]]
        raw[b] = (d_true != d_est).sum()
        wrong = (d_true[1:] != d_true[:-1]) != (d_est[1:] != d_est[:-1])
        tr = transient[b, ends[b]][1:]
        diff[b], diff_tr[b], bits_tr[b] = wrong.sum(), (wrong & tr).sum(), tr.sum()
    return {
        "range_rmse_m": np.sqrt((dR**2).mean(axis=1)),
        "doppler_rmse_hz": np.sqrt((dv**2).mean(axis=1)) / LAMBDA_L1,
        "bit_errors": raw,
        "transition_errors": diff,
        "transient_transition_errors": diff_tr,
        "bits": ends.sum(axis=1),
        "transitions": np.maximum(ends.sum(axis=1) - 1, 0),  # consecutive bit pairs compared
        "transient_transitions": bits_tr,
        "jumps": jump.sum(axis=1),
        "lost": np.abs(dR[:, -1]) > CHIP_M / 2,
    }
