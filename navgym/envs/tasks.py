"""What the agent controls, shared across platforms: fading, mixture weights, resampling.

A task owns the filter state, maps the agent's action to the filter's knob, runs one filter
step with that knob, and adds its own observation features and reward cost.

* :class:`FadingTask` — fading factor ``lambda >= 1`` of any Gaussian filter of
  :mod:`filters.registry`, applied at each prediction (``P- = lambda F P F^T + Q``; Benzerrouk
  2014, eq. 63-70, gives the classical formulas). Action ``a in [-1, 1]`` maps log-linearly:
  ``lambda = lambda_max ** ((a + 1) / 2)`` (``a = -1`` is the plain filter).
* :class:`MixtureTask` — prior weight ``eps`` of the outlier component of a two-component
  Gaussian-mixture measurement noise ``(1 - eps) N(0, R) + eps N(0, ratio R)`` (Benzerrouk
  2014, eq. 71) in a Gaussian-sum filter (eq. 72-76). ``eps = eps_max (a + 1) / 2``. With
  ``per_row=True`` (v2) one weight per measurement row, ``Box(-1, 1, (m_max,))``,
  ``eps_i = eps_max (a_i + 1) / 2`` on the platform's outlier rows (0 on the others), applied by
  the sequential per-row mixture update :func:`filters.row_mixture.update`; the observation then
  carries each row's posterior outlier weight.
* :class:`NoiseScaleTask` (v2) — scales of the filter's process and measurement noise,
  ``Q' = s_q Q`` in the prediction and ``R' = s_r R`` in the update of any Gaussian filter of
  :mod:`filters.registry`, after Gao et al. 2020 (Remote Sensing 12:1704: a reinforcement
  learning agent that sets the Q of a GNSS/INS Kalman filter). ``Box(-1, 1, (2,))``, each scale
  log-mapped over its range ``[s_lo, s_hi]`` (default 0.1 to 100):
  ``s = 10 ** (lo + (a + 1) / 2 (hi - lo))`` with ``lo = log10 s_lo = -1``, ``hi = log10 s_hi = 2``;
  the plain filter (``s = 1``) is ``a = -1 + 2 (-lo) / (hi - lo) = -1/3`` for the default range.
* :class:`RobustTask` (v2) — the threshold ``c`` of the robust iterated EKF of
  :func:`filters.robust.iterated_update` (Huber or Tukey weights of the whitened residuals,
  Belles et al. 2022, eq. 20, Algorithm 1). ``Box(-1, 1, (1,))``, log-mapped over
  ``threshold_range = (c_lo, c_hi)`` (default 0.5 to 1000):
  ``c = 10 ** (lo + (a + 1) / 2 (hi - lo))`` for ``a < 1`` and ``c = inf`` (weights 1: the plain
  iterated EKF) at ``a = 1``, the neutral action. An observation model that is an
  :class:`~navgym.envs.protocols.ErrorStateObservation` (the Jpa platform's DDs) is updated
  in error-state form (ESKF): the update runs on ``N(0, P-)`` with the model about the
  predicted mean, and ``inject`` resets the result into the mean (Belles et al. 2022,
  eq. 13-17).
* :class:`ResampleTask` — a bootstrap particle filter's decision to resample now
  (``Discrete(2)``), i.e. the particles as they stand after the last update (whose ESS the
  agent observes), before this step's prediction; each resampling costs ``resample_cost``.
  With ``roughening = K > 0`` the resampled particles are roughened (Gordon, Salmond & Smith
  1993: ``x_ij += K E_j N^(-1/n) e_ij``, ``E_j`` the spread of component j), so resampling both
  restores diversity and adds noise: the decision has a real trade-off.

**Clairvoyant reference** (``clairvoyant=True``; Fading, Mixture, NoiseScale, Robust; evaluation only):
the task ignores the agent's knob (reported as the neutral knob) and runs its plain filter with
the step's true noise of the platform (``StepModels.truth``, v2 platforms): ``Q = truth.Q`` in
the prediction, ``R = truth.R`` in the update and ``z - truth.bias`` as the measurement. It reads
truth: it is the upper reference of what a knob could achieve (like the hindsight oracle), never
a baseline, and its observations must not be trained on. A platform that gives no truth (the
v0/v1 platforms) makes its first step raise :class:`NoTruthError`.

**Actions** are checked by one function, :func:`check_action`, for every task: a Box action
must be an array of real numbers (no bools, complex numbers, strings or objects) of the batch
shape, finite; values outside the box are clipped and counted. A Discrete action must be an
integer in range (an integral float such as ``1.0`` names it too). Every rejection is a
``ValueError`` naming the action and the action space, raised before anything changes.

**Arguments** are checked at construction through :mod:`navgym.envs.arguments` (the error names
the argument, the value and the accepted range): ``lambda_max`` finite > 1; ``eps_max`` in
(0, 1); ``variance_ratio`` finite > 1; ``filter`` a key of :data:`filters.registry.FILTERS`;
``n_particles`` an integer in [1, :data:`MAX_PARTICLES`]; ``resample_cost`` finite >= 0;
``method`` a key of :data:`filters.core.resampling.RESAMPLERS`; ``roughening`` in [0,
:data:`MAX_ROUGHENING`]; ``log_ess_feature`` a bool; ``particle_dtype`` "float32" or "float64";
``q_scale_range`` and ``r_scale_range`` pairs ``(s_lo, s_hi)`` with ``0 < s_lo <= 1 <= s_hi``,
``s_lo < s_hi`` and ``s_hi / s_lo <= 10**`` :data:`MAX_SCALE_DECADES`; ``weight`` "huber" or
"tukey"; ``threshold_range`` a pair ``(c_lo, c_hi)`` with ``0 < c_lo < c_hi < inf`` and at most
:data:`MAX_SCALE_DECADES` decades; ``per_row`` and ``clairvoyant`` bools.

**Numerical failures.** A Gaussian task's prediction that overflows in some rows (a huge fading
factor on a grown covariance) would make the update reject the whole batch; those rows are
updated from their (finite) state before the prediction instead and reported in the step's
``extras["numerical_failure"]`` (B,), which the core turns into the end of their episodes
(see :mod:`navgym.envs.core`). The other rows' results do not change.
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from filters import GaussianState, gaussian_sum, kalman, robust, row_mixture
from filters import get as get_filter
from filters.core.resampling import RESAMPLERS
from filters.core.types import ParticleState, UpdateInfo
from filters.particle import bootstrap, estimates, regularization
from filters.particle.triggers import redistribution_trigger
from filters.registry import FILTERS
from navgym.envs import arguments
from navgym.envs.features import Feature
from navgym.envs.protocols import ErrorStateObservation, ReducibleObservation, StepModels, TaskStep
from navgym.envs.rows import replace_rows, take_rows
from navgym.signal_tracking.task import JumpsTask

#: Largest particle count of the Resample task: a batch holds B x N x n particle entries, so N is
#: bounded to keep one sub-env's cloud at most 10**6 particles (8 MB per state dimension).
MAX_PARTICLES = 10**6
#: Largest roughening constant K of the Resample task (Gordon, Salmond & Smith 1993 use K ~ 0.2;
#: beyond a few spreads the jitter swamps the cloud and the arithmetic degenerates).
MAX_ROUGHENING = 10.0
#: Widest range of a NoiseScale scale, in decades (``s_hi / s_lo``).
MAX_SCALE_DECADES = 12.0
#: A NoiseScale exponent ``log10 s`` this close to 0 is taken as 0 (``s = 1`` exactly): the
#: float32 neutral action (``-1/3`` rounded) maps to about ``-1.5e-8``.
SCALE_SNAP = 1e-6


class NoTruthError(ValueError):
    """A clairvoyant task stepped on a platform that gives no true noise (``StepModels.truth``)."""


def truth_of(models: StepModels, task: str) -> Any:
    """The step's true noise of ``models`` for the clairvoyant ``task`` (:class:`NoTruthError` if None)."""
    if models.truth is None:
        raise NoTruthError(
            f"{task}(clairvoyant=True) runs the filter with the step's true noise, but this platform "
            "gives none (StepModels.truth is None: only the v2 platforms fill it); the clairvoyant "
            "is an evaluation reference of the v2 ids"
        )
    return models.truth


