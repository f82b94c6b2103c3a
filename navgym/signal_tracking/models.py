"""Dirac-Gauss DPF n.d., §3: GPS correlator outputs of a highly dynamic receiver, as a hybrid Markov model.

Every code period ``T = 1 ms`` the correlators output (Dirac-Gauss DPF n.d., §3, one satellite)::

    y_k = A_k h(k T - R_k / c) D_k exp(-j 2 pi f1 R_k / c + j phi_k) + nu_k

with ``h`` the triangular correlation pulse of the C/A code (one chip = 293.05 m), ``D_k`` the
navigation bit (constant over 20 codes, a two-state Markov chain flipping with probability 1/2
at bit boundaries whose timing is unknown), the amplitude and phase drifting as Gaussian random
walks, and the user's range, velocity and acceleration following the modified Singer model::

    R_{k+1} = R_k + v_k T,   v_{k+1} = v_k (1 - alpha T) + gamma_k T,   gamma_{k+1} = gamma_k + pi_k w_k

(``pi_k`` Poisson, ``w_k`` Gaussian in the paper). Choices of this reproduction, where the paper
gives no values: the carrier phase is carried as ``Phi = phi - 2 pi R / lambda`` (a linear change
of variables: ``Phi_{k+1} = Phi_k - 2 pi v_k T / lambda + dphi_k``, so the dynamics stay linear
and the EKFs linearize ``exp(j Phi)`` and ``h`` only); the correlators are an early / prompt /
late triple at +-1/2 chip around the range the filter predicts (a delay-locked replica steered
by the estimate); jumps arrive at ``jump_rate`` per second with magnitudes uniform in
``+-jump_max_g`` g (the paper: "acceleration jump +-10 g"); ``alpha = 0.05 / s``. The SNR is the
prompt correlator's ``A^2 / (2 sigma^2)`` per 1 ms sample (Dirac-Gauss DPF n.d.: 0 to -3 dB).

State ``x = [A, Phi, R, v, gamma]``; mode ``d = c + 20 b``: ``c`` the code's index within its
bit, ``b`` 0 for ``D = +1`` and 1 for ``D = -1`` (40 modes).

Shared by the study ``experiments.dirac_gauss`` (which moved it here) and the SignalTracking
platform (:mod:`navgym.signal_tracking.platform`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from filters.core.resampling import Rng, uniform

C_LIGHT = 299_792_458.0
LAMBDA_L1 = C_LIGHT / 1575.42e6  # carrier wavelength [m]
CHIP_M = C_LIGHT / 1.023e6  # C/A chip [m]
T_CODE = 1e-3  # code period [s]
CODES_PER_BIT = 20
N_MODES = 2 * CODES_PER_BIT
G0 = 9.80665
TAPS_CHIPS = np.array([-0.5, 0.0, 0.5])  # early, prompt, late


@dataclass(frozen=True)
class SignalConfig:
    """Signal and dynamics parameters (module docstring)."""

    snr_db: float = 0.0
    sigma: float = 1.0  # noise std of each real correlator component
    singer_alpha: float = 0.05  # velocity damping [1/s]
    jump_rate: float = 0.5  # acceleration jumps per second
    jump_max_g: float = 10.0
    jump_bins: int = 10  # M_w: the deterministic filter's nonzero grid points
    amp_walk: float = 1e-3  # amplitude random walk per step, relative to A
    phase_walk: float = 0.01  # phase random walk per step [rad]
    accel_walk: float = 0.05  # Gaussian acceleration noise per step [m/s^2]
    taps: np.ndarray = field(default_factory=lambda: TAPS_CHIPS.copy())

    @property
    def amplitude(self) -> float:
        return float(self.sigma * np.sqrt(2.0 * 10.0 ** (self.snr_db / 10.0)))


def transition_matrix(cfg: SignalConfig) -> np.ndarray:
    """``F`` of ``x = [A, Phi, R, v, gamma]`` over one code period."""
    T = T_CODE
    F = np.eye(5)
    F[1, 3] = -2.0 * np.pi * T / LAMBDA_L1
    F[2, 3] = T
    F[3, 3] = 1.0 - cfg.singer_alpha * T
    F[3, 4] = T
    return F


def process_noise(cfg: SignalConfig) -> np.ndarray:
    """The Gaussian part ``Q`` of the process noise (amplitude, phase, acceleration walks)."""
    return np.diag([(cfg.amp_walk * cfg.amplitude) ** 2, cfg.phase_walk**2, 0.0, 0.0, cfg.accel_walk**2])


class SignalModel:
    """:class:`filters.particle.dirac_gauss.HybridModel` of the correlator outputs.

    ``aux``: the replica's prompt range ``(K,)`` [m]; the taps sit at ``aux + taps x chip``.
    """

    def __init__(self, cfg: SignalConfig) -> None:
        self.cfg = cfg
        self.F = transition_matrix(cfg)
        self.Q = process_noise(cfg)
        L = len(cfg.taps)
        self.R = cfg.sigma**2 * np.eye(2 * L)
        p = cfg.jump_rate * T_CODE
        edges = np.linspace(-cfg.jump_max_g, cfg.jump_max_g, cfg.jump_bins + 1) * G0
        centers = 0.5 * (edges[1:] + edges[:-1])
        width = edges[1] - edges[0]
        self.jump_grid = np.zeros((cfg.jump_bins + 1, 5))
        self.jump_grid[1:, 4] = centers
        with np.errstate(divide="ignore"):  # jump_rate 0: the jump points get probability 0
            self.jump_log_prob = np.log(np.r_[1.0 - p, np.full(cfg.jump_bins, p / cfg.jump_bins)])
        self.jump_cov = np.zeros((cfg.jump_bins + 1, 5, 5))
        self.jump_cov[1:, 4, 4] = width**2 / 12.0  # the spread of the jumps in each bin

    def mode_children(self, mode: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        c, b = mode % CODES_PER_BIT, mode // CODES_PER_BIT
        last = c == CODES_PER_BIT - 1
        same = np.where(last, b * CODES_PER_BIT, mode + 1)  # next code, same bit value
        flip = np.where(last, (1 - b) * CODES_PER_BIT, same)  # a new bit of the other value
        log_half = np.log(0.5)
        logp = np.stack([np.where(last, log_half, 0.0), np.where(last, log_half, -np.inf)], axis=-1)
        return np.stack([same, flip], axis=-1), logp

    def sample_jump(self, rng: Rng, B: int, N: int) -> np.ndarray:
        u = uniform(rng, B, (N, 2))
        jump = np.where(u[..., 0] <= self.cfg.jump_rate * T_CODE, 1.0, 0.0)
        out = np.zeros((B, N, 5))
        out[..., 4] = jump * (2.0 * u[..., 1] - 1.0) * self.cfg.jump_max_g * G0
        return out

    def _parts(self, x: np.ndarray, mode: np.ndarray, prompt: np.ndarray):
        A, Phi, R = x[:, 0], x[:, 1], x[:, 2]
        D = 1.0 - 2.0 * (mode // CODES_PER_BIT)
        u = (R[:, None] - prompt[:, None]) / CHIP_M - self.cfg.taps  # (K, L)
        tri = np.maximum(1.0 - np.abs(u), 0.0)
        dtri = np.where(np.abs(u) < 1.0, -np.sign(u), 0.0) / CHIP_M
        return A, D, np.cos(Phi), np.sin(Phi), tri, dtri

    def h(self, x: np.ndarray, mode: np.ndarray, aux: np.ndarray) -> np.ndarray:
        A, D, c, s, tri, _ = self._parts(x, mode, aux)
        amp = (A * D)[:, None] * tri
        return np.concatenate([amp * c[:, None], amp * s[:, None]], axis=1)

    def H(self, x: np.ndarray, mode: np.ndarray, aux: np.ndarray) -> np.ndarray:
        A, D, c, s, tri, dtri = self._parts(x, mode, aux)
        K, L = tri.shape
        J = np.zeros((K, 2 * L, 5))
        cs = (c[:, None], s[:, None])
        for half, (trig, dtrig) in enumerate(((cs[0], -cs[1]), (cs[1], cs[0]))):
            rows = slice(half * L, (half + 1) * L)
            J[:, rows, 0] = D[:, None] * tri * trig
            J[:, rows, 1] = (A * D)[:, None] * tri * dtrig
            J[:, rows, 2] = (A * D)[:, None] * dtri * trig
        return J


class Truth(NamedTuple):
    """Simulated truth of B runs over T steps."""

    x: np.ndarray  # (B, T, 5)
    mode: np.ndarray  # (B, T)
    bit_index: np.ndarray  # (B, T): index of the bit each code belongs to


def simulate_truth(
    cfg: SignalConfig, rngs: list[np.random.Generator], steps: int, rowwise: bool = False
) -> Truth:
    """Truth of ``len(rngs)`` runs: random code phase, bits, initial phase, Doppler and jumps.

    Run b draws from ``rngs[b]`` alone, in a fixed order (run b equals a single run with that
    generator); the recursion runs over time for all runs at once. With ``rowwise`` the
    recursion's product ``x F^T`` is summed element by element instead of by a BLAS matrix
    product (whose rounding may depend on the number of rows), so run b is bit-identical alone
    and in a batch (the platform's episodes; the study keeps the matrix product).
    """
    B = len(rngs)
    F = transition_matrix(cfg)
    Qs = np.sqrt(np.diag(process_noise(cfg)))
    n_bits = steps // CODES_PER_BIT + 2
    c0 = np.empty(B, dtype=np.int64)
    bits = np.zeros((B, n_bits), dtype=np.int64)  # the first bit is +1 (known sign)
    x0 = np.zeros((B, 5))
    e = np.empty((B, steps, 5))
    jump = np.empty((B, steps))
    for b, g in enumerate(rngs):
        c0[b] = g.integers(CODES_PER_BIT)
        bits[b, 1:] = g.integers(0, 2, n_bits - 1)
        x0[b] = [cfg.amplitude, g.uniform(-np.pi, np.pi), 0.0, g.uniform(-300.0, 300.0), 0.0]
        e[b] = g.standard_normal((steps, 5)) * Qs
        arrive = g.random(steps) < cfg.jump_rate * T_CODE
        jump[b] = np.where(arrive, g.uniform(-1.0, 1.0, steps) * cfg.jump_max_g * G0, 0.0)
    e[..., 4] += jump
    x = np.empty((B, steps, 5))
    xk = x0
    for k in range(steps):  # the recursion over time, batched over the runs
        x[:, k] = xk
        xk = ((xk[:, None, :] * F).sum(axis=2) if rowwise else xk @ F.T) + e[:, k]
    codes = c0[:, None] + np.arange(steps)
    bit_index = codes // CODES_PER_BIT
    mode = codes % CODES_PER_BIT + CODES_PER_BIT * np.take_along_axis(bits, bit_index, axis=1)
    return Truth(x, mode, bit_index)


def observe(
    model: SignalModel, x: np.ndarray, mode: np.ndarray, prompt: np.ndarray, noise: np.ndarray
) -> np.ndarray:
    """Correlator outputs ``(B, 2L)`` of true states ``x (B, 5)`` for replicas at ``prompt (B,)``."""
    return model.h(x, mode, prompt) + model.cfg.sigma * noise
