"""Gymnasium shells over :class:`~navgym.envs.core.NavCore`: single env and native vector env.

**Public API for baselines, oracles and evaluation** (beyond Gymnasium's): every navgym env,
reached with :func:`navigation_env` (through wrappers and the SB3 adapter), publishes the
members of :class:`NavigationAPI`: the ``task`` (its name and knob range), the ``platform``
(its step, error scale, divergence bound, scenario distribution), the
``observation_features`` (named columns with bounds) and the ``horizon``. A native vector env
also offers :meth:`NavVectorEnv.episode_stepper`, which steps one episode per sub-env without
autoreset (evaluation, lookahead oracles). Everything else of the core is internal.

Both follow the environment contracts of ``docs/architecture.md``: observation from the estimator only
(truth goes to ``info``), float32 ``Box`` actions in [-1, 1] or ``Discrete``, non-finite actions
raise ``ValueError``, determinism from per-environment generators. The vector env autoresets in
Gymnasium's ``NEXT_STEP`` mode.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv

from navgym.envs.arguments import ArgumentTypeError
from navgym.envs.core import NavCore
from navgym.envs.features import FeatureSet
from navgym.envs.protocols import Platform, Task
from navgym.envs.tasks.actions import check_single_shape

#: The keys of ``reset(options=...)``: ``"scenario"``, a pinned :class:`~navgym.scenarios.Scenario`
#: (the vector env: one for every sub-env, or a list of one per sub-env).
RESET_OPTIONS = ("scenario",)


def reset_options(options: Any) -> Mapping[str, Any]:
    """``options`` of ``reset`` checked: None or a mapping whose keys are :data:`RESET_OPTIONS`.

    Raises :class:`~navgym.envs.arguments.ArgumentTypeError` (a ``TypeError`` and a
    ``ValueError``) for a non-mapping and ``ValueError`` naming an unknown key, with the closest
    known one (``"scenaro"`` -> ``"scenario"``).
    """
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ArgumentTypeError(
            f"options must be a dict (keys {list(RESET_OPTIONS)}) or None; got {type(options).__name__}"
        )
    for key in options:
        if key not in RESET_OPTIONS:
            close = difflib.get_close_matches(str(key), RESET_OPTIONS, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ValueError(f"unknown reset option {key!r}: the options are {list(RESET_OPTIONS)}{hint}")
    return options


class NavigationAPI:
    """The members of a navgym env that baselines, oracles and evaluation may read."""

    core: NavCore

    @property
    def task(self) -> Task:
        """What the agent controls (name, knob range, single-env ``action_space``).

        ``task.name`` is "Fading", "Mixture" or "Resample"; the knob range is ``lambda_max``;
        ``eps_max``, ``variance_ratio``, ``outlier_rows``; or ``n_particles``.
        """
        return self.core.task

    @property
    def platform(self) -> Platform:
        """The estimation problem.

        ``name``, ``dt`` [s], ``error_scale_m``, ``divergence_m``, ``m_max`` and its
        ``scenarios`` distribution.
        """
        return self.core.platform

    @property
    def observation_features(self) -> FeatureSet:
        """The observation's named columns (``index(name)`` gives a feature's slice, ``dim``)."""
        return self.core.obs_features

    @property
    def horizon(self) -> int:
        """Steps after which an episode is truncated (``max_episode_steps`` or ``episode_steps``)."""
        return int(self.core.truncate_steps)


#: Functions that find the navgym env behind an object of another library's wrappers (e.g.
#: stable-baselines3's ``VecEnv`` wrappers, registered by :mod:`navgym.envs.sb3` when imported):
#: each returns the env behind ``env``, or None when ``env`` is not one of its wrappers.
UNWRAPPERS: list[Callable[[Any], Any]] = []


def register_unwrapper(unwrap: Callable[[Any], Any]) -> None:
    """Let :func:`navigation_env` see through another library's wrappers (see :data:`UNWRAPPERS`)."""
    if unwrap not in UNWRAPPERS:
        UNWRAPPERS.append(unwrap)


def navigation_env(env: Any) -> NavEnv | NavVectorEnv:
    """The navgym env behind ``env``: itself, under Gymnasium wrappers, or under SB3's adapter.

    ``env`` may also be an env id (a single env is built with default arguments to read the
    layout; pass an env when non-default keyword arguments change it, e.g. ``m_max``).
    Raises ``ValueError`` when no navgym env is found.
    """
    if isinstance(env, str):
        import navgym  # noqa: F401  (registers the ids)

        env = gym.make(env)
    if isinstance(env, (gym.Env, VectorEnv)):
        env = env.unwrapped
    else:
        for unwrap in UNWRAPPERS:
            inner = unwrap(env)
            if inner is not None:
                env = inner
                break
    if not isinstance(env, (NavEnv, NavVectorEnv)):
        raise ValueError(f"not a navgym environment: {type(env).__name__}; pass a navgym env or env id")
    return env


