"""The RowScale task (v3): one measurement-noise multiplier per row and a process-noise scale.

A scalar knob cannot say "satellite 7 is bad": the per-row R of the truth-told filter is what
takes a v2 filter close to the clairvoyant (``experiments/knob_reach``), and only together with
the process noise of the motion. RowScale gives the agent both in one action of ``m_max + 1``
entries: for each measurement row ``i`` a multiplier ``s_i`` of its noise, and a scale ``s_q``
of the process noise of the platform's motion states (``Platform.process_noise_states``: the
velocity errors of GpsIns, the pose of Robot2d)::

    R'_ij = sqrt(s_i) R_ij sqrt(s_j)            (R' = S^1/2 R S^1/2, S = diag(s))
    Q'    = D Q D,  D = diag(sqrt(s_q) on the motion states, 1 elsewhere)

in the prediction and the update of any Gaussian filter of :mod:`filters.registry`. A diagonal
``R`` has each row's variance scaled by its own ``s_i``: the weighting of classical
receivers (C/N0 weighting, Hartinger & Brunner 1999; elevation weighting, RTKLIB E.6.24) is a
RowScale action, and ``s_i`` at its top (``1e4`` by default: a 100-fold sigma) all but excludes
a row, like a fault-exclusion test. Masked rows are ignored by the update whatever their scale.

``Box(-1, 1, (m_max + 1,))``, each scale log-mapped over its range ``[s_lo, s_hi]``:
``s = 10 ** (lo + (a + 1) / 2 (hi - lo))`` with ``lo, hi = log10 s_lo, log10 s_hi``; the first
``m_max`` entries are the rows' ``s_i`` (``r_scale_range``, default 0.3 to 1e4), the last is
``s_q`` (``q_scale_range``, default 0.1 to 1e4: the v2 GpsIns manoeuvres need about 100 times
the nominal velocity noise, which the v2 NoiseScale range 0.1 to 100 bound). The plain filter
is ``a = -1 + 2 (-lo) / (hi - lo)`` on every entry.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from filters import GaussianState
from navgym.envs.arguments import Argument, Integer, Interval, Reals
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels, TaskStep, TrueNoise
from navgym.envs.tasks.base import (
    CLAIRVOYANT,
    CLAIRVOYANT_TEXT,
    GaussianTask,
    clairvoyant_update,
    filter_argument,
    runnable_filters,
    truth_of,
)
from navgym.envs.tasks.noise_scale import SCALE_SNAP, motion_mask, scale_motion_q, scale_range
from navgym.envs.tasks.registry import TaskSpec, register_task

#: Default range ``(s_lo, s_hi)`` of a row's R multiplier: down to 0.3, up to exclusion (1e4).
ROW_SCALE_RANGE = (0.3, 1e4)
#: Default range of the motion states' process-noise scale ``s_q``.
PROCESS_SCALE_RANGE = (0.1, 1e4)


class RowScaleDiagnostics(NamedTuple):
    """The RowScale task's diagnostics of a step (keys of ``info``; they feed the features)."""

    r_scale: np.ndarray  #: (B, m_max) the applied row multipliers s_i
    q_scale: np.ndarray  #: (B,) the applied process-noise scale s_q


def _range_argument(name: str, default: tuple[float, float], what: str) -> Argument:
    return Argument(
        name,
        default,
        Interval(0.0, low_open=True),
        f"(s_lo, s_hi) of {what}, 0 < s_lo <= 1 <= s_hi, s_lo < s_hi, at most 1e12 wide",
        refused=((2.0, 10.0), (0.01, 0.5), (1.0, 1.0), (1e-7, 1e7)),
    )


#: The RowScale task's keyword arguments.
ARGUMENTS = (
    filter_argument("ekf"),
    _range_argument("r_scale_range", ROW_SCALE_RANGE, "each row's measurement-noise multiplier s_i"),
    _range_argument("q_scale_range", PROCESS_SCALE_RANGE, "the motion states' process-noise scale s_q"),
    CLAIRVOYANT,
    Argument(
        "regime_oracle",
        None,
        Reals(5, 0.0, low_open=True),
        "evaluation only: ignore the knob, set the scales from the step's true regime per row "
        "(s_nominal, s_noisy, s_biased, s_q_nominal, s_q_event)",
        opt_in=True,
    ),
)
#: A row is *noisy* when its true variance exceeds this multiple of the filter's ``R_ii``, and the
#: motion is in an *event* when a motion state's true process noise exceeds this multiple of ``Q``.
REGIME_RATIO = 2.0


