"""The NoiseScale task (v2): the agent scales the filter's process and measurement noise each step.

``Q' = s_q Q`` in the prediction and ``R' = s_r R`` in the update of any Gaussian filter of
:mod:`filters.registry`, after Gao et al. 2020 (Remote Sensing 12:1704: a reinforcement learning
agent that sets the Q of a GNSS/INS Kalman filter). ``Box(-1, 1, (2,))``, each scale log-mapped
over its range ``[s_lo, s_hi]`` (default 0.1 to 100):
``s = 10 ** (lo + (a + 1) / 2 (hi - lo))`` with ``lo = log10 s_lo = -1``, ``hi = log10 s_hi = 2``;
the plain filter (``s = 1``) is ``a = -1 + 2 (-lo) / (hi - lo) = -1/3`` for the default range.

``motion_q=True`` (opt-in; the v2 ids scale the whole ``Q``) scales only the process noise of the
platform's motion states (``Platform.process_noise_states``, as RowScale's ``s_q``:
``Q' = D Q D`` with ``D = sqrt(s_q)`` on those states, 1 elsewhere), so that a large ``s_q``
opens the velocity block without inflating the sensor-bias states' noise. With ranges that do
not bind (``q_scale_range = r_scale_range = (0.1, 1e4)``) it is the NoiseScale knob of the v3
study (``experiments/knob_reach``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from navgym.envs.arguments import Argument, Flag, Interval
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels, TaskStep, TrueNoise
from navgym.envs.tasks.base import (
    CLAIRVOYANT,
    CLAIRVOYANT_TEXT,
    GaussianTask,
    clairvoyant_update,
    filter_argument,
    runnable_filters,
)
from navgym.envs.tasks.registry import TaskSpec, register_task

#: Widest range of a NoiseScale scale (and of the Robust task's threshold), in decades.
MAX_SCALE_DECADES = 12.0
#: A NoiseScale exponent ``log10 s`` this close to 0 is taken as 0 (``s = 1`` exactly): the
#: float32 neutral action (``-1/3`` rounded) maps to about ``-1.5e-8``.
SCALE_SNAP = 1e-6


class NoiseScaleDiagnostics(NamedTuple):
    """The NoiseScale task's diagnostics of a step (keys of ``info``; they feed the features)."""

    q_scale: np.ndarray  #: (B,) the applied s_q
    r_scale: np.ndarray  #: (B,) the applied s_r


def _scale_argument(name: str, what: str) -> Argument:
    return Argument(
        name,
        (0.1, 100.0),
        Interval(0.0, low_open=True),
        f"(s_lo, s_hi) of {what}, 0 < s_lo <= 1 <= s_hi, s_lo < s_hi, at most 1e12 wide",
        refused=((2.0, 10.0), (0.01, 0.5), (1.0, 1.0), (1e-7, 1e7)),
    )


#: The NoiseScale task's keyword arguments.
ARGUMENTS = (
    filter_argument("ekf"),
    _scale_argument("q_scale_range", "the process noise scale s_q"),
    _scale_argument("r_scale_range", "the measurement noise scale s_r"),
    CLAIRVOYANT,
    Argument(
        "motion_q",
        False,
        Flag(),
        "scale only the motion states' process noise (the platform's process_noise_states) by s_q",
        opt_in=True,
    ),
)


def scale_range(argument: Argument, value: Any) -> tuple[float, float]:
    """A NoiseScale range ``(s_lo, s_hi)`` (``ValueError`` naming the argument unless valid).

    ``0 < s_lo <= 1 <= s_hi``, ``s_lo < s_hi``, at most :data:`MAX_SCALE_DECADES` decades wide.
    """
    lo, hi = argument.check(value)
    if not (lo <= 1.0 <= hi and lo < hi and np.log10(hi / lo) <= MAX_SCALE_DECADES):
        raise ValueError(
            f"{argument.name} must be a pair (low, high) with 0 < low <= 1 <= high, low < high "
            "and high / low "
            f"<= 1e{MAX_SCALE_DECADES:g} (the plain filter, scale 1, is in range); got {value!r}"
        )
    return lo, hi