def clairvoyant_step(filt: Any, state: GaussianState, models: StepModels, task: str):
    """The plain filter ``filt`` with the step's true noise: ``(pred, failed, post, info)``.

    ``Q = truth.Q`` in the prediction, ``R = truth.R`` in the update, ``z - truth.bias`` as the
    measurement (evaluation only: it reads truth).
    """
    truth = truth_of(models, task)
    pred = filt.predict(state, models.transition, None, models.dt, Q=truth.Q)
    pred, failed = _isolate_nonfinite(pred, state)
    z = np.asarray(models.z) - np.asarray(truth.bias)
    post, info = filt.update(pred, z, models.observation, mask=models.mask, R=truth.R)
    return pred, failed, post, info


def _shown(action: Any, limit: int = 120) -> str:
    text = repr(action)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def check_action(action: Any, space: spaces.Space, B: int) -> tuple[np.ndarray, np.ndarray]:
    """A batch of ``B`` actions of ``space``, validated: ``(values, clipped)``.

    Box: ``values (B, dim)`` float64 clipped into the box and ``clipped (B,)`` where a row was
    outside it. Discrete: ``values (B,)`` int64 and ``clipped`` all False. Accepted shapes are
    ``(B, *space.shape)``, and ``(B,)`` or ``(B, 1)`` when an action is one number.

    Raises:
        ValueError: naming the action and the space, for anything else: not an array of real
            numbers (bools, complex numbers, strings, objects), a wrong shape, NaN or inf, a
            Discrete action that is not an integer of the space.
    """

    def reject(why: str) -> ValueError:
        # formatted on error only: the space's repr costs more than the checks of a valid action
        where = f"the action space {space}" + (f" (batched over {B} sub-environments)" if B > 1 else "")
        return ValueError(f"action {_shown(action)} is not an action of {where}: {why}")

    try:
        a = np.asarray(action)
    except (TypeError, ValueError) as exc:  # ragged nested sequences
        raise reject(f"not an array of numbers ({exc})") from None
    if a.dtype.kind == "b":
        raise reject("bools are not actions (pass numbers)")
    if a.dtype.kind not in "iuf":
        raise reject(f"an action must consist of real numbers; got dtype {a.dtype}")
    shape = tuple(space.shape or ())
    dim = 1  # the product of the shape (np.prod costs ~5 us per call)
    for k in shape:
        dim *= int(k)
    accepted = [(B, *shape)] + ([(B,), (B, 1)] if dim == 1 else [])
    if a.shape not in accepted:
        want = " or ".join(str(s) for s in dict.fromkeys(accepted))
        raise reject(f"shape {a.shape}, expected {want}")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise reject("it must be finite (got NaN or inf)")
    if isinstance(space, spaces.Discrete):
        lo, n = int(space.start), int(space.n)
        what = "0 or 1" if (lo, n) == (0, 2) else f"an integer in [{lo}, {lo + n - 1}]"
        if a.dtype.kind == "f" and (a != np.round(a)).any():  # 0.9 would silently mean 0
            raise reject(f"it must be {what} (an integer)")
        if ((a < lo) | (a > lo + n - 1)).any():
            raise reject(f"it must be {what}")
        return a.reshape(B).astype(np.int64), np.zeros(B, dtype=bool)
    low = np.asarray(space.low, dtype=np.float64).reshape(dim)
    high = np.asarray(space.high, dtype=np.float64).reshape(dim)
    x = a.astype(np.float64).reshape(B, dim)
    with np.errstate(over="ignore"):  # a float128 beyond float64 becomes inf, then the bound
        clipped = ((x < low) | (x > high)).any(axis=1)
    return np.minimum(np.maximum(x, low), high), clipped  # np.clip's values (x is finite)