def step_regimes(models: StepModels, process_states: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """The true regime of each row and of the motion at one step (read from ``StepModels.truth``).

    The classification of :meth:`RowScaleTask.regime_knob` (evaluation and supervised labels
    only: it reads truth). Per row, code ``2`` (*biased*) where the true mean error is not 0,
    else ``1`` (*noisy*) where the true variance exceeds :data:`REGIME_RATIO` times the filter's
    ``R_ii``, else ``0`` (*nominal*), whether or not the row was received; the motion is in an
    *event* where a state of ``process_states`` has a true process noise above
    :data:`REGIME_RATIO` times the filter's ``Q_ii``.

    Returns:
        ``(row (B, m_max) int64 codes in {0, 1, 2}, event (B,) bool)``.
    """
    truth = truth_of(models, "RowScale(regime_oracle=...)")
    R = np.asarray(models.observation.R)
    r_nom = np.diagonal(R, axis1=-2, axis2=-1)
    r_true = np.diagonal(truth.R, axis1=-2, axis2=-1)
    biased = np.asarray(truth.bias) != 0.0
    noisy = r_true > REGIME_RATIO * r_nom
    row = np.where(biased, 2, np.where(noisy, 1, 0))
    states = list(process_states)
    q_nom = np.diagonal(np.asarray(models.transition.Q), axis1=-2, axis2=-1)[..., states]
    q_true = np.diagonal(truth.Q, axis1=-2, axis2=-1)[..., states]
    event = np.asarray((q_true > REGIME_RATIO * q_nom).any(axis=-1))
    return row, event


class RowScaleTask(GaussianTask[RowScaleDiagnostics]):
    """One R multiplier per measurement row and a motion process-noise scale (module docstring).

    The knob is ``(B, m_max + 1)``: ``[s_1 .. s_m, s_q]``; ``R' = S^1/2 R S^1/2`` in the update,
    ``Q' = D Q D`` on ``process_states`` in the prediction. The observation carries the applied
    ``log10`` scales.
    """

    name = "RowScale"
    baseline_family = "RowScale"

    def __init__(
        self,
        filter: str = "ekf",
        r_scale_range: tuple[float, float] = ROW_SCALE_RANGE,
        q_scale_range: tuple[float, float] = PROCESS_SCALE_RANGE,
        m_max: int | None = None,
        process_states: tuple[int, ...] | None = None,
        n: int | None = None,
        clairvoyant: bool = False,
        regime_oracle: tuple[float, ...] | None = None,
    ) -> None:
        filt = self.gaussian_filter(filter)
        if m_max is None or process_states is None or n is None:
            raise ValueError(
                "RowScale needs the platform's m_max, n and process_noise_states (the rows and "
                "states of its knob); make it through an environment id or build_core"
            )
        self.m_max = Integer(1).check("m_max", m_max)
        n = Integer(1).check("n", n)
        states, on = motion_mask(process_states, n)
        #: The motion states whose process noise ``s_q`` scales.
        self.process_states = states
        self.r_scale_range = scale_range(ARGUMENTS[1], r_scale_range)
        self.q_scale_range = scale_range(ARGUMENTS[2], q_scale_range)
        super().__init__(filter, filt, clairvoyant, self.m_max + 1)
        if regime_oracle is not None and self.clairvoyant:
            raise ValueError("regime_oracle and clairvoyant are two references; take one")
        #: The regime oracle's table (``None``: the agent's knob; see :meth:`regime_knob`).
        self.regime_oracle = None if regime_oracle is None else np.asarray(ARGUMENTS[4].check(regime_oracle))
        if self.regime_oracle is not None:
            self.filter_name = filter + "/regime_oracle"
        self.action_space = spaces.Box(-1.0, 1.0, shape=(self.m_max + 1,), dtype=np.float32)
        #: ``(m_max + 1,)`` log10 bounds ``lo``, ``hi`` of ``[s_1 .. s_m, s_q]``.
        self.log_low = np.log10([self.r_scale_range[0]] * self.m_max + [self.q_scale_range[0]])
        self.log_high = np.log10([self.r_scale_range[1]] * self.m_max + [self.q_scale_range[1]])
        #: ``(n,)`` 1.0 on the motion states, 0.0 elsewhere.
        self._on = on

    def exponents(self, a: np.ndarray) -> np.ndarray:
        """``log10 [s_1 .. s_m, s_q]`` of actions ``a (B, m_max + 1)`` (within :data:`SCALE_SNAP` of 0: 0)."""
        e = self.log_low + (a + 1.0) / 2.0 * (self.log_high - self.log_low)
        return np.where(np.abs(e) < SCALE_SNAP, 0.0, e)

    def actions_of(self, scales: np.ndarray) -> np.ndarray:
        """The actions ``(B, m_max + 1)`` of scales ``[s_1 .. s_m, s_q]`` (clipped into range).

        The inverse of :meth:`knob_of`, for baselines that compute the scales themselves.
        """
        e = np.log10(np.clip(scales, 10.0**self.log_low, 10.0**self.log_high))
        return (-1.0 + 2.0 * (e - self.log_low) / (self.log_high - self.log_low)).astype(np.float32)

    def knob_of(self, a: np.ndarray) -> np.ndarray:
        """The scales ``[s_1 .. s_m, s_q]`` ``(B, m_max + 1)``."""
        return 10.0 ** self.exponents(a)

    def neutral_knob(self, B: int) -> np.ndarray:
        return np.ones((B, self.m_max + 1))

    def neutral_action(self) -> np.ndarray:
        """The action of every scale 1: ``-1 + 2 (-lo) / (hi - lo)`` per entry."""
        return (-1.0 + 2.0 * -self.log_low / (self.log_high - self.log_low)).astype(np.float32)

    def regime_knob(self, models: StepModels) -> np.ndarray:
        """The regime oracle's scales ``(B, m_max + 1)`` from the step's truth (evaluation only).

        Each row's regime, from ``StepModels.truth``: *biased* where its true mean error is not 0
        (multipath, NLOS, a gross error), else *noisy* where its true variance exceeds
        :data:`REGIME_RATIO` times the filter's ``R_ii`` (jamming, a canyon, low C/N0), else
        *nominal*; the motion is in an *event* where a motion state's true process noise exceeds
        :data:`REGIME_RATIO` times the filter's (a burst, slip). The table ``(s_nominal, s_noisy,
        s_biased, s_q_nominal, s_q_event)`` gives the scales. It reads truth: an upper reference
        of what a policy that recognizes the regimes could do (the v3 reach gate), never a
        baseline.
        """
        table = self.regime_oracle
        assert table is not None
        row, event = step_regimes(models, self.process_states)
        rows = table[:3][row]
        return np.column_stack([rows, np.where(event, table[4], table[3])])

    def step(
        self,
        state: GaussianState,
        knob: np.ndarray,
        models: StepModels,
        rngs: Sequence[np.random.Generator] | None,
    ) -> TaskStep[GaussianState, RowScaleDiagnostics]:
        """:meth:`GaussianTask.step`, with the regime oracle's scales in place of the knob if set."""
        if self.regime_oracle is not None:
            knob = self.regime_knob(models)
        return super().step(state, knob, models, rngs)

    def predict(
        self, state: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> GaussianState:
        if truth is not None:
            return super().predict(state, knob, models, truth)
        Q = scale_motion_q(models.transition.Q, self._on, knob[:, -1:])
        return self.filter.predict(state, models.transition, None, models.dt, Q=Q)  # may overflow: isolated

    def update(
        self, pred: GaussianState, knob: np.ndarray, models: StepModels, truth: TrueNoise | None
    ) -> tuple[GaussianState, Any, RowScaleDiagnostics]:
        if truth is not None:
            post, info = clairvoyant_update(self.filter, pred, models, truth)
        else:
            r = np.sqrt(knob[:, :-1])  # (B, m_max)
            R = r[:, :, None] * np.asarray(models.observation.R) * r[:, None, :]
            post, info = self.filter.update(pred, models.z, models.observation, mask=models.mask, R=R)
        return post, info, RowScaleDiagnostics(knob[:, :-1], knob[:, -1])

    def features(self) -> list[Feature]:
        return [
            Feature(
                "log_row_scale",
                float(self.log_low[0]),
                float(self.log_high[0]),
                "log10",
                "per row, log10 s_i, the applied multiplier of its measurement noise",
                self.m_max,
            ),
            Feature(
                "log_process_scale",
                float(self.log_low[-1]),
                float(self.log_high[-1]),
                "log10",
                "log10 s_q, the applied scale of the motion states' process noise",
            ),
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {"log_row_scale": np.zeros((B, self.m_max)), "log_process_scale": np.zeros(B)}

    def feature_values(self, step: TaskStep[GaussianState, RowScaleDiagnostics]) -> dict[str, np.ndarray]:
        return {
            "log_row_scale": np.log10(step.diagnostics.r_scale),
            "log_process_scale": np.log10(step.diagnostics.q_scale),
        }


#: The cards' paragraph on the baselines a RowScale agent must beat.
ROW_SCALE_BAR_TEXT = (
    "**The bar** (RowScale): the best of the tuned RowScale baselines (``navgym tune --episodes "
    "256`` on tuning seeds; the best tuning score): the plain filter, a constant, per-row chi-square "
    "exclusion, the per-row innovation-based R estimate (``row_iae``) and the context rules (C/N0 "
    "weighting, elevation weighting, a C/N0 mask with chi-square exclusion, the receiver's accuracy "
    "figure, each with an IMU threshold on the process noise) where the observation has their "
    "features. On the four v3 ids it is ``row_iae``; ``regime_oracle`` (gate G1) and "
    "``clairvoyant`` are references above it, never baselines."
)

#: The cards' Version History line of the RowScale ids.
ROW_SCALE_VERSION_HISTORY = """\
* v3 (RowScale): the v2 episodes with the platform's context (``context=True``: the receiver's
  report and the IMU statistics above, the fix noise following the simulated receiver), the
  RowScale knob (one noise multiplier per row and a process-noise scale), the v2 memory features
  and ``penalize_remaining_steps=True``.
"""

#: The RowScale task's declaration.
ROW_SCALE = register_task(
    TaskSpec(
        name="rowscale",
        title="RowScale",
        cls=RowScaleTask,
        arguments=ARGUMENTS,
        action_text=(
            "``RowScale``: ``Box(-1, 1, (m_max + 1,), float32)``, ``s = 10 ** (lo + (a + 1) / 2 (hi - lo))`` "
            "per entry: the first ``m_max`` are each measurement row's noise multiplier ``s_i`` "
            "(``r_scale_range``, default 0.3 to 1e4, wide enough to exclude a row), applied as "
            "``R' = S^1/2 R S^1/2``; the last is ``s_q`` (``q_scale_range``, default 0.1 to 1e4), applied "
            "as ``Q' = D Q D`` with ``D = sqrt(s_q)`` on the motion states (the platform's "
            "``process_noise_states``), every {dt:g} s step; "
            "``a = -1 + 2 (-lo) / (hi - lo)`` on every entry is the plain filter; masked rows are ignored."
        ),
        argument_text=(
            '``RowScale``: ``filter="ekf"`` (a Gaussian filter of :mod:`filters.registry` that runs on '
            "the platform's state size: {filters}), "
            "``r_scale_range=(0.3, 1e4)``, ``q_scale_range=(0.1, 1e4)`` (``(s_lo, s_hi)`` with "
            "``0 < s_lo <= 1 <= s_hi``), ``clairvoyant=False``, ``regime_oracle=None`` (evaluation only: "
            "five scales ``(s_nominal, s_noisy, s_biased, s_q_nominal, s_q_event)`` set from the step's true "
            "regime of each row and of the motion, the knob ignored; the v3 reach gate's upper reference)"
        ),
        baseline="RowScale",
        clairvoyant=True,
        card_note=CLAIRVOYANT_TEXT + " " + ROW_SCALE_BAR_TEXT,
        version_history=ROW_SCALE_VERSION_HISTORY,
        card_fields=lambda spec: {"filters": runnable_filters(spec, "rowscale")},
        platform_defaults=lambda spec, platform: {
            "m_max": platform.m_max,
            "n": platform.n,
            "process_states": platform.process_noise_states,
        },
    )
)