class NavEnv(NavigationAPI, gym.Env):
    """Single navigation environment: a :class:`NavCore` with B = 1 (see the platform cards)."""

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}

    def __init__(self, core: NavCore, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None; got {render_mode!r}"
            )
        self.core = core
        self.render_mode = render_mode
        self.observation_space = core.observation_space
        self.action_space = core.action_space
        self._history: list[dict[str, Any]] = []
        self._renderer: Any = None  # navgym.envs.rendering.FrameRenderer, made at the first frame
        self._needs_reset = True

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        scenario = reset_options(options).get("scenario")
        super().reset(seed=seed)
        obs = self.core.reset(np.array([0]), [self.np_random], [scenario])
        self._needs_reset = False
        self._history = []
        info = {"scenario": self.core.scenarios[0]}
        if self.render_mode == "human":
            self.render()
        return obs[0], info

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("call reset() before step()")
        # the task validates the action (ValueError) before the core changes anything; its shape
        # first, here, so that the error names the single env's shapes (not the batch axis)
        check_single_shape(action, self.action_space)
        batch: Any
        try:
            batch = np.asarray(action)[None]
        except (TypeError, ValueError):  # not an array (ragged): the task's check names it
            batch = [action]
        obs, reward, terminated, truncated, info = self.core.advance(batch, [self.np_random])
        single = info.row(0)
        single["scenario"] = self.core.scenarios[0]
        if self.render_mode is not None:
            from navgym.envs.rendering import history_row

            self._history.append(history_row(single, float(reward[0])))
            if self.render_mode == "human":
                self.render()
        if terminated[0] or truncated[0]:
            self._needs_reset = True
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), single

    def render(self):
        """The frame of the episode so far (``rgb_array``), or draw it in a window (``human``).

        Reads the recorded rows only: no random number is drawn, no state changes
        (:mod:`navgym.envs.rendering`).
        """
        if self.render_mode not in ("rgb_array", "human"):
            return None
        if self._renderer is None:
            from navgym.envs.rendering import FrameRenderer

            name = self.core.platform.name
            self._renderer = FrameRenderer(name, name == "SignalTracking", self.render_mode == "human")
        scenario = self.core.scenarios[0] if self.core.scenarios else None
        frame = self._renderer.draw(self._history, scenario)
        return frame if self.render_mode == "rgb_array" else None

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None  # a figure does not pickle; the next render makes a new one
        return state


class NavVectorEnv(NavigationAPI, VectorEnv):
    """Native batched vector environment over one :class:`NavCore` with B = ``num_envs``."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, core: NavCore) -> None:
        self.core = core
        self.num_envs = core.B
        self.single_observation_space = core.observation_space
        self.single_action_space = core.action_space
        self.observation_space = gym.vector.utils.batch_space(core.observation_space, self.num_envs)
        self.action_space = gym.vector.utils.batch_space(core.action_space, self.num_envs)
        self.rngs = [seeding.np_random(None)[0] for _ in range(self.num_envs)]
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._started = False
        self._scratch_rng = np.random.default_rng(0)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None):
        scenarios = reset_options(options).get("scenario")
        B = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * B
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(B)]
        else:
            seeds = list(seed)
            if len(seeds) != B:
                raise ValueError(f"seed must be an int or a list of {B} seeds; got {len(seeds)}")
        for i, s in enumerate(seeds):
            if s is not None or not self._started:
                self.rngs[i] = seeding.np_random(s)[0]
        if scenarios is None or not isinstance(scenarios, (list, tuple)):
            scenarios = [scenarios] * B
        obs = self.core.reset(np.arange(B), self.rngs, scenarios)
        self._autoreset[:] = False
        self._started = True
        return obs, {"scenario": np.array(self.core.scenarios, dtype=object)}

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = actions
        checked = self.core.validate_action(a)  # before the autoreset draws anything (ValueError)
        reset_idx = np.flatnonzero(self._autoreset)
        rngs = self.rngs
        if reset_idx.size:
            # NEXT_STEP autoreset: sub-envs that ended last step start a new episode now and
            # return its first observation; they are stepped along with the others (one batched
            # call) with a throw-away generator, and their fresh state is restored afterwards,
            # so their own generators see exactly the draws of a single env's reset.
            reset_obs = self.core.reset(reset_idx, [self.rngs[i] for i in reset_idx], [None] * reset_idx.size)
            fresh = self.core.snapshot(reset_idx)
            rngs = list(self.rngs)
            for i in reset_idx:
                rngs[i] = self._scratch_rng
        obs, reward, terminated, truncated, info = self.core.advance(a, rngs, checked)
        if reset_idx.size:
            self.core.restore(reset_idx, fresh)
            obs = obs.copy()
            obs[reset_idx] = reset_obs
            reward = reward.copy()
            reward[reset_idx] = 0.0
            terminated = terminated.copy()
            truncated = truncated.copy()
            terminated[reset_idx] = False
            truncated[reset_idx] = False
        self._autoreset = terminated | truncated
        valid = np.ones(self.num_envs, dtype=bool)
        valid[reset_idx] = False
        return obs, reward, terminated, truncated, info.vector(valid)

    def episode_stepper(self) -> EpisodeStepper:
        """A stepper for one episode per sub-env from the current state, without autoreset."""
        return EpisodeStepper(self)


class EpisodeStepper:
    """Steps a native vector env's sub-envs through one episode each, without autoreset.

    Finished rows are not autoreset (no new episode is simulated): their filter state and
    bookkeeping are put back to what they were when the stepper was created (the start of the
    episodes, or the moment of an oracle's copy), so they stay finite while the other rows go
    on; their outputs after the step that ends them are to be ignored. Rows are independent and
    each uses its own generator, so unfinished rows get exactly what ``env.step`` gives them.
    Invalid actions raise ``ValueError`` as in ``env.step``.
    """

    def __init__(self, env: NavVectorEnv) -> None:
        self.env = env
        self._rows = np.arange(env.core.B)
        self._start = env.core.snapshot(self._rows)

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """``env.step`` without autoreset: ``(obs, reward, terminated, truncated, info)`` of every row."""
        core = self.env.core
        obs, reward, term, trunc, info = core.step(actions, self.env.rngs)  # validated there
        done = np.flatnonzero(np.asarray(term) | np.asarray(trunc))
        if done.size:
            obs = obs.copy()  # the core's own buffer, which the restore rewrites
            core.restore(done, core.snapshot_rows(self._start, done))
        return obs, reward, term, trunc, info