def _isolate_nonfinite(pred: GaussianState, before: GaussianState) -> tuple[GaussianState, np.ndarray]:
    """``pred`` with its failed rows replaced by ``before``'s, and which rows those were.

    A row has failed when an entry is not finite or its entries are so large that their sum
    overflows (a covariance near the float range, which the update could only turn into inf).
    """
    B = pred.m.shape[0]
    with np.errstate(over="ignore", invalid="ignore"):
        bad = ~(np.isfinite(pred.m.sum(axis=1)) & np.isfinite(pred.P.reshape(B, -1).sum(axis=1)))
    if bad.any():
        rows = np.flatnonzero(bad)
        pred = replace_rows(pred, rows, take_rows(before, rows))
    return pred, bad


class FadingTask:
    """The agent sets the fading factor of a Gaussian filter each step."""

    name = "Fading"

    def __init__(
        self,
        filter: str = "ekf",  # noqa: A002
        lambda_max: float = 10.0,
        clairvoyant: bool = False,
    ) -> None:
        self.filter_name = arguments.choice("filter", filter, FILTERS)
        self.filter = get_filter(filter)
        self.lambda_max = arguments.real("lambda_max", lambda_max, 1.0, low_open=True)
        #: Evaluation only: ignore the knob, run the plain filter with the true noise (module docstring).
        self.clairvoyant = arguments.flag("clairvoyant", clairvoyant)
        if self.clairvoyant:
            self.filter_name += "/clairvoyant"
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        a, clipped = check_action(action, self.action_space, B)
        if self.clairvoyant:
            return np.ones(B), clipped
        return self.lambda_max ** ((a[:, 0] + 1.0) / 2.0), clipped

    def neutral_action(self) -> np.ndarray:
        return np.array([-1.0], dtype=np.float32)

    def init_state(self, belief: GaussianState, rngs: Sequence[np.random.Generator]) -> GaussianState:
        return belief

    def step(self, state: GaussianState, knob: np.ndarray, models: StepModels, rngs) -> TaskStep:
        if self.clairvoyant:
            pred, failed, post, info = clairvoyant_step(self.filter, state, models, "FadingTask")
            H = None
        else:
            pred = self.filter.predict(state, models.transition, None, models.dt, fading=knob)
            pred, failed = _isolate_nonfinite(pred, state)  # overflow of lambda F P F^T
            H = models.observation.H(pred.m)  # once: for the update and for the traces
            observation = JacobianAt(models.observation, pred.m, H)
            post, info = self.filter.update(pred, models.z, observation, mask=models.mask)
        extras = {"fading": knob, **fading_traces(pred, info, models, knob, H)}
        if failed.any():
            info = info._replace(healthy=np.asarray(info.healthy) & ~failed)
            extras["numerical_failure"] = failed
        return TaskStep(post, post, info, pred.P, np.zeros(len(knob)), extras)

    def features(self) -> list[Feature]:
        return [
            Feature(name, -8.0, 12.0, "log10", text)
            for name, text in (
                ("log_tr_vv", "log10 |v|^2 over the rows used (innovation energy)"),
                ("log_tr_R", "log10 tr R over the rows used"),
                ("log_tr_HQH", "log10 tr(H Q H^T) over the rows used (Benzerrouk 2014, eq. 68)"),
                ("log_tr_M", "log10 tr(H F P F^T H^T) over the rows used (Benzerrouk 2014, eq. 69)"),
            )
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {f.name: np.zeros(B) for f in self.features()}

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        return {
            k: np.log10(np.maximum(step.extras[k[4:]], 1e-8))
            for k in ("log_tr_vv", "log_tr_R", "log_tr_HQH", "log_tr_M")
        }


class JacobianAt:
    """An observation model whose Jacobian at the point ``x`` is already known.

    ``H(x)`` returns the given Jacobian for that very array (``x is self.x``) and asks the model
    otherwise; every other attribute is the model's. The fading task evaluates ``H`` at the
    predicted mean once, for the EKF update and for the traces of :func:`fading_traces`.
    """

    def __init__(self, model: Any, x: np.ndarray, H: np.ndarray) -> None:
        self.model, self.x, self.H_x = model, x, H

    def H(self, x: np.ndarray) -> np.ndarray:
        return self.H_x if x is self.x else self.model.H(x)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.model, name)


