"""The SignalTracking estimation problem: GPS signal tracking with jumps (Dirac-Gauss DPF n.d., §3-4).

One satellite's correlator outputs, every code period ``T = 1`` ms, of a receiver whose
acceleration jumps (Poisson, up to +-10 g) while the navigation bits (20 codes each, unknown
timing) modulate the carrier: the correlator model of :mod:`navgym.signal_tracking.models`
(shared with the study ``experiments.dirac_gauss``), state ``x = [A, Phi, R, v, gamma]``
(amplitude, carrier phase, range [m], range rate [m/s], acceleration [m/s^2]).

**One env step is** ``codes_per_step`` **code periods** (default 10, half a bit: ``dt = 10`` ms):
the task's filter (the random Dirac-Gauss PF, :mod:`navgym.signal_tracking.task`) processes
them one by one, and the knob the agent sets holds over the step.

**Episodes** (:meth:`SignalTrackingPlatform.simulate`): the truth of
:func:`~navgym.signal_tracking.models.simulate_truth` over ``T x codes_per_step`` code periods
(random code phase within the bit, bits, initial phase, initial range rate uniform in +-300 m/s,
jumps at ``jump_rate`` per second, uniform in +-``jump_max_g`` g), the correlator noise of every
code period, the scenario's outages as signal blockages (noise only in the correlators; none by
default), and the filter's prior: truth plus one draw of ``N(0, diag(prior_sigma)^2)`` (a
receiver after pull-in). The jumps are the v2 events unknown to the filter: its model's jump
prior is the knob.

**The correlators depend on the filter.** The early / prompt / late correlators sit around the
range the filter predicts (the replica follows the filter's own estimate), so the measurements
cannot be precomputed: :meth:`~SignalTrackingPlatform.step_models` hands the task a
:class:`Correlators` object, the receiver's correlator bank for the step's code periods, whose
:meth:`Correlators.outputs` returns the 6 correlator outputs (I and Q of early, prompt, late) for
the replica range the filter gives it. The truth inside it never leaves it except as those
outputs, as in a receiver. ``StepModels.z`` is therefore all NaN with ``mask`` all True (the 6
rows are used every step); the task reports the step's (data-wiped) correlator residuals as its
innovations.

**Truth for the clairvoyant** (evaluation only): ``StepModels.truth`` is a :class:`JumpTruth`,
which code periods of the step carry a true jump (their magnitudes are not given).

**Errors**: ``pos_err_m`` is the absolute range error [m] at the step's last code period (the
platform is one-dimensional: ``truth_pos`` and ``est_pos`` are ``(range, 0)``, ``cov_ne`` is
``diag(P_RR, 0)``); ``extra_error`` is ``doppler_weight x |Doppler error|`` [m] with the Doppler
error ``|v_est - v| / lambda_L1`` [Hz]. Loss of code lock, a range error beyond half a chip
(146.5 m, ``divergence_m``), ends the episode with the core's divergence penalty.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from navgym.envs.features import (
    CovarianceBlock,
    Feature,
    covariance_values,
    innovation_features,
    innovation_initial_values,
    innovation_values,
)
from navgym.envs.platform import PlatformBase
from navgym.envs.protocols import PositionError, StepModels
from navgym.scenarios import Scenario, ScenarioDistribution, default_rngs, gnss_available, stack_scenarios
from navgym.signal_tracking.models import (
    CHIP_M,
    LAMBDA_L1,
    T_CODE,
    SignalConfig,
    SignalModel,
    simulate_truth,
)

#: The platform's signal: the study's model at 0 dB with denser jumps (2 per second, the study's
#: ``--jump-rate 2`` variant), so a 1 s episode carries about two.
PLATFORM_SIGNAL = SignalConfig(snr_db=0.0, jump_rate=2.0)
#: Prior sigmas of ``[A (relative), Phi [rad], R [m], v [m/s], gamma [m/s^2]]`` after pull-in
#: (0.3 x the study's acquisition prior, which loses lock from the start in some runs).
PRIOR_SIGMA = (0.03, 0.06, 4.5, 0.15, 0.3)
#: Half a C/A chip [m]: a range error beyond it is a loss of code lock (the correlators no longer
#: see the code).
HALF_CHIP_M = CHIP_M / 2.0
#: A change of the true acceleration above this between two code periods is a jump [m/s^2]
#: (the study's ``experiments.dirac_gauss.run.JUMP_DETECT``).
JUMP_DETECT = 1.0


class SignalEpisodes(NamedTuple):
    """Truth and correlator noise of B episodes over ``K = T x codes_per_step`` code periods.

    Truth-only fields (evaluation, and the correlators' inside): ``x``, ``mode``, ``noise``,
    ``jump``.
    """

    x: np.ndarray  # (B, K, 5) true state per code period (truth)
    mode: np.ndarray  # (B, K) true mode (code index within the bit, bit value) (truth)
    noise: np.ndarray  # (B, K, 6) standard normal correlator noise (truth)
    jump: np.ndarray  # (B, K) bool: a true acceleration jump arrives between code periods k - 1 and k (truth)
    visible: np.ndarray  # (B, K) bool: the signal is received (False in the scenario's outages: blockage)
    m0: np.ndarray  # (B, 5) the filter's prior mean


class JumpTruth(NamedTuple):
    """What the clairvoyant reads of a step (evaluation only): which of its code periods jump."""

    jump: np.ndarray  #: (B, codes_per_step) bool: a true jump arrives in the prediction into that code period


class Correlators:
    """The receiver's correlator bank of one env step for B episodes (module docstring).

    ``outputs(j, prompt)`` gives the 6 correlator outputs ``(B, 6)`` of the step's code period
    ``j`` for replicas at ``prompt (B,)`` [m]: ``h(x_true, mode_true, prompt) + sigma noise``
    (:func:`navgym.signal_tracking.models.observe`). The task only ever sees these outputs.
    """

    def __init__(
        self, model: SignalModel, x: np.ndarray, mode: np.ndarray, noise: np.ndarray, visible: np.ndarray
    ) -> None:
        self._model, self._x, self._mode, self._noise, self._visible = model, x, mode, noise, visible
        self.codes = x.shape[1]  #: code periods in the step

    def outputs(self, j: int, prompt: np.ndarray) -> np.ndarray:
        """Correlator outputs ``(B, 6)`` of code period ``j`` for replica ranges ``prompt (B,)``.

        In a blockage (the scenario's outages) the signal is gone: noise only.
        """
        x, mode, e = self._x[:, j], self._mode[:, j], self._noise[:, j]
        signal = self._model.h(x, mode, np.asarray(prompt, np.float64))
        return np.where(self._visible[:, j, None], signal, 0.0) + self._model.cfg.sigma * e


@dataclass(frozen=True)
class SignalTrackingPlatform(PlatformBase):
    """Dirac-Gauss DPF n.d.'s signal tracking problem (see the module docstring and the env card).

    Attributes:
        signal: Signal and dynamics of the truth (:class:`~navgym.signal_tracking.models.SignalConfig`).
        codes_per_step: Code periods per env step (``dt = codes_per_step x 1 ms``).
        prior_sigma: Prior sigmas (``A`` relative to the amplitude).
        doppler_weight: Metres of reward error per Hz of Doppler error.
        true_noise: Keep the jump times for the clairvoyant (``StepModels.truth``).
    """

    signal: SignalConfig = PLATFORM_SIGNAL
    codes_per_step: int = 10
    prior_sigma: tuple[float, ...] = PRIOR_SIGMA
    doppler_weight: float = 0.1
    scenarios: ScenarioDistribution = field(default_factory=ScenarioDistribution)
    error_scale_m: float = 10.0
    divergence_m: float = HALF_CHIP_M
    true_noise: bool = True
    name: str = "SignalTracking"
    n: int = 5
    m_max: int = 6

    def __post_init__(self) -> None:
        self.check_reward_scales()

    @property
    def dt(self) -> float:
        return self.codes_per_step * T_CODE

    @property
    def filter_model(self) -> SignalModel:
        """The filter's nominal model: the truth's signal and dynamics (its jump prior is the knob)."""
        return _model(self.signal)

    def episode_bytes(self, T: int) -> int:
        """Bytes of one episode of ``T`` steps at reset (see the Platform protocol).

        Per code period the state, noise, mode and flags (17 values of 8 bytes), twice over for
        the simulation's temporaries (process noise, jumps).
        """
        return 2 * 8 * 17 * (int(T) * self.codes_per_step + 1) + 8 * 5

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> SignalEpisodes:
        """Truth, correlator noise and prior of B episodes of T steps.

        Each episode draws three child seeds (truth, noise, prior) from its generator, so B
        episodes at once equal B single ones; the time recursion runs for all of them at once.
        """
        cfg = self.signal
        K = int(T) * self.codes_per_step
        seeds = np.array([r.integers(0, 2**63 - 1, size=3) for r in rngs])
        g_truth, g_noise, g_prior = (default_rngs(seeds[:, i]) for i in range(3))
        truth = simulate_truth(cfg, g_truth, K, rowwise=True)
        noise = np.stack([g.standard_normal((K, 6)) for g in g_noise])
        # a jump arrives between code periods k - 1 and k (the filter's prediction into code
        # period k) where the acceleration moves by more than JUMP_DETECT (the Gaussian walk is
        # accel_walk = 0.05 m/s^2 per code period: 20 sigma; a smaller jump is not flagged)
        jump = np.zeros((len(rngs), K), dtype=bool)
        jump[:, 1:] = np.abs(np.diff(truth.x[..., 4], axis=1)) > JUMP_DETECT
        sig = np.asarray(self.prior_sigma) * np.array([cfg.amplitude, 1.0, 1.0, 1.0, 1.0])
        m0 = truth.x[:, 0] + np.stack([g.standard_normal(5) for g in g_prior]) * sig
        tt = np.broadcast_to(np.arange(K) * T_CODE, (len(rngs), K))
        visible = gnss_available(stack_scenarios(list(scenarios)), tt)
        return SignalEpisodes(truth.x, truth.mode, noise, jump, visible, m0)

    def P0(self) -> np.ndarray:
        """Prior covariance ``(5, 5)``: ``diag(prior_sigma)^2`` (amplitude scaled)."""
        sig = np.asarray(self.prior_sigma) * np.array([self.signal.amplitude, 1.0, 1.0, 1.0, 1.0])
        return np.diag(sig**2)

    def initial_belief(self, ep: SignalEpisodes) -> GaussianState:
        B = ep.m0.shape[0]
        return GaussianState(ep.m0.copy(), np.broadcast_to(self.P0(), (B, 5, 5)).copy())

    # ---------------------------------------------------------------------------------- step
    def _codes(self, ep: SignalEpisodes, t: np.ndarray) -> np.ndarray:
        """Code-period indices ``(B, S)`` of the step from ``t`` (the last step repeats at the end)."""
        S = self.codes_per_step
        last = ep.noise.shape[1] // S - 1
        return np.minimum(t, last)[:, None] * S + np.arange(S)

    def step_models(self, ep: SignalEpisodes, t: np.ndarray) -> StepModels:
        B = t.shape[0]
        rows = np.arange(B)[:, None]
        k = self._codes(ep, t)
        corr = Correlators(
            self.filter_model, ep.x[rows, k], ep.mode[rows, k], ep.noise[rows, k], ep.visible[rows, k]
        )
        truth = JumpTruth(ep.jump[rows, k].copy()) if self.true_noise else None
        return StepModels(
            self.filter_model,
            corr,
            np.full((B, self.m_max), np.nan),
            np.ones((B, self.m_max), dtype=bool),
            self.dt,
            truth=truth,  # type: ignore[arg-type]  # the platform's own truth (JumpTruth)
        )

    def position_error(
        self, mean: np.ndarray, ep: SignalEpisodes, t: np.ndarray, P: np.ndarray
    ) -> PositionError:
        """Range error at the step's last code period; ``extra_error``: ``doppler_weight x`` Doppler error."""
        B = t.shape[0]
        rows = np.arange(B)
        k = np.maximum(np.minimum(t, ep.noise.shape[1] // self.codes_per_step) * self.codes_per_step - 1, 0)
        x = ep.x[rows, k]
        err = mean - x
        err[:, 1] = np.angle(np.exp(1j * err[:, 1]))  # the phase error, wrapped
        zeros = np.zeros(B)
        cov = np.zeros((B, 2, 2))
        cov[:, 0, 0] = P[:, 2, 2]
        doppler = np.abs(err[:, 3]) / LAMBDA_L1
        return PositionError(
            np.abs(err[:, 2]),
            np.stack([x[:, 2], zeros], 1),
            np.stack([mean[:, 2], zeros], 1),
            cov,
            err,
            self.doppler_weight * doppler,
        )

    # ------------------------------------------------------------------------------ features
    def covariance_blocks(self) -> tuple[CovarianceBlock, ...]:
        return (
            CovarianceBlock("log_sigma_range", (2,), -3.0, 3.0, "log10 m", "log10 sqrt(P_RR)"),
            CovarianceBlock("log_sigma_velocity", (3,), -4.0, 3.0, "log10 m/s", "log10 sqrt(P_vv)"),
            CovarianceBlock("log_sigma_accel", (4,), -3.0, 3.0, "log10 m/s^2", "log10 sqrt(P_gamma)"),
        )

    def features(self) -> list[Feature]:
        return [
            *innovation_features(
                self.m_max,
                "correlator residuals (I then Q of early, prompt, late; data wiped) averaged over the step "
                "/ sqrt(S_ii)",
            ),
            *(Feature(b.name, b.low, b.high, b.unit, b.description) for b in self.covariance_blocks()),
        ]

    def initial_feature_values(self, belief: GaussianState, ep: SignalEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        return {
            **innovation_initial_values(B, self.m_max),
            **covariance_values(belief.P, self.covariance_blocks()),
        }

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: SignalEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        return {
            **innovation_values(info, models.mask, self.m_max),
            **covariance_values(belief.P, self.covariance_blocks()),
        }


_MODELS: dict[tuple, SignalModel] = {}


def _model(cfg: SignalConfig) -> SignalModel:
    """One :class:`SignalModel` per configuration (its arrays are read only)."""
    key = (cfg.snr_db, cfg.sigma, cfg.singer_alpha, cfg.jump_rate, cfg.jump_max_g, cfg.jump_bins,
           cfg.amp_walk, cfg.phase_walk, cfg.accel_walk, tuple(cfg.taps))  # fmt: skip
    if key not in _MODELS:
        _MODELS[key] = SignalModel(cfg)
    return _MODELS[key]