def motion_mask(process_states: Any, n: int) -> tuple[tuple[int, ...], np.ndarray]:
    """``(states, on)``: the checked motion states and ``on (n,)``, 1.0 on them, 0.0 elsewhere.

    Raises:
        ValueError: no state, a repeated one, or one outside ``[0, n - 1]``.
    """
    states = tuple(int(i) for i in process_states)
    if not states or any(not 0 <= i < n for i in states) or len(set(states)) != len(states):
        raise ValueError(f"process_states must be distinct states in [0, {n - 1}]; got {process_states!r}")
    on = np.zeros(int(n))
    on[list(states)] = 1.0
    return states, on


def scale_motion_q(Q: np.ndarray, on: np.ndarray, s_q: np.ndarray) -> np.ndarray:
    """``Q' = D Q D`` with ``D = diag(sqrt(s_q)`` on the motion states ``on``, 1 elsewhere).

    ``Q (n, n)`` or ``(B, n, n)``, ``s_q (B, 1)``: ``(B, n, n)``. A diagonal ``Q`` has its motion
    states' variances scaled by ``s_q`` and the others kept; their cross terms by ``sqrt(s_q)``.
    A shared ``Q`` is scaled on its nonzero entries only (a 15-state INS ``Q`` has 21 of 225).
    """
    d = 1.0 + on * (np.sqrt(s_q) - 1.0)  # (B, n)
    Q = np.asarray(Q)
    if Q.ndim == 2:  # one Q for the batch: its nonzero entries only (the rest stay exactly 0)
        i, j = np.nonzero(Q)
        out = np.zeros((d.shape[0], *Q.shape))
        out[:, i, j] = d[:, i] * Q[i, j] * d[:, j]  # the same products, in the same order
        return out
    return d[:, :, None] * Q * d[:, None, :]


