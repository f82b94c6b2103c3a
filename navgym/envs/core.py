"""The batched core shared by the single environment (B = 1) and the native vector env.

One :class:`NavCore` advances B episodes of one platform under one task. Both
:class:`navgym.envs.base.NavEnv` and :class:`navgym.envs.base.NavVectorEnv` are thin shells over
it, so the two cannot drift apart: sub-environment ``i`` of a vector env reset with seed ``s``
uses the generator of a single env reset with seed ``s + i`` and draws the same numbers in the
same order.

Reward (documented in every env card)::

    r_t = -min((pos_err_m + extra_err) / error_scale_m, reward_clip) - cost(decision)

(``extra_err`` is the platform's ``PositionError.extra_error``, 0 where it gives none: Jpa's
weighted attitude error; ``info["extra_err"]``) and an episode terminates (``terminated =
True``) with an extra ``divergence_penalty`` when the filter's health flag is False, the
position error exceeds ``divergence_m``, or the filter's own horizontal sigma ``sqrt(tr P_ne)``
exceeds ``100 divergence_m`` (runaway covariance). With ``penalize_remaining_steps`` (the default
of the ``-v1`` ids) the penalty also charges the worst step reward for every step the episode
does not play, ``divergence_penalty + reward_clip (T - t)``: a constant penalty smaller than the
reward still to come would make diverging early pay.
``info["divergence_reason"]`` (``""`` while an episode goes on) names the first rule that ended
it: ``"numerical failure"``, ``"health"``, ``"error bound"`` or ``"covariance bound"``.

**Memory features** (``memory_features=True``; default False, the v0/v1 observation): averages of
the innovations over past steps (NIS at two time constants, per-row innovation means, a
whiteness statistic; :mod:`navgym.envs.memory`) appended after ``previous_action``. Their
per-episode memory is reset with the episode and kept by :meth:`NavCore.snapshot` /
:meth:`NavCore.restore`.

**Numerical failures end one episode, never the batch.** The B filters of a batch are stepped
by one call, so a filter that fails numerically in one row (its state overflowed to inf or
NaN, a prediction overflowed, a LAPACK routine raised ``LinAlgError``) must not stop the other
rows or change their numbers. The core therefore

* replaces, before the filter step, the state of every row whose state is not finite (checked
  on the rows that ended unhealthy and were not reset since, and on every row when the filter
  rejects its input with a ``ValueError``) by a placeholder: the task's state at the row's
  prior (``platform.initial_belief``), stepped with the task's neutral knob;
* lets the task isolate the rows it finds non-finite inside its step
  (``TaskStep.numerical_failure``, see :mod:`navgym.envs.tasks.base`);
* when the step raises ``LinAlgError`` or ``FloatingPointError``, finds the failing rows by
  bisection (the step rerun with the rows outside a half replaced by placeholders, every
  generator put back to its state before the step first), then steps the batch once more with
  the failing rows replaced by placeholders. Each probe is a step of the whole batch, about
  ``2 k log2 B`` of them for k failing rows: a cost paid only when a step raises.

Such rows are reported unhealthy (``info["healthy"]`` False, ``info["pos_err_m"]`` NaN), get
the worst accuracy term ``-reward_clip`` and the divergence penalty, and terminate with
``divergence_reason = "numerical failure"``. The other rows take exactly the arithmetic and
the random numbers they take without the failing rows (rows are independent), so their
results are bit-identical to a batch without them. An exception that remains with every row
replaced by its placeholder, or a ``ValueError`` not caused by a non-finite state, is raised.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any

import numpy as np

from filters.core import pcg64
from filters.core.compiled import compiled_enabled
from filters.core.linalg import cholesky, solve_lower
from filters.core.nis_kernels import quadratic_form_pass
from navgym.envs import arguments
from navgym.envs.distinct import simulate_distinct
from navgym.envs.features import Feature, FeatureSet
from navgym.envs.memory import InnovationMemory, MemoryState
from navgym.envs.protocols import Platform, StepModels, Task, TaskStep
from navgym.envs.rows import finite_rows, pack_layout, replace_rows, take_rows, unpack_layout
from navgym.envs.step_info import StepInfo
from navgym.scenarios import Scenario, pinned

#: A filter whose horizontal sigma exceeds this many ``divergence_m`` has diverged.
SIGMA_DIVERGENCE = 100.0
#: Exceptions of a filter step that mean a numerical failure (of some rows), not a bug.
NUMERICAL_ERRORS = (np.linalg.LinAlgError, FloatingPointError)
#: ``info["divergence_reason"]`` values, in the order the rules are checked.
DIVERGENCE_REASONS = ("numerical failure", "health", "error bound", "covariance bound")
#: The dtype of ``info["divergence_reason"]`` (what ``np.select`` over the reasons gives).
_REASON_DTYPE = np.dtype(f"<U{max(map(len, DIVERGENCE_REASONS))}")
_NEG_MAX = -np.finfo(np.float64).max

#: The core's keyword arguments of the environments (reward, horizon, evaluation info), declared
#: once: :class:`NavCore` checks them with these rules, the cards and the fuzz read them.
CORE_ARGUMENTS: tuple[arguments.Argument, ...] = (
    arguments.Argument(
        "max_episode_steps",
        None,
        arguments.Integer(1),
        "truncate the episodes after this many steps (None: the simulated episode_steps)",
    ),
    arguments.Argument("reward_clip", 10.0, arguments.Real(0.0, low_open=True), "the worst accuracy term"),
    arguments.Argument("divergence_penalty", 100.0, arguments.Real(0.0), "the penalty of a diverged episode"),
    arguments.Argument(
        "penalize_remaining_steps",
        False,
        arguments.Flag(),
        "the penalty also charges reward_clip per step of the episode not played (v1)",
    ),
    arguments.Argument("eval_info", True, arguments.Flag(), "compute the NEES of info (truth)"),
    arguments.Argument(
        "memory_features",
        False,
        arguments.Flag(),
        "innovation averages over past steps in the observation (v2; navgym.envs.memory)",
        opt_in=True,
    ),
)
_CORE = {a.name: a for a in CORE_ARGUMENTS}


class RecordedGenerators(Sequence):
    """The generators of a step, each one's state recorded when the task first takes it.

    :meth:`rewind` puts every generator taken back to that state, so a step can be rerun with
    the same random numbers. A task that draws nothing (the Gaussian tasks) costs nothing.
    """

    def __init__(self, rngs: Sequence[np.random.Generator] | None) -> None:
        self._rngs = [] if rngs is None else list(rngs)
        self._states: dict[int, tuple[np.random.Generator, Mapping[str, Any]]] = {}
        #: every generator's state in one compiled snapshot (:func:`filters.core.pcg64.snapshot`),
        #: taken when the task first iterates over them all: a dict per generator costs about
        #: 1 us (0.3 ms per step at B = 256)
        self._snapshot: np.ndarray | None = None
        self._snapshot_tried = False

    def __len__(self) -> int:
        return len(self._rngs)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self._rngs)))]
        g = self._rngs[i]
        if self._snapshot is None and id(g) not in self._states:
            self._states[id(g)] = (g, g.bit_generator.state)
        return g

    def __iter__(self) -> Iterator[np.random.Generator]:
        if not self._snapshot_tried:  # None: not distinct PCG64 generators, or NumPy only
            self._snapshot_tried = True
            self._snapshot = pcg64.snapshot(self._rngs)
        if self._snapshot is not None:
            yield from self._rngs
            return
        states = self._states  # __getitem__'s recording, without its per-item call
        for g in self._rngs:
            if id(g) not in states:
                states[id(g)] = (g, g.bit_generator.state)
            yield g

    def rewind(self) -> None:
        """Every generator taken so far back to its state when it was first taken."""
        if self._snapshot is not None:
            pcg64.restore(self._rngs, self._snapshot)
        for g, state in self._states.values():  # taken before the snapshot: earlier states
            g.bit_generator.state = state


class NavCore:
    """B episodes of ``platform`` under ``task`` (see the module docstring for the reward)."""

    def __init__(
        self,
        platform: Platform,
        task: Task[Any, Any],
        num_envs: int,
        max_episode_steps: int,
        reward_clip: float = 10.0,
        divergence_penalty: float = 100.0,
        eval_info: bool = True,
        truncate_steps: int | None = None,
        penalize_remaining_steps: bool = False,
        memory_features: bool = False,
    ) -> None:
        self.platform = platform
        self.task: Task[Any, Any] = task
        #: The event fields a pinned scenario may hold (the events the platform models; None:
        #: any). :func:`~navgym.envs.build.build_core` sets it from the platform's spec.
        self.modelled_events: frozenset[str] | None = None
        self.B = arguments.integer("num_envs", num_envs, 1)
        self.T = arguments.integer("episode_steps", max_episode_steps, 1)
        if truncate_steps is not None:
            truncate_steps = _CORE["max_episode_steps"].check(truncate_steps)
        #: Steps after which episodes are truncated: the horizon, or an earlier time limit.
        self.truncate_steps = self.T if truncate_steps is None else min(self.T, truncate_steps)
        self.reward_clip = _CORE["reward_clip"].check(reward_clip)
        self.divergence_penalty = _CORE["divergence_penalty"].check(divergence_penalty)
        #: Also charge ``reward_clip`` for every step the diverged episode does not play, so
        #: that ending an episode early can never beat finishing it (see the module docstring).
        self.penalize_remaining_steps = _CORE["penalize_remaining_steps"].check(penalize_remaining_steps)
        self.eval_info = _CORE["eval_info"].check(eval_info)
        #: Innovation statistics over past steps in the observation (:mod:`navgym.envs.memory`):
        #: None unless ``memory_features`` (the v0/v1 default), else their model.
        self.memory_model = (
            InnovationMemory(platform.dt, platform.m_max)
            if _CORE["memory_features"].check(memory_features)
            else None
        )
        act = task.action_space
        self.action_dim = int(np.prod(act.shape)) if act.shape else 1
        self.obs_features = FeatureSet(
            platform.features()
            + task.features()
            + [
                Feature("time_since_gnss", 0.0, 10.0, "min", "time since the last GNSS update / 60 s"),
                Feature(
                    "previous_action",
                    -1.0,
                    1.0,
                    "-",
                    "the previous action (Discrete: 0 or 1)",
                    self.action_dim,
                ),
            ]
            + ([] if self.memory_model is None else self.memory_model.features())
        )
        self.observation_space = self.obs_features.space
        self.action_space = act
        self.episodes: Any = None
        self.state: Any = None
        self.t = np.zeros(self.B, dtype=np.int64)
        self.time_since_gnss = np.zeros(self.B)
        self.prev_action = np.zeros((self.B, self.action_dim))
        self.scenarios: list[Any] = [None] * self.B
        self.last_obs = np.zeros((self.B, self.obs_features.dim), dtype=np.float32)
        #: Rows whose last step ended unhealthy (their state may be non-finite) and that were
        #: not reset since: checked before the next filter step.
        self.unhealthy = np.zeros(self.B, dtype=bool)
        #: The per-episode memory (:class:`~navgym.envs.memory.MemoryState`), None without it.
        self.memory: MemoryState | None = (
            None if self.memory_model is None else self.memory_model.initial_state(self.B)
        )

    # ------------------------------------------------------------------------------------ pickle
    def __getstate__(self) -> dict[str, Any]:
        """The core's attributes, its state and episodes with their memory layouts kept.

        A particle cloud ``(B, N, n)`` laid out ``(B, n, N)`` would come back from pickle in C
        order, and reductions over it would round differently (:func:`~navgym.envs.rows.pack_layout`).
        """
        d = self.__dict__.copy()
        d["state"] = pack_layout(self.state)
        d["episodes"] = pack_layout(self.episodes)
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        d = dict(d)
        d["state"] = unpack_layout(d["state"])
        d["episodes"] = unpack_layout(d["episodes"])
        d.setdefault("unhealthy", np.zeros(d["B"], dtype=bool))  # pickled before it existed
        d.setdefault("memory_model", None)  # pickled before the memory features existed
        d.setdefault("memory", None)
        d.setdefault("modelled_events", None)  # pickled before pinned events were checked
        self.__dict__.update(d)

    # ------------------------------------------------------------------------------------ reset
    def reset(
        self, idx: np.ndarray, rngs: Sequence[np.random.Generator], scenarios: Sequence[Any | None]
    ) -> np.ndarray:
        """Start new episodes in rows ``idx`` with their generators; return their observations."""
        idx = np.asarray(idx, dtype=np.int64)
        rngs = list(rngs)
        scen = list(scenarios)
        if len(scen) != len(rngs):
            raise ValueError(f"one scenario (or None) per generator: got {len(scen)} for {len(rngs)}")
        for s in scen:
            if s is not None:
                self._check_pinned(s)
        # drawn or pinned scenarios, the episodes; rows reset with the same seed simulated once
        eps, chosen = simulate_distinct(self.platform, rngs, scen, self.T)
        belief = self.platform.initial_belief(eps)
        state = self.task.init_state(belief, rngs)
        if self.episodes is None or len(idx) == self.B and np.array_equal(idx, np.arange(self.B)):
            self.episodes, self.state = eps, state
        else:
            self.episodes = replace_rows(self.episodes, idx, eps, inplace=True)
            self.state = replace_rows(self.state, idx, state)
        for j, i in enumerate(idx):
            self.scenarios[i] = chosen[j]
        self.t[idx] = 0
        self.time_since_gnss[idx] = 0.0
        self.unhealthy[idx] = False
        if self.memory_model is not None:
            self.memory = replace_rows(self.memory, idx, self.memory_model.initial_state(len(idx)))
        neutral = np.asarray(self.task.neutral_action(), dtype=np.float64).reshape(-1)
        self.prev_action[idx] = neutral
        # Observation at reset: the prior, no innovation yet (eps holds exactly rows idx of the
        # episodes now, so no copy of them is taken).
        obs = self._initial_obs(belief, eps, idx)
        self.last_obs = self.last_obs.copy()  # the previous one was returned to the caller
        self.last_obs[idx] = obs
        return obs

    def _check_pinned(self, scenario: Any) -> None:
        """A pinned scenario (``reset(options={"scenario": ...})``) must describe this episode."""
        if not isinstance(scenario, Scenario):
            raise TypeError(
                "options['scenario'] must be a navgym.scenarios.Scenario (or None); "
                f"got {type(scenario).__name__}"
            )
        horizon = self.T * float(self.platform.dt)
        if abs(scenario.duration - horizon) > 1e-9 * horizon:
            raise ValueError(
                f"the pinned scenario lasts {scenario.duration:g} s but the episode {horizon:g} s "
                f"(episode_steps {self.T} x dt {self.platform.dt:g} s): build it with duration={horizon:g}"
            )
        pinned.check_values(scenario)
        if self.modelled_events is not None:
            pinned.check_events(scenario, self.modelled_events, str(self.platform.name))

    #: Per-episode bookkeeping arrays of the core (rows = episodes) kept by :meth:`snapshot`
    #: (with the memory of the memory features, where on: the snapshot's ``"memory"``).
    BOOKKEEPING = ("t", "time_since_gnss", "prev_action", "last_obs", "unhealthy")

    def snapshot(self, idx: np.ndarray) -> dict[str, Any]:
        """The per-episode bookkeeping and filter state of rows ``idx`` (see :meth:`restore`).

        With the platform's ``episode_cursors`` (the episode fields ``step_models`` advances)
        and, where the memory features are on, the rows' memory.
        """
        snap = {
            "state": take_rows(self.state, idx),
            **{k: getattr(self, k)[idx].copy() for k in self.BOOKKEEPING},
            "cursors": {f: getattr(self.episodes, f)[idx].copy() for f in self.platform.episode_cursors},
        }
        if self.memory is not None:
            snap["memory"] = take_rows(self.memory, idx)
        return snap

    @classmethod
    def snapshot_rows(cls, snap: dict[str, Any], rows: np.ndarray) -> dict[str, Any]:
        """The part of a :meth:`snapshot` for its rows ``rows`` (positions within the snapshot)."""
        out = {
            "state": take_rows(snap["state"], rows),
            **{k: snap[k][rows] for k in cls.BOOKKEEPING},
            "cursors": {f: a[rows] for f, a in snap["cursors"].items()},
        }
        if "memory" in snap:
            out["memory"] = take_rows(snap["memory"], rows)
        return out

    def restore(self, idx: np.ndarray, snap: dict[str, Any]) -> None:
        """Put back rows ``idx`` as they were in ``snap``."""
        self.state = replace_rows(self.state, idx, snap["state"])
        for k in self.BOOKKEEPING:
            getattr(self, k)[idx] = snap[k]
        for f, rows in snap["cursors"].items():
            getattr(self.episodes, f)[idx] = rows
        if "memory" in snap:
            self.memory = replace_rows(self.memory, idx, snap["memory"])

    def _initial_obs(self, belief, episodes, idx) -> np.ndarray:
        cols = self.platform.initial_feature_values(belief, episodes)
        cols.update(self.task.initial_feature_values(len(idx)))
        cols["time_since_gnss"] = np.zeros(len(idx))
        cols["previous_action"] = self.prev_action[idx]
        if self.memory_model is not None:
            cols.update(self.memory_model.values(self.memory_model.initial_state(len(idx))))
        return self.obs_features.build(cols)

    # ------------------------------------------------------------------------------------- step
    def validate_action(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The task's knob ``(B,)`` of ``action (B, ...)`` and which rows were clipped.

        Raises ``ValueError`` naming the action and the action space for actions that are not
        in it and cannot be clipped (see :func:`navgym.envs.tasks.actions.check_action`) before anything
        is drawn or changed, so a vector env can check an action before it autoresets.
        """
        return self.task.knob(action, self.B)

    def step(
        self, action: np.ndarray, rngs: Sequence[np.random.Generator]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Advance every episode one filter step with ``action (B, ...)``; ``info`` as a dict."""
        obs, reward, terminated, truncated, info = self.advance(action, rngs)
        return obs, reward, terminated, truncated, info.as_dict()

    def advance(
        self,
        action: np.ndarray,
        rngs: Sequence[np.random.Generator],
        checked: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, StepInfo]:
        """Advance every episode one filter step with ``action (B, ...)``.

        ``platform.step_models`` -> ``task.step`` (a :class:`~navgym.envs.protocols.TaskStep`)
        -> the episode ends, the reward and the observation -> a
        :class:`~navgym.envs.step_info.StepInfo`, which the shells view as their ``info``.
        ``checked``: :meth:`validate_action` of ``action``, where the caller has already
        checked it (the vector env, before its autoreset; the knob is a function of the action
        alone), else None.
        """
        if self.episodes is None:
            raise RuntimeError("call reset() before step()")
        knob, clipped = self.validate_action(action) if checked is None else checked
        models = self.platform.step_models(self.episodes, self.t)
        # Overflow in a diverging member is flagged by the health flag (and ends its episode with
        # the divergence penalty); NumPy's warnings for it would only be noise.
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            out, failed = self._filter_step(knob, models, rngs)
            if out.numerical_failure is not None:
                failed = failed | np.asarray(out.numerical_failure, dtype=bool)
            self.state = out.state
            if self.memory is not None and self.memory_model is not None:
                self.memory, memory_cols = self.memory_model.update(
                    self.memory, self.t, out.info, models.mask
                )
            self.t = self.t + 1
            received = np.asarray(models.mask[:, list(self.platform.gnss_rows)].any(axis=1))
            self.time_since_gnss = np.where(received, 0.0, self.time_since_gnss + models.dt)
            err = self.platform.position_error(out.belief.m, self.episodes, self.t, out.belief.P)
        pos_err = np.where(failed, np.nan, err.pos_err_m)
        healthy = np.asarray(out.info.healthy, dtype=bool) & np.isfinite(pos_err)
        self.unhealthy = ~healthy
        # Divergence: the health flag, the error bound, or the filter's own horizontal sigma
        # beyond SIGMA_DIVERGENCE x the bound (a runaway covariance, e.g. extreme fading through
        # an outage, ended before it overflows).
        sigma_h = np.sqrt(np.abs(np.trace(err.cov_ne, axis1=1, axis2=2))) / SIGMA_DIVERGENCE
        rules = [
            failed,
            ~healthy,
            ~(pos_err <= self.platform.divergence_m),
            ~(sigma_h <= self.platform.divergence_m),
        ]
        diverged = np.logical_or.reduce(rules)
        # np.select only where an episode ended (most steps: none)
        reason = (
            np.select(rules, DIVERGENCE_REASONS, default="")
            if diverged.any()
            else np.zeros(self.B, _REASON_DTYPE)
        )
        reward_err = pos_err if err.extra_error is None else pos_err + err.extra_error
        # -min(nan_to_num(e, nan=inf) / scale, clip) without nan_to_num's Python-level cost: fmin
        # takes the clip for NaN, and -inf (never an error) still maps to -max_float as before
        accuracy = -np.fmin(np.maximum(reward_err, _NEG_MAX) / self.platform.error_scale_m, self.reward_clip)
        penalty_size = self.divergence_penalty
        if self.penalize_remaining_steps:
            # steps of the simulated episode not played: T, not truncate_steps, which a single env
            # cannot know (gym.make's TimeLimit wraps it), so gym.make and gym.make_vec agree
            penalty_size = penalty_size + self.reward_clip * np.maximum(self.T - self.t, 0)
        penalty = np.where(diverged, -penalty_size, 0.0)
        reward = accuracy - out.cost + penalty
        terminated = diverged
        truncated = (self.t >= self.truncate_steps) & ~terminated
        a = np.asarray(action, dtype=np.float64).reshape(self.B, self.action_dim)
        self.prev_action = np.clip(a, -1.0, 1.0)
        cols = self.platform.feature_values(out.belief, out.info, models, self.episodes, self.t)
        cols.update(self.task.feature_values(out))
        cols["time_since_gnss"] = self.time_since_gnss / 60.0
        cols["previous_action"] = self.prev_action
        if self.memory is not None:
            cols.update(memory_cols)
        obs = self.obs_features.build(cols)
        self.last_obs = obs
        nees = _nees(out.belief, err.state_err) if self.eval_info else np.full(self.B, np.nan)
        info = StepInfo(
            pos_err_m=pos_err,
            nees=nees,
            truth_pos=err.truth_pos,
            est_pos=err.est_pos,
            cov_ne=err.cov_ne,
            innovation=out.info.innovation,
            innovation_cov=out.info.S,
            nis=out.info.nis,
            n_meas=out.info.n_meas,
            filtered_cov=out.belief.P,
            healthy=healthy,
            diverged=diverged,
            divergence_reason=reason,
            gnss_available=received,
            knob=knob.astype(np.float64),
            action_clipped=clipped,
            reward_accuracy=accuracy,
            extra_err=None if err.extra_error is None else np.asarray(err.extra_error),
            reward_cost=-out.cost,
            reward_penalty=penalty,
            t=self.t.copy(),
            predicted_cov=out.P_pred,
            task=out.diagnostics,
        )
        return obs, reward, terminated, truncated, info

    # ------------------------------------------------------------------- numerical isolation
    def _filter_step(
        self, knob: np.ndarray, models: StepModels, rngs: Sequence[np.random.Generator]
    ) -> tuple[TaskStep[Any, Any], np.ndarray]:
        """The task's step of every row, and the rows replaced by placeholders (module docstring)."""
        state = self.state
        failed = np.zeros(self.B, dtype=bool)
        suspects = np.flatnonzero(self.unhealthy)
        if suspects.size:  # rows that ended unhealthy and were not reset since
            failed[suspects] = ~finite_rows(take_rows(state, suspects), suspects.size)
        recorded = RecordedGenerators(rngs)
        placeholders: list[Any] = []

        def attempt(rows: np.ndarray) -> TaskStep[Any, Any]:
            recorded.rewind()
            if not rows.any():
                return self.task.step(state, knob, models, recorded)
            if not placeholders:
                placeholders.append(self._placeholders())
            ph_state, ph_knob = placeholders[0]
            idx = np.flatnonzero(rows)
            k = knob.copy()
            k[idx] = ph_knob[idx]
            return self.task.step(replace_rows(state, idx, take_rows(ph_state, idx)), k, models, recorded)

        try:
            return attempt(failed), failed
        except NUMERICAL_ERRORS:  # (LinAlgError is a ValueError: first)
            pass
        except ValueError:  # a filter rejects a non-finite input (else: a bug, raised)
            nonfinite = ~finite_rows(state, self.B) & ~failed
            if not nonfinite.any():
                raise
            failed |= nonfinite
            try:
                return attempt(failed), failed
            except NUMERICAL_ERRORS:
                pass
        failed |= _failing_rows(attempt, failed)
        return attempt(failed), failed

    def _placeholders(self) -> tuple[Any, np.ndarray]:
        """Every row's task state at its prior and the neutral knob: what replaces a failed row."""
        belief = self.platform.initial_belief(self.episodes)
        scratch = np.random.default_rng(0)
        state = self.task.init_state(belief, [scratch] * self.B)
        neutral = np.broadcast_to(self.task.neutral_action(), (self.B, *np.shape(self.task.neutral_action())))
        return state, self.task.knob(np.array(neutral), self.B)[0]


def _failing_rows(attempt: Callable[[np.ndarray], Any], replaced: np.ndarray) -> np.ndarray:
    """Rows whose step raises a numerical error, found by bisection over the rows not ``replaced``.

    ``attempt(rows)`` steps the batch with ``rows`` replaced by placeholders. A half is tried
    alone (every other row replaced); a failing half is split again down to single rows. Rows
    that fail only together are all returned.
    """
    B = replaced.shape[0]

    def fails(rows: np.ndarray) -> bool:
        others = np.ones(B, dtype=bool)
        others[rows] = False
        try:
            attempt(others | replaced)
        except NUMERICAL_ERRORS:
            return True
        return False

    def search(rows: np.ndarray) -> list[int]:
        if rows.size <= 1:
            return [int(i) for i in rows]
        halves = (rows[: rows.size // 2], rows[rows.size // 2 :])
        found = [i for h in halves if fails(h) for i in search(h)]
        return found or [int(i) for i in rows]

    out = np.zeros(B, dtype=bool)
    out[search(np.flatnonzero(~replaced))] = True
    return out


def _nees(belief, state_err: np.ndarray | None) -> np.ndarray:
    """Normalized estimation error squared ``e^T P^-1 e`` (evaluation only: uses truth).

    ``|L^-1 e|^2`` with ``P = L L^T`` (one batched Cholesky and a forward substitution, about
    40 % cheaper than ``np.linalg.solve`` at B = 4096, n = 8). A member whose covariance is not
    positive definite (a diverged member) takes ``np.linalg.solve`` (NaN where that fails too);
    the others keep their Cholesky numbers (:func:`filters.core.linalg.cholesky` is exact per
    member), so one diverged row does not change the other rows' NEES.

    Compiled (:func:`filters.core.nis_kernels.quadratic_form_pass`, one pass instead of LAPACK
    once per matrix: about 0.7 ms of a GpsInsResample-v2 step at B = 256, n = 8) unless
    :func:`filters.core.compiled.numpy_only`; its diverged members take the same solve.
    """
    B = belief.m.shape[0]
    if state_err is None:
        return np.full(B, np.nan)
    e = state_err[:, :, None]
    if compiled_enabled() and belief.P.dtype == np.float64:
        out, ok = np.empty(B), np.empty(B, dtype=bool)
        quadratic_form_pass(
            np.ascontiguousarray(state_err, dtype=np.float64), np.ascontiguousarray(belief.P), out, ok
        )
        if not ok.all():
            _nees_by_solve(belief.P, e, out, np.flatnonzero(~ok))
        return out
    try:
        y = solve_lower(np.linalg.cholesky(belief.P), e)
        return (y * y).sum(axis=(1, 2))
    except np.linalg.LinAlgError:
        pass
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # in diverged rows only
        L, ok = cholesky(belief.P)
        y = solve_lower(L, e)
        out = (y * y).sum(axis=(1, 2))
        _nees_by_solve(belief.P, e, out, np.flatnonzero(~ok))
    return out


def _nees_by_solve(P: np.ndarray, e: np.ndarray, out: np.ndarray, rows: np.ndarray) -> None:
    """``out[i] = e_i^T P_i^-1 e_i`` by ``np.linalg.solve`` for the diverged ``rows`` (NaN where it fails)."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for i in rows:
            try:
                out[i] = (e[i] * np.linalg.solve(P[i], e[i])).sum()
            except np.linalg.LinAlgError:
                out[i] = np.nan