def fading_traces(
    pred: GaussianState, info, models: StepModels, lam: np.ndarray, H: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """Traces over the used rows that the classical fading formulas need (Benzerrouk 2014, eq. 67-70).

    ``tr_vv = |v|^2``, ``tr_R``, ``tr_HQH = tr(H Q H^T)`` with ``H`` the observation Jacobian at
    the predicted mean, and ``tr_M = tr(H F P F^T H^T) = (tr S - tr R - tr HQH) / lambda`` from
    the innovation covariance ``S = H (lambda F P F^T + Q) H^T + R`` of the applied factor. A
    baseline keeps its own ``V_k`` recursion on ``tr_vv`` (traces are linear), so these four
    numbers per step are all the formulas need; they are published in the observation. ``H``,
    when given, is that Jacobian (else it is evaluated).
    """
    w = models.mask.astype(np.float64)
    R = np.broadcast_to(models.observation.R, info.S.shape)
    tr_R = np.einsum("bii,bi->b", R, w)
    B, m, n = w.shape[0], w.shape[1], pred.m.shape[1]
    H = np.broadcast_to(models.observation.H(pred.m) if H is None else H, (B, m, n))
    Q = np.asarray(models.transition.Q)
    HQ = (H.reshape(B * m, n) @ Q).reshape(B, m, n) if Q.ndim == 2 else H @ Q
    tr_HQH = np.einsum("bjk,bjk,bj->b", HQ, H, w)
    tr_S = np.einsum("bii,bi->b", info.S, w)
    tr_M = np.maximum(tr_S - tr_R - tr_HQH, 0.0) / lam
    return {"tr_vv": (info.innovation**2 * w).sum(axis=1), "tr_R": tr_R, "tr_HQH": tr_HQH, "tr_M": tr_M}


class MixtureTask:
    """The agent sets the outlier weight of a Gaussian-sum filter's noise mixture each step.

    One weight for every outlier row (v0/v1), or one per row with ``per_row=True`` (v2; needs the
    platform's ``m_max``).
    """

    name = "Mixture"

    def __init__(
        self,
        filter: str = "ckf",  # noqa: A002
        eps_max: float = 0.5,
        variance_ratio: float = 100.0,
        outlier_rows: tuple[int, ...] | None = None,
        per_row: bool = False,
        m_max: int | None = None,
        clairvoyant: bool = False,
    ) -> None:
        self.filter_name = arguments.choice("filter", filter, FILTERS)
        self.base = get_filter(filter)
        self.eps_max = arguments.real("eps_max", eps_max, 0.0, 1.0, low_open=True, high_open=True)
        self.variance_ratio = arguments.real("variance_ratio", variance_ratio, 1.0, low_open=True)
        #: Rows subject to impulsive noise, the platform's ``outlier_rows`` (None: every row).
        self.outlier_rows = None if outlier_rows is None else tuple(int(r) for r in outlier_rows)
        #: One weight per measurement row (v2), applied by :func:`filters.row_mixture.update`.
        self.per_row = arguments.flag("per_row", per_row)
        #: Evaluation only: ignore the knob, run the plain filter with the true noise (module docstring).
        self.clairvoyant = arguments.flag("clairvoyant", clairvoyant)
        if self.clairvoyant:
            self.filter_name += "/clairvoyant"
        self.m_max: int | None = None
        if self.per_row:
            if m_max is None:
                raise ValueError("per_row=True needs the platform's m_max (the rows of the action)")
            self.m_max = arguments.integer("m_max", m_max, 1)
            rows = range(self.m_max) if self.outlier_rows is None else self.outlier_rows
            if any(not 0 <= r < self.m_max for r in rows):
                raise ValueError(f"outlier_rows must lie in [0, {self.m_max - 1}]; got {self.outlier_rows}")
            #: (m_max,) 1.0 on the outlier rows, 0.0 elsewhere (their weight is always 0).
            self.row_weights = np.zeros(self.m_max)
            self.row_weights[list(rows)] = 1.0
            self.action_space = spaces.Box(-1.0, 1.0, shape=(self.m_max,), dtype=np.float32)
        else:
            self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        """``eps (B,)``, or ``(B, m_max)`` per row (0 on the rows that are not outlier rows)."""
        a, clipped = check_action(action, self.action_space, B)
        if self.per_row:
            eps = self.eps_max * (a + 1.0) / 2.0 * self.row_weights
            return (np.zeros_like(eps) if self.clairvoyant else eps), clipped
        if self.clairvoyant:
            return np.zeros(B), clipped
        return self.eps_max * (a[:, 0] + 1.0) / 2.0, clipped

    def neutral_action(self) -> np.ndarray:
        return np.full(self.action_space.shape, -1.0, dtype=np.float32)

    def init_state(self, belief: GaussianState, rngs) -> GaussianState:
        return belief

    def step(self, state: GaussianState, knob: np.ndarray, models: StepModels, rngs) -> TaskStep:
        B = len(knob)
        if self.clairvoyant:
            pred, failed, post, info = clairvoyant_step(self.base, state, models, "MixtureTask")
            outlier_posterior = np.zeros(knob.shape)
        else:
            pred = self.base.predict(state, models.transition, None, models.dt)
            pred, failed = _isolate_nonfinite(pred, state)
            if self.per_row:
                post, info = row_mixture.update(
                    pred,
                    models.z,
                    models.observation,
                    models.mask,
                    eps=knob,
                    variance_ratio=self.variance_ratio,
                    base=self.base,
                )
                outlier_posterior = np.where(models.mask, info.outlier_posterior, 0.0)
            else:
                R = np.asarray(models.observation.R)  # (m, m) shared or (B, m, m)
                # The outlier component inflates the rows the platform declares as impulsive (default:
                # all): R2 = D R D with D = sqrt(ratio) on those rows, 1 elsewhere (Benzerrouk 2014,
                # eq. 71 per row).
                d = np.ones(R.shape[-1])
                rows = self.outlier_rows
                d[slice(None) if rows is None else list(rows)] = np.sqrt(self.variance_ratio)
                # (K, m, m) when R is shared by the batch (no per-step (B, K, m, m) copy), else (B, K, m, m)
                R_components = np.stack([R, d[:, None] * R * d[None, :]], axis=-3)
                weights = np.stack([1.0 - knob, knob], axis=1)
                post, info = gaussian_sum.update(
                    pred,
                    models.z,
                    models.observation,
                    models.mask,
                    R_components=R_components,
                    weights=weights,
                    base=self.base,
                )
                outlier_posterior = np.exp(info.log_weights[:, 1])
        extras = {"eps": knob, "outlier_posterior": outlier_posterior}
        if failed.any():
            info = info._replace(healthy=np.asarray(info.healthy) & ~failed)
            extras["numerical_failure"] = failed
        return TaskStep(post, post, info, pred.P, np.zeros(B), extras)

    def features(self) -> list[Feature]:
        if self.per_row:
            return [
                Feature(
                    "outlier_posterior",
                    0.0,
                    1.0,
                    "-",
                    "per row, posterior weight of its outlier noise component (eq. 74; 0 on rows "
                    "not received)",
                    self.m_max or 1,
                )
            ]
        return [
            Feature(
                "outlier_posterior", 0.0, 1.0, "-", "posterior weight of the outlier noise component (eq. 74)"
            )
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {"outlier_posterior": np.zeros((B, self.m_max) if self.per_row else B)}

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        return {"outlier_posterior": step.extras["outlier_posterior"]}


class NoiseScaleTask:
    """The agent scales the filter's process and measurement noise each step (v2; module docstring).

    The knob is ``(B, 2)``: ``[s_q, s_r]``, applied as ``Q' = s_q Q`` in the prediction and
    ``R' = s_r R`` in the update of the Gaussian filter ``filter``; the observation carries the
    applied ``log10`` scales. After Gao et al. 2020 (Remote Sensing 12:1704), whose agent sets Q.
    """

    name = "NoiseScale"

    def __init__(
        self,
        filter: str = "ekf",  # noqa: A002
        q_scale_range: tuple[float, float] = (0.1, 100.0),
        r_scale_range: tuple[float, float] = (0.1, 100.0),
        clairvoyant: bool = False,
    ) -> None:
        self.filter_name = arguments.choice("filter", filter, FILTERS)
        self.filter = get_filter(filter)
        self.q_scale_range = _scale_range("q_scale_range", q_scale_range)
        self.r_scale_range = _scale_range("r_scale_range", r_scale_range)
        #: Evaluation only: ignore the knob, run the plain filter with the true noise (module docstring).
        self.clairvoyant = arguments.flag("clairvoyant", clairvoyant)
        if self.clairvoyant:
            self.filter_name += "/clairvoyant"
        #: ``(2,)`` log10 bounds ``lo``, ``hi`` of ``[s_q, s_r]``.
        self.log_low = np.log10([self.q_scale_range[0], self.r_scale_range[0]])
        self.log_high = np.log10([self.q_scale_range[1], self.r_scale_range[1]])
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)

    def exponents(self, a: np.ndarray) -> np.ndarray:
        """``log10 [s_q, s_r]`` of actions ``a (B, 2)`` in [-1, 1] (within :data:`SCALE_SNAP` of 0: 0)."""
        e = self.log_low + (a + 1.0) / 2.0 * (self.log_high - self.log_low)
        return np.where(np.abs(e) < SCALE_SNAP, 0.0, e)

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        """The scales ``[s_q, s_r]`` ``(B, 2)`` (ones under the clairvoyant)."""
        a, clipped = check_action(action, self.action_space, B)
        if self.clairvoyant:
            return np.ones((B, 2)), clipped
        return 10.0 ** self.exponents(a), clipped

    def neutral_action(self) -> np.ndarray:
        """The action of ``s_q = s_r = 1``: ``-1 + 2 (-lo) / (hi - lo)`` (``-1/3`` for 0.1 to 100)."""
        return (-1.0 + 2.0 * -self.log_low / (self.log_high - self.log_low)).astype(np.float32)

    def init_state(self, belief: GaussianState, rngs) -> GaussianState:
        return belief

    def step(self, state: GaussianState, knob: np.ndarray, models: StepModels, rngs) -> TaskStep:
        B = knob.shape[0]
        if self.clairvoyant:
            pred, failed, post, info = clairvoyant_step(self.filter, state, models, "NoiseScaleTask")
        else:
            Q = knob[:, 0, None, None] * np.asarray(models.transition.Q)
            pred = self.filter.predict(state, models.transition, None, models.dt, Q=Q)
            pred, failed = _isolate_nonfinite(pred, state)  # overflow of a huge s_q Q
            R = knob[:, 1, None, None] * np.asarray(models.observation.R)
            post, info = self.filter.update(pred, models.z, models.observation, mask=models.mask, R=R)
        extras = {"q_scale": knob[:, 0], "r_scale": knob[:, 1]}
        if failed.any():
            info = info._replace(healthy=np.asarray(info.healthy) & ~failed)
            extras["numerical_failure"] = failed
        return TaskStep(post, post, info, pred.P, np.zeros(B), extras)

    def features(self) -> list[Feature]:
        (q_lo, r_lo), (q_hi, r_hi) = self.log_low, self.log_high
        return [
            Feature("log_q_scale", float(q_lo), float(q_hi), "log10", "log10 s_q, the applied scale of Q"),
            Feature("log_r_scale", float(r_lo), float(r_hi), "log10", "log10 s_r, the applied scale of R"),
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {"log_q_scale": np.zeros(B), "log_r_scale": np.zeros(B)}

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        return {
            "log_q_scale": np.log10(step.extras["q_scale"]),
            "log_r_scale": np.log10(step.extras["r_scale"]),
        }


def _scale_range(name: str, value: Any) -> tuple[float, float]:
    """A NoiseScale range ``(s_lo, s_hi)`` (``ValueError`` naming ``name`` unless valid).

    ``0 < s_lo <= 1 <= s_hi``, ``s_lo < s_hi``, at most :data:`MAX_SCALE_DECADES` decades wide.
    """
    lo, hi = arguments.interval(name, value, 0.0, low_open=True)
    if not (lo <= 1.0 <= hi and lo < hi and np.log10(hi / lo) <= MAX_SCALE_DECADES):
        raise ValueError(
            f"{name} must be a pair (low, high) with 0 < low <= 1 <= high, low < high and high / low "
            f"<= 1e{MAX_SCALE_DECADES:g} (the plain filter, scale 1, is in range); got {value!r}"
        )
    return lo, hi


#: The Robust task's weight functions (:data:`filters.robust.WEIGHT_FUNCTIONS`).
ROBUST_WEIGHTS = ("huber", "tukey")


class RobustTask:
    """The agent sets the robust threshold of an iterated EKF / ESKF each step (v2; module docstring).

    The knob ``c (B,)`` goes to :func:`filters.robust.iterated_update` (Algorithm 1 of Belles et
    al. 2022: ``W = diag w(R^{-1/2} (z - h(x)))``, Huber ``w = min(1, c / |e|)`` or Tukey
    ``w = (1 - (e / c)^2)^2`` inside ``|e| < c``, reweighted until no weight moves more than
    ``tol``); ``c = inf`` is the plain iterated EKF. The observation carries ``log10 c`` and the
    mean and smallest weight of the last update.
    """

    name = "Robust"

    def __init__(
        self,
        weight: str = "huber",
        threshold_range: tuple[float, float] = (0.5, 1000.0),
        clairvoyant: bool = False,
        max_iter: int = 5,
        tol: float = 1e-3,
        max_inner: int = 3,
    ) -> None:
        self.weight = arguments.choice("weight", weight, ROBUST_WEIGHTS)
        #: Gauss-Newton steps per weighting (the attitude is the only nonlinearity; 3 reach 1e-6).
        self.max_inner = arguments.integer("max_inner", max_inner, 1, 100)
        lo, hi = arguments.interval("threshold_range", threshold_range, 0.0, low_open=True)
        if not (lo < hi and np.isfinite(hi) and np.log10(hi / lo) <= MAX_SCALE_DECADES):
            raise ValueError(
                f"threshold_range must be a pair (low, high) with 0 < low < high < inf and high / low "
                f"<= 1e{MAX_SCALE_DECADES:g}; got {threshold_range!r}"
            )
        self.threshold_range = (lo, hi)
        self.max_iter = arguments.integer("max_iter", max_iter, 1, 100)
        self.tol = arguments.real("tol", tol, 0.0, 1.0)
        #: Evaluation only: ignore the knob, run the plain filter with the true noise (module docstring).
        self.clairvoyant = arguments.flag("clairvoyant", clairvoyant)
        self.filter_name = f"iekf/{self.weight}" + ("/clairvoyant" if self.clairvoyant else "")
        self.log_low, self.log_high = float(np.log10(lo)), float(np.log10(hi))
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    def thresholds(self, a: np.ndarray) -> np.ndarray:
        """``c (B,)`` of actions ``a (B,)`` in [-1, 1]: log-mapped, ``inf`` at ``a = 1``."""
        c = 10.0 ** (self.log_low + (a + 1.0) / 2.0 * (self.log_high - self.log_low))
        return np.where(a >= 1.0, np.inf, c)

    def action_of(self, c: np.ndarray | float) -> np.ndarray:
        """The action ``(..., 1)`` float32 of thresholds ``c`` (``inf`` or beyond ``c_hi``: 1)."""
        c = np.asarray(c, np.float64)
        with np.errstate(divide="ignore"):
            a = -1.0 + 2.0 * (np.log10(np.clip(c, *self.threshold_range)) - self.log_low) / (
                self.log_high - self.log_low
            )
        a = np.where(c >= self.threshold_range[1], 1.0, np.clip(a, -1.0, 1.0))
        return a.astype(np.float32)[..., None]

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        a, clipped = check_action(action, self.action_space, B)
        if self.clairvoyant:
            return np.full(B, np.inf), clipped
        return self.thresholds(a[:, 0]), clipped

    def neutral_action(self) -> np.ndarray:
        """``a = 1``: ``c = inf``, the plain iterated EKF."""
        return np.array([1.0], dtype=np.float32)

    def init_state(self, belief: GaussianState, rngs) -> GaussianState:
        return belief

    def step(self, state: GaussianState, knob: np.ndarray, models: StepModels, rngs) -> TaskStep:
        B = knob.shape[0]
        z, Q, R = models.z, None, None
        if self.clairvoyant:
            truth = truth_of(models, "RobustTask")
            z, Q, R = np.asarray(models.z) - np.asarray(truth.bias), truth.Q, truth.R
        pred = kalman.predict(state, models.transition, None, models.dt, Q=Q)
        pred, failed = _isolate_nonfinite(pred, state)
        obs = models.observation
        eskf = isinstance(obs, ErrorStateObservation)
        prior = GaussianState(np.zeros_like(pred.m), pred.P) if eskf else pred
        model = obs.error_state(pred.m) if eskf else obs
        post, info = robust.iterated_update(
            prior,
            z,
            model,
            models.mask,
            R,
            threshold=knob,
            weight=self.weight,
            max_iter=self.max_iter,
            tol=self.tol,
            max_inner=self.max_inner,
            inner_tol=1e-6,
        )
        if eskf:
            post = GaussianState(*obs.inject(pred.m, post.m, post.P))
        n = np.maximum(models.mask.sum(axis=1), 1)
        extras = {
            "threshold": knob,
            "mean_weight": np.where(models.mask, info.weights, 0.0).sum(axis=1) / n,
            "min_weight": np.where(models.mask, info.weights, 1.0).min(axis=1),
        }
        if failed.any():
            info = info._replace(healthy=np.asarray(info.healthy) & ~failed)
            extras["numerical_failure"] = failed
        return TaskStep(post, post, info, pred.P, np.zeros(B), extras)

    def features(self) -> list[Feature]:
        return [
            Feature(
                "log_threshold",
                self.log_low,
                self.log_high,
                "log10",
                "log10 c, the applied threshold (inf: the top)",
            ),
            Feature("mean_weight", 0.0, 1.0, "-", "mean robust weight of the rows used in the last update"),
            Feature("min_weight", 0.0, 1.0, "-", "smallest robust weight of the last update"),
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        ones = np.ones(B)
        return {"log_threshold": np.full(B, self.log_high), "mean_weight": ones, "min_weight": ones.copy()}

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        c = np.minimum(step.extras["threshold"], 10.0**self.log_high)
        return {
            "log_threshold": np.log10(c),
            "mean_weight": step.extras["mean_weight"],
            "min_weight": step.extras["min_weight"],
        }


class ParticleBelief(NamedTuple):
    """Particle filter state plus the resampling count of the episode."""

    particles: Any  # ParticleState
    resamples: np.ndarray  # (B,) resamplings so far


class ResampleTask:
    """The agent decides when a bootstrap particle filter resamples; each resampling costs."""

    name = "Resample"

    def __init__(
        self,
        n_particles: int = 1000,
        resample_cost: float = 0.05,
        method: str = "systematic",
        roughening: float = 0.0,
        log_ess_feature: bool = False,
        particle_dtype: str = "float32",
    ) -> None:
        if isinstance(particle_dtype, np.dtype) or (
            isinstance(particle_dtype, type) and issubclass(particle_dtype, np.generic)
        ):
            particle_dtype = np.dtype(particle_dtype).name  # as ``options`` gives it back
        particle_dtype = arguments.choice("particle_dtype", particle_dtype, ("float32", "float64"))
        n_particles = arguments.integer("n_particles", n_particles, 1, MAX_PARTICLES)
        resample_cost = arguments.real("resample_cost", resample_cost, 0.0)
        method = arguments.choice("method", method, RESAMPLERS)
        roughening = arguments.real("roughening", roughening, 0.0, MAX_ROUGHENING)
        log_ess_feature = arguments.flag("log_ess_feature", log_ess_feature)
        self.filter_name = (
            f"pf{n_particles}"
            + ("/f32" if particle_dtype == "float32" else "")
            + (f"+rough{roughening:g}" if roughening else "")
        )
        self.n_particles = n_particles
        self.resample_cost = resample_cost
        self.method = method
        #: Roughening constant K of Gordon, Salmond & Smith (1993) applied after each resampling
        #: (0: none). Without it a filter whose states carry almost no process noise (Carvalho et al. 1997's
        #: INS errors) collapses onto a few distinct particles at every resampling.
        self.roughening = float(roughening)
        #: Also observe ``log10(ESS / N)`` (in ``[-log10 N, 0]``): the collapsed-cloud range
        #: (ESS/N of 1e-3 vs 1e-2) is invisible in the linear ``ess_frac`` once standardized.
        self.log_ess_feature = bool(log_ess_feature)
        #: Precision of the particle cloud (weights, moments and diagnostics stay float64).
        #: float32 halves the memory traffic of every pass over the B x N particles; pseudo-range
        #: models are weighed "observed minus computed" (their ``reduced``), so no innovation
        #: precision is lost.
        self.particle_dtype = np.dtype(particle_dtype)
        self.action_space = spaces.Discrete(2)

    @property
    def options(self) -> dict[str, Any]:
        """The keyword arguments that rebuild this task (every parameter of ``__init__``)."""
        names = [p for p in inspect.signature(ResampleTask.__init__).parameters if p != "self"]
        return {p: getattr(self, p) for p in names}

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        d, clipped = check_action(action, self.action_space, B)
        return d.astype(bool), clipped

    def neutral_action(self) -> np.ndarray:
        return np.array(0, dtype=np.int64)

    def init_state(self, belief: GaussianState, rngs) -> ParticleBelief:
        # "structure of arrays": every element-wise pass of the filter runs along the particles
        particles = bootstrap.from_gaussian(belief.m, belief.P, self.n_particles, list(rngs), layout="soa")
        particles = particles._replace(x=particles.x.astype(self.particle_dtype))  # keeps the layout
        return ParticleBelief(particles, np.zeros(belief.m.shape[0]))

    def step(self, state: ParticleBelief, knob: np.ndarray, models: StepModels, rngs) -> TaskStep:
        rngs = list(rngs)
        # "Resample now": the decision applies to the particles as the agent last saw them
        # (after the previous update, whose ESS is in the observation), then predict + update.
        particles = bootstrap.resample(state.particles, knob, rngs, self.method)
        if self.roughening > 0:
            particles = regularization.roughen(particles, rngs, K=self.roughening, decision=knob)
        post, info = self.filter_step(particles, models, rngs)
        info = info._replace(resampled=knob)
        belief = estimates.mean_and_covariance(post)
        n_eff = info.ess / self.n_particles
        tiny = redistribution_trigger(post.log_w)
        cost = self.resample_cost * knob.astype(np.float64)
        new = ParticleBelief(post, state.resamples + knob)
        extras = {
            "ess_frac": n_eff,
            "resampled": knob,
            "redistribution_rule": tiny,
            "resamples": new.resamples,
        }
        # The predicted particle covariance is not computed (one more weighted covariance pass
        # over B x N particles); particle tasks publish no info["predicted_cov"].
        return TaskStep(new, belief, info, None, cost, extras)

    def filter_step(
        self, particles: ParticleState, models: StepModels, rngs
    ) -> tuple[ParticleState, UpdateInfo]:
        """Bootstrap predict + update of the (resampled) cloud: Touil & Ghadi 2012, eq. 15-16.

        Pseudo-range models with a ``reduced`` form are weighed "observed minus computed" for
        float32 clouds (the same likelihood in metres-sized numbers). A subclass may replace the
        filter step (e.g. ``experiments.critical_scenario``'s n-conditional exploration).
        """
        pred = bootstrap.predict(particles, models.transition, None, models.dt, rng=rngs)
        obs, z = self.observation(models)
        return bootstrap.update(pred, z, obs, mask=models.mask)

    def observation(self, models: StepModels) -> tuple[Any, np.ndarray]:
        """The observation model and measurements the particles are weighed with."""
        obs, z = models.observation, models.z
        if self.particle_dtype == np.float32 and isinstance(obs, ReducibleObservation):
            obs, z = obs.reduced(z)  # same likelihood, metres-sized numbers
        return obs, z

    def features(self) -> list[Feature]:
        return [
            Feature("ess_frac", 0.0, 1.0, "-", "effective sample size after the update / N"),
            Feature(
                "redistribution_rule",
                0.0,
                1.0,
                "-",
                "1 when Carvalho et al. 1997's redistribution rule fires",
            ),
        ] + (
            [Feature("log_ess_frac", -float(np.log10(self.n_particles)), 0.0, "log10", "log10(ESS / N)")]
            if self.log_ess_feature
            else []
        )

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        """At reset the particles carry equal weights: ESS/N = 1."""
        return {"ess_frac": np.ones(B), "redistribution_rule": np.zeros(B)} | (
            {"log_ess_frac": np.zeros(B)} if self.log_ess_feature else {}
        )

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        return {
            "ess_frac": step.extras["ess_frac"],
            "redistribution_rule": step.extras["redistribution_rule"],
            **(
                {"log_ess_frac": np.log10(np.clip(step.extras["ess_frac"], 1.0 / self.n_particles, 1.0))}
                if self.log_ess_feature
                else {}
            ),
        }


TASKS = {
    "fading": FadingTask,
    "mixture": MixtureTask,
    "resample": ResampleTask,
    "noisescale": NoiseScaleTask,
    "robust": RobustTask,
}
#: The SignalTracking platform's Jumps task (:mod:`navgym.signal_tracking.task`; v2 only).
TASKS["jumps"] = JumpsTask


def make_task(
    task: str, outlier_rows: tuple[int, ...] | None = None, m_max: int | None = None, **kwargs: Any
) -> FadingTask | MixtureTask | ResampleTask | NoiseScaleTask | RobustTask:
    """Build a task by name (``"fading" | "mixture" | "resample" | "noisescale"``).

    ``outlier_rows`` (the platform's rows subject to impulsive noise) and ``m_max`` (its
    measurement rows) are used by the Mixture task; the other keyword arguments are the task's
    own.
    """
    try:
        cls = TASKS[task.lower()]
    except (KeyError, AttributeError):
        raise ValueError(f"task must be one of {sorted(TASKS)}; got {task!r}") from None
    if cls is MixtureTask:
        kwargs["outlier_rows"] = outlier_rows
        kwargs["m_max"] = m_max
    return cls(**kwargs)


__all__ = [
    "MAX_PARTICLES",
    "MAX_ROUGHENING",
    "MAX_SCALE_DECADES",
    "FadingTask",
    "MixtureTask",
    "NoTruthError",
    "NoiseScaleTask",
    "ResampleTask",
    "RobustTask",
    "TaskStep",
    "check_action",
    "make_task",
]