class NoiseScaleTask(GaussianTask[NoiseScaleDiagnostics]):
    """The agent scales the filter's process and measurement noise each step (v2; module docstring).

    The knob is ``(B, 2)``: ``[s_q, s_r]``, applied as ``Q' = s_q Q`` in the prediction (with
    ``motion_q``: ``Q' = D Q D`` on ``process_states`` only) and ``R' = s_r R`` in the update of
    the Gaussian filter ``filter``; the observation carries the applied ``log10`` scales. After
    Gao et al. 2020 (Remote Sensing 12:1704), whose agent sets Q.
    """

    name = "NoiseScale"
    baseline_family = "NoiseScale"

    def __init__(
        self,
        filter: str = "ekf",
        q_scale_range: tuple[float, float] = (0.1, 100.0),
        r_scale_range: tuple[float, float] = (0.1, 100.0),
        clairvoyant: bool = False,
        motion_q: bool = False,
        process_states: tuple[int, ...] | None = None,
        n: int | None = None,
    ) -> None:
        filt = self.gaussian_filter(filter)
        self.motion_q = bool(ARGUMENTS[4].check(motion_q))
        #: ``(n,)`` 1.0 on the motion states ``s_q`` scales, 0.0 elsewhere (None: every state).
        self._on: np.ndarray | None = None
        if self.motion_q:
            if process_states is None or n is None:
                raise ValueError(
                    "motion_q=True needs the platform's n and process_noise_states; make the task "
                    "through an environment id or build_core"
                )
            _, self._on = motion_mask(process_states, int(n))
        self.q_scale_range = scale_range(ARGUMENTS[1], q_scale_range)
        self.r_scale_range = scale_range(ARGUMENTS[2], r_scale_range)
        super().__init__(filter, filt, clairvoyant, 2)
        #: ``(2,)`` log10 bounds ``lo``, ``hi`` of ``[s_q, s_r]``.
        self.log_low = np.log10([self.q_scale_range[0], self.r_scale_range[0]])
        self.log_high = np.log10([self.q_scale_range[1], self.r_scale_range[1]])

    def exponents(self, a: np.ndarray) -> np.ndarray:
        """``log10 [s_q, s_r]`` of actions ``a (B, 2)`` in [-1, 1] (within :data:`SCALE_SNAP` of 0: 0)."""
        e = self.log_low + (a + 1.0) / 2.0 * (self.log_high - self.log_low)
        return np.where(np.abs(e) < SCALE_SNAP, 0.0, e)

    def knob_of(self, a: np.ndarray) -> np.ndarray:
        """The scales ``[s_q, s_r]`` ``(B, 2)``."""
        return 10.0 ** self.exponents(a)

    def neutral_knob(self, B: int) -> np.ndarray:
        return np.ones((B, 2))

    def neutral_action(self) -> np.ndarray:
        """The action of ``s_q = s_r = 1``: ``-1 + 2 (-lo) / (hi - lo)`` (``-1/3`` for 0.1 to 100)."""
        return (-1.0 + 2.0 * -self.log_low / (self.log_high - self.log_low)).astype(np.float32)

    def predict(
        self, state: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> GaussianState:
        if truth is not None:
            return super().predict(state, knob, models, truth)
        if self._on is None:
            Q = knob[:, 0, None, None] * np.asarray(models.transition.Q)
        else:
            Q = scale_motion_q(models.transition.Q, self._on, knob[:, :1])
        return self.filter.predict(state, models.transition, None, models.dt, Q=Q)  # may overflow: isolated

    def update(
        self, pred: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> tuple[GaussianState, Any, NoiseScaleDiagnostics]:
        if truth is not None:
            post, info = clairvoyant_update(self.filter, pred, models, truth)
        else:
            R = knob[:, 1, None, None] * np.asarray(models.observation.R)
            post, info = self.filter.update(pred, models.z, models.observation, mask=models.mask, R=R)
        return post, info, NoiseScaleDiagnostics(knob[:, 0], knob[:, 1])

    def features(self) -> list[Feature]:
        (q_lo, r_lo), (q_hi, r_hi) = self.log_low, self.log_high
        return [
            Feature("log_q_scale", float(q_lo), float(q_hi), "log10", "log10 s_q, the applied scale of Q"),
            Feature("log_r_scale", float(r_lo), float(r_hi), "log10", "log10 s_r, the applied scale of R"),
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {"log_q_scale": np.zeros(B), "log_r_scale": np.zeros(B)}

    def feature_values(self, step: TaskStep[GaussianState, NoiseScaleDiagnostics]) -> dict[str, np.ndarray]:
        return {
            "log_q_scale": np.log10(step.diagnostics.q_scale),
            "log_r_scale": np.log10(step.diagnostics.r_scale),
        }


#: The NoiseScale task's declaration.
NOISE_SCALE = register_task(
    TaskSpec(
        name="noisescale",
        title="NoiseScale",
        cls=NoiseScaleTask,
        arguments=ARGUMENTS,
        action_text=(
            "``NoiseScale``: ``Box(-1, 1, (2,), float32)``, ``s = 10 ** (lo + (a + 1) / 2 (hi - lo))`` for "
            "``[s_q, s_r]`` with ``lo, hi = log10`` of ``q_scale_range`` / ``r_scale_range`` (default 0.1 to "
            "100: ``lo = -1``, ``hi = 2``), applied as ``Q' = s_q Q`` in the prediction and "
            "``R' = s_r R`` in "
            "the update of every {dt:g} s step (after Gao et al. 2020, Remote Sensing 12:1704); "
            "``a = -1 + 2 (-lo) / (hi - lo)`` (``-1/3`` by default) is the plain filter."
        ),
        argument_text=(
            '``NoiseScale``: ``filter="ekf"`` (a Gaussian filter of :mod:`filters.registry` that runs on '
            "the platform's state size: {filters}), "
            "``q_scale_range=(0.1, 100)``, ``r_scale_range=(0.1, 100)`` (``(s_lo, s_hi)`` with "
            "``0 < s_lo <= 1 <= s_hi``), ``clairvoyant=False``, ``motion_q=False`` (True: ``s_q`` scales "
            "only the motion states' process noise, the platform's ``process_noise_states``)"
        ),
        baseline="NoiseScale",
        clairvoyant=True,
        card_note=CLAIRVOYANT_TEXT,
        card_fields=lambda spec: {"filters": runnable_filters(spec, "noisescale")},
        platform_defaults=lambda spec, platform: {
            "n": platform.n,
            "process_states": platform.process_noise_states,
        },
    )
)
