"""The Jumps task (v2): the agent sets the jump prior of a random Dirac-Gauss PF every step.

The filter is the random Dirac-Gauss particle filter of Dirac-Gauss DPF n.d., §2.1
(:func:`filters.particle.dirac_gauss.random_step`): N particles, each a mode (code index within
the bit and the bit's value) and an EKF of ``x = [A, Phi, R, v, gamma]``; every code period each
particle draws its mode transition and, with probability ``p``, an acceleration jump uniform in
+-``jump_max_g`` g (the prior of the model's ``pi_k w_k``), its EKF updates on the 6 correlator
outputs, the weights take the EKFs' predictive likelihoods, and the cloud is resampled
(systematic) when ESS / N falls below ``ess_threshold``.

**The knob** is ``p``, the per-code-period jump probability of every particle, held over the
env step's code periods. ``Box(-1, 1, (1,))``, log-mapped over ``jump_range = (p_lo, p_hi)``
(default ``1e-5`` to ``0.1``): ``p = 10 ** (lo + (a + 1) / 2 (hi - lo))``. The plain filter (the
**neutral action**) uses the nominal ``p = NOMINAL_JUMP_PROBABILITY = 2e-3`` (2 jumps per second,
the platform's default rate), ``a = -1 + 2 (log10 2e-3 - lo) / (hi - lo) = 0.1505`` for the
default range. A larger ``p`` spends more particles on jump hypotheses (ready for a jump, noisier
between jumps); a smaller one keeps them on the no-jump track. It trades in both directions.

**Clairvoyant reference** (``clairvoyant=True``, evaluation only): the knob is ignored; in an env
step whose code periods contain a true jump (``StepModels.truth``, a
:class:`~navgym.signal_tracking.platform.JumpTruth`: only *which steps* jump, not when within the
step nor how much) it sets ``p = min(p_hi, 1 / codes_per_step)`` (about one jump per particle,
at a uniform code period of the step), and ``p = p_lo`` in the other steps. It is a schedule of
the knob itself (every value it uses is an action), so its gain is a gain the knob can reach.

**The replica follows the filter**: before each code period the prompt correlator is placed at
the range the filter predicts (``R + v T`` of the posterior mixture mean), as in the study.

**What the step reports** (estimator-side only): the innovation of each code period is the
correlator outputs minus the prediction of the heaviest particle (predicted one code period,
its data bit wiped: the sign of the prediction that fits better, as a Costas discriminator is
blind to the bit), averaged over the step; its covariance ``S = sigma^2 I / codes`` (the average of
white correlator noise). The features add the mean and smallest ESS / N of the step, the mean
log-likelihood per code period, the applied ``log10 p`` and the prompt's lock indicator
``(I'^2 - Q'^2) / (I'^2 + Q'^2)`` summed over the step (``I', Q'`` the prompt rotated by the
heaviest particle's phase: ``cos 2 dPhi``, 1 in carrier lock, about 0 out of it).

**Registration**: the task's :class:`~navgym.envs.tasks.TaskSpec` (:data:`JUMPS`) is registered
when this module is imported, as :mod:`navgym.signal_tracking.env` does: the platform registers
its own task, and the core imports no platform.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from filters.core.resampling import Rng, uniform
from filters.core.types import GaussianState
from filters.particle import dirac_gauss as dg
from navgym.envs.arguments import Argument, Flag, Integer, Interval, Real
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels, TaskStep
from navgym.envs.tasks import TaskSpec, check_action, register_task, truth_of
from navgym.signal_tracking.models import CODES_PER_BIT, G0, T_CODE, SignalModel

#: The plain filter's jump probability per code period (2 jumps per second).
NOMINAL_JUMP_PROBABILITY = 2e-3
#: Largest particle count of the Jumps task (B x N EKFs per code period).
MAX_JUMP_PARTICLES = 4096
#: Bounds of the mean log-likelihood per code period in the observation.
LOG_LIKELIHOOD_RANGE = (-50.0, 10.0)


class JumpModel:
    """A :class:`SignalModel` whose jump probability per code period is ``p (B,)`` (the knob)."""

    def __init__(self, model: SignalModel, p: np.ndarray) -> None:
        self.model, self.p = model, np.asarray(p, np.float64)
        self.F, self.Q, self.R = model.F, model.Q, model.R
        self.jump_grid, self.jump_log_prob, self.jump_cov = (
            model.jump_grid,
            model.jump_log_prob,
            model.jump_cov,
        )
        self.cfg = model.cfg
        self.mode_children, self.h, self.H = model.mode_children, model.h, model.H

    def sample_jump(self, rng: Rng, B: int, N: int) -> np.ndarray:
        """Jumps ``(B, N, 5)``: with probability ``p_b`` uniform in +-jump_max_g g (the study's draws)."""
        u = uniform(rng, B, (N, 2))
        jump = np.where(u[..., 0] <= self.p[:, None], 1.0, 0.0)
        out = np.zeros((B, N, 5))
        out[..., 4] = jump * (2.0 * u[..., 1] - 1.0) * self.cfg.jump_max_g * G0
        return out


class JumpsStats(NamedTuple):
    """The step's diagnostics in the shape the core and the memory features read."""

    innovation: np.ndarray  # (B, 6)
    S: np.ndarray  # (B, 6, 6)
    nis: np.ndarray  # (B,)
    n_meas: np.ndarray  # (B,)
    log_likelihood: np.ndarray  # (B,) summed over the step's code periods
    healthy: np.ndarray  # (B,)
    ess: np.ndarray  # (B,) after the step's last code period
    resampled: np.ndarray  # (B,) resamplings in the step


class JumpsDiagnostics(NamedTuple):
    """The Jumps task's diagnostics of a step (keys of ``info``; they feed the features)."""

    jump_probability: np.ndarray  #: (B,) the applied p (the clairvoyant's schedule included)
    ess_frac: np.ndarray  #: (B,) mean ESS / N over the step's code periods
    min_ess_frac: np.ndarray  #: (B,) smallest ESS / N of the step
    mean_log_likelihood: np.ndarray  #: (B,) log-likelihood per code period
    lock_indicator: np.ndarray  #: (B,) the prompt's carrier lock indicator over the step
    resampled: np.ndarray  #: (B,) resamplings in the step


#: The Jumps task's keyword arguments.
ARGUMENTS = (
    Argument("n_particles", 128, Integer(1, MAX_JUMP_PARTICLES), "particles N of the random Dirac-Gauss PF"),
    Argument(
        "jump_range",
        (1e-5, 0.1),
        Interval(0.0, 1.0, low_open=True),
        f"(p_lo, p_hi) of the jump probability, p_lo <= {NOMINAL_JUMP_PROBABILITY:g} <= p_hi, p_lo < p_hi",
        refused=((0.01, 0.1), (1e-5, 1e-3), (2e-3, 2e-3)),
    ),
    Argument("ess_threshold", 0.5, Real(0.0, 1.0), "resample when ESS / N falls below it"),
    Argument(
        "clairvoyant", False, Flag(), "evaluation only: the knob set from the true jump steps", opt_in=True
    ),
)
_N, _RANGE, _ESS, _CLAIRVOYANT = ARGUMENTS


class JumpsTask:
    """The agent sets the jump probability of the random Dirac-Gauss PF each step (module docstring)."""

    name = "Jumps"
    baseline_family = "Jumps"

    def __init__(
        self,
        n_particles: int = 128,
        jump_range: tuple[float, float] = (1e-5, 0.1),
        ess_threshold: float = 0.5,
        clairvoyant: bool = False,
    ) -> None:
        self.n_particles = _N.check(n_particles)
        lo, hi = _RANGE.check(jump_range)
        if not (lo <= NOMINAL_JUMP_PROBABILITY <= hi and lo < hi):
            raise ValueError(
                f"jump_range must be a pair (low, high) with 0 < low <= {NOMINAL_JUMP_PROBABILITY:g} <= high "
                f"<= 1 and low < high (the plain filter's probability is in range); got {jump_range!r}"
            )
        self.jump_range = (lo, hi)
        self.log_low, self.log_high = float(np.log10(lo)), float(np.log10(hi))
        self.ess_threshold = _ESS.check(ess_threshold)
        #: Evaluation only: ignore the knob, set it from the true jump steps (module docstring).
        self.clairvoyant = _CLAIRVOYANT.check(clairvoyant)
        self.filter_name = f"dgpf{self.n_particles}" + ("/clairvoyant" if self.clairvoyant else "")
        self.action_space: spaces.Space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    # ------------------------------------------------------------------------------- knob
    def probabilities(self, a: np.ndarray) -> np.ndarray:
        """``p`` of actions ``a`` in [-1, 1] (log-mapped over ``jump_range``)."""
        return 10.0 ** (
            self.log_low + (np.asarray(a, np.float64) + 1.0) / 2.0 * (self.log_high - self.log_low)
        )

    def action_of(self, p: np.ndarray | float) -> np.ndarray:
        """The action ``(..., 1)`` float32 of probabilities ``p`` (clipped into ``jump_range``)."""
        lp = np.log10(np.clip(np.asarray(p, np.float64), *self.jump_range))
        a = -1.0 + 2.0 * (lp - self.log_low) / (self.log_high - self.log_low)
        return np.clip(a, -1.0, 1.0).astype(np.float32)[..., None]

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        a, clipped = check_action(action, self.action_space, B)
        if self.clairvoyant:
            return np.full(B, NOMINAL_JUMP_PROBABILITY), clipped
        return self.probabilities(a[:, 0]), clipped

    def neutral_action(self) -> np.ndarray:
        """The plain filter: ``p = NOMINAL_JUMP_PROBABILITY``."""
        return self.action_of(NOMINAL_JUMP_PROBABILITY).reshape(1)

    # ------------------------------------------------------------------------------ filter
    def init_state(self, belief: GaussianState, rngs: Sequence[np.random.Generator]) -> dg.DiracGaussState:
        """N particles at the prior, the code phase within the bit spread over them (``i mod 20``)."""
        B = belief.m.shape[0]
        modes = np.broadcast_to(np.arange(self.n_particles) % CODES_PER_BIT, (B, self.n_particles))
        return dg.initial_state(belief.m, belief.P, modes)

    def step(
        self,
        state: dg.DiracGaussState,
        knob: np.ndarray,
        models: StepModels,
        rngs: Sequence[np.random.Generator],
    ) -> TaskStep[dg.DiracGaussState, JumpsDiagnostics]:
        corr = models.observation
        base: SignalModel = models.transition
        B = state.m.shape[0]
        S = corr.codes
        if self.clairvoyant:
            jumped = np.asarray(truth_of(models, "JumpsTask").jump).any(axis=1)
            knob = np.where(jumped, min(self.jump_range[1], 1.0 / S), self.jump_range[0])
        model = JumpModel(base, knob)
        sigma = base.cfg.sigma
        rngs = list(rngs)
        resid = np.zeros((B, 6))
        ll = np.zeros(B)
        ess_sum = np.zeros(B)
        ess_min = np.full(B, np.inf)
        resampled = np.zeros(B)
        ip2 = np.zeros(B)
        qp2 = np.zeros(B)
        healthy = np.ones(B, dtype=bool)
        rows = np.arange(B)
        for j in range(S):
            mean = dg.mixture_moments(state).m
            prompt = mean[:, 2] + T_CODE * mean[:, 3]
            y = corr.outputs(j, prompt)
            best = np.argmax(state.log_w, axis=1)
            xb = state.m[rows, best] @ base.F.T
            mb = base.mode_children(state.mode[rows, best], j)[0][:, 0]  # the bit kept (wiped below)
            yb = base.h(xb, mb, prompt)
            sign = np.where(((y - yb) ** 2).sum(1) <= ((y + yb) ** 2).sum(1), 1.0, -1.0)
            resid += y - sign[:, None] * yb
            c, s = np.cos(xb[:, 1]), np.sin(xb[:, 1])
            i_p, q_p = y[:, 1], y[:, 4]  # the prompt's I and Q (taps -1/2, 0, +1/2)
            ip2 += (c * i_p + s * q_p) ** 2
            qp2 += (-s * i_p + c * q_p) ** 2
            state, info = dg.random_step(
                state, y, model, j, rngs, aux=prompt, ess_threshold=self.ess_threshold
            )
            ll += np.where(np.isfinite(info.log_likelihood), info.log_likelihood, 0.0)
            healthy &= np.asarray(info.healthy, dtype=bool)
            ess = info.ess / self.n_particles
            ess_sum += ess
            ess_min = np.minimum(ess_min, ess)
            resampled += info.resampled
        innovation = resid / S
        S_mat = np.broadcast_to(np.eye(6) * sigma**2 / S, (B, 6, 6)).copy()
        nis = (innovation**2).sum(axis=1) * S / sigma**2
        belief = dg.mixture_moments(state)
        stats = JumpsStats(innovation, S_mat, nis, np.full(B, 6), ll, healthy, ess_sum / S, resampled)
        diagnostics = JumpsDiagnostics(
            jump_probability=knob,
            ess_frac=ess_sum / S,
            min_ess_frac=ess_min,
            mean_log_likelihood=ll / S,
            lock_indicator=(ip2 - qp2) / np.maximum(ip2 + qp2, 1e-300),
            resampled=resampled,
        )
        return TaskStep(state, belief, stats, None, np.zeros(B), knob, diagnostics)

    # ---------------------------------------------------------------------------- features
    def features(self) -> list[Feature]:
        return [
            Feature(
                "log_jump_probability",
                self.log_low,
                self.log_high,
                "log10",
                "log10 p, the applied jump prior",
            ),
            Feature("ess_frac", 0.0, 1.0, "-", "mean ESS / N over the step's code periods"),
            Feature("min_ess_frac", 0.0, 1.0, "-", "smallest ESS / N of the step"),
            Feature(
                "mean_log_likelihood",
                *LOG_LIKELIHOOD_RANGE,
                "-",
                "the filter's log p(y_k | y_1:k-1) averaged over the step's code periods",
            ),
            Feature(
                "lock_indicator",
                -1.0,
                1.0,
                "-",
                "prompt carrier lock indicator (I'^2 - Q'^2) / (I'^2 + Q'^2) over the step (cos 2 dPhi)",
            ),
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {
            "log_jump_probability": np.full(B, np.log10(NOMINAL_JUMP_PROBABILITY)),
            "ess_frac": np.ones(B),
            "min_ess_frac": np.ones(B),
            "mean_log_likelihood": np.zeros(B),
            "lock_indicator": np.ones(B),
        }

    def feature_values(self, step: TaskStep[dg.DiracGaussState, JumpsDiagnostics]) -> dict[str, np.ndarray]:
        d = step.diagnostics
        return {
            "log_jump_probability": np.log10(d.jump_probability),
            "ess_frac": d.ess_frac,
            "min_ess_frac": d.min_ess_frac,
            "mean_log_likelihood": d.mean_log_likelihood,
            "lock_indicator": d.lock_indicator,
        }


#: How many times its cloud a step of the Jumps task holds at its peak (:func:`state_bytes`).
STEP_COPIES = 16


def state_bytes(task: JumpsTask, platform: Any) -> int:
    """Bytes of one episode's Dirac-Gauss cloud at its peak in a step (``TaskSpec.state_bytes``).

    The cloud holds ``n + n**2 + 2`` float64 values per particle (its EKF's mean and covariance,
    its mode and log-weight; ``n`` the state size). A code period's step holds it
    :data:`STEP_COPIES` times over: the cloud before and after, the prediction, the jump draws
    and, per particle, the EKF bank's Jacobian, innovation covariance, gain and Joseph-form
    products (each a few ``n x n`` or ``m x n`` blocks with ``m`` correlator outputs).
    """
    n = int(platform.n)
    return int(task.n_particles) * STEP_COPIES * 8 * (n + n * n + 2)


#: The Jumps task's declaration, registered by the platform (module docstring).
JUMPS = register_task(
    TaskSpec(
        name="jumps",
        title="Jumps",
        cls=JumpsTask,
        arguments=ARGUMENTS,
        action_text=(
            "``Jumps``: ``Box(-1, 1, (1,), float32)``, the jump probability per code period "
            "``p = 10 ** (lo + (a + 1) / 2 (hi - lo))`` with ``lo, hi = log10`` of "
            "``jump_range`` (default 1e-5 "
            "to 0.1) of every particle of the random Dirac-Gauss PF over the {dt:g} s step (Dirac-Gauss DPF "
            "n.d., §2.1; ``navgym.signal_tracking.task``); ``a = 0.1505`` (``p = 2e-3``) is the plain filter."
        ),
        argument_text=(
            "``Jumps``: ``n_particles=128``, ``jump_range=(1e-5, 0.1)`` (``(p_lo, p_hi)``, ``0 "
            "< p_lo <= 2e-3 <= "
            "p_hi <= 1``), ``ess_threshold=0.5``, ``clairvoyant=False`` (True, evaluation only: the knob set "
            "from the true jump steps, see the Description)"
        ),
        baseline="Jumps",
        clairvoyant=True,
        state_bytes=state_bytes,
        memory_arguments=("n_particles",),
    )
)

__all__ = ["JUMPS", "NOMINAL_JUMP_PROBABILITY", "JumpModel", "JumpsDiagnostics", "JumpsTask"]
