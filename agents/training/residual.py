"""Residual policy learning over a tuned classical baseline.

Silver et al. 2018 ("Residual Policy Learning", arXiv:1812.06298) and Johannink et al. 2019
("Residual Reinforcement Learning for Robot Control", ICRA): the agent outputs a correction
``a_res`` in ``[-1, 1]`` that is added to a fixed base controller's action,

    a = clip(a_base + scale * a_res, low, high),

so a policy whose output starts near 0 (SB3's action heads are initialised that way) starts from
the base controller's behaviour and learns only where to depart from it. Here the base
controller is one of the classical baselines of the env's task (:mod:`agents.baselines`), with
its per-episode memory, reading the raw observation exactly as when it runs alone.

* :func:`resolve_residual`: an entry's ``residual`` (see :mod:`agents.training.config`) checked
  against the env: the baseline exists for the task, its parameters (``tuned``: the committed
  tuned file) resolved to every parameter's value, Box actions only.
* :class:`ResidualVecEnv`: the SB3 ``VecEnvWrapper`` training uses, innermost
  (``VecFrameStack?(VecNormalize?(VecMonitor(ResidualVecEnv(NavSB3VecEnv))))``): at each step it
  computes the base action from the raw observation (the baseline's memory reset for the rows
  that autoreset), combines it with the agent's action, and with ``observe_base`` appends the
  base action to the observation (terminal observations too, for the value bootstrap); so
  ``VecNormalize`` normalizes the augmented observation and its statistics stay plain arrays.
* :class:`ResidualRuntime`: the same computation for a loaded agent
  (:class:`agents.training.agent.TrainedAgent`), whose ``predict`` state then holds the
  baseline's memory beside the agent's own (:class:`ResidualState`).

Everything is batched over the sub-environments (no Python loop over rows, except SB3's per-row
``infos`` of the rows that finished). Importing this module needs stable-baselines3.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from stable_baselines3.common.vec_env import VecEnvWrapper

from agents.training.config import SUPERVISED_BASE, residual_of
from agents.training.spaces import space_to_dict

#: The project's root folder (the one holding ``agents/``).
PROJECT_ROOT = Path(__file__).resolve().parents[2]

__all__ = [
    "ResidualRuntime",
    "ResidualSpec",
    "ResidualState",
    "ResidualVecEnv",
    "augment",
    "augmented_space",
    "combine",
    "resolve_residual",
]


@dataclass(frozen=True)
class ResidualSpec:
    """A resolved ``residual``: the baseline, all its parameters, the scale, what is observed.

    Attributes:
        baseline: name in the task's baseline set (:func:`agents.baselines.baseline_specs`).
        task: the baseline set's key (:func:`agents.baselines.baseline_task`, e.g. ``RowMixture``).
        params: every parameter of the baseline (fixed, tuned or given, and defaults).
        scale: the residual's range in action units.
        observe_base: the base action is appended to the observation.
        params_source: where ``params`` came from (the tuned file, or ``explicit``).
        agent: ``baseline: supervised``: the supervised agent's folder (``""`` otherwise).
    """

    baseline: str
    task: str
    params: Mapping[str, float]
    scale: float
    observe_base: bool
    params_source: str = "explicit"
    agent: str = ""

    def config_record(self) -> dict[str, Any]:
        """The ``residual`` a run writes into its ``config.yml`` (parameters resolved)."""
        out = {
            "baseline": self.baseline,
            "params": dict(self.params),
            "scale": float(self.scale),
            "observe_base": bool(self.observe_base),
        }
        return {**out, "agent": self.agent} if self.agent else out

    def record(self) -> dict[str, Any]:
        """The manifest's and ``meta.json``'s ``residual`` (without the spaces)."""
        return {**self.config_record(), "task": self.task, "params_source": self.params_source}


def _plain(value: Any) -> Any:
    v = np.asarray(value)
    return v.item() if v.ndim == 0 else v.tolist()


def resolve_residual(value: Any, env_id: str, env: Any) -> ResidualSpec | None:
    """An entry's ``residual`` checked against ``env`` (``None`` when the entry has none).

    Args:
        value: the entry's ``residual`` (checked with :func:`agents.training.config.residual_of`).
        env_id: the env id (the tuned file of ``params: tuned``).
        env: the env whose layout and task the baseline reads (any form
            :func:`agents.baselines.navigation_env` takes).

    Raises:
        ValueError: naming the key: a Discrete task, a baseline the task does not have,
            parameters it does not take, or ``params: tuned`` without a tuned entry (the
            message gives the ``navgym tune`` command that writes it).
    """
    from gymnasium import spaces

    from agents.baselines import baseline_specs, baseline_task, load_tuned, make_baseline, navigation_env
    from agents.baselines.registry import tuned_path

    spec = residual_of(value)
    if spec is None:
        return None
    nav = navigation_env(env)
    if not isinstance(nav.task.action_space, spaces.Box):
        raise ValueError(
            f"residual: {env_id} has the action space {nav.task.action_space} (task {nav.task.name}); a "
            "residual correction is added to a Box action only: remove 'residual' from its entry"
        )
    task = baseline_task(env)
    if spec.get("agent") is not None:
        _supervised_base(spec["agent"], env_id, env)  # checks the folder, its manifest and layout
        return ResidualSpec(
            SUPERVISED_BASE,
            task,
            {},
            spec["scale"],
            spec["observe_base"],
            f"supervised: {spec['agent']}",
            agent=str(spec["agent"]),
        )
    specs = baseline_specs(task)
    name = spec["baseline"]
    if name not in specs:
        raise ValueError(
            f"residual.baseline: no baseline {name!r} for the {task} task of {env_id}; have {sorted(specs)}"
        )
    params = spec["params"]
    source = "explicit"
    if params == "tuned":
        path = tuned_path(env_id)
        tuned = load_tuned(env_id)
        if name not in tuned:
            what = "does not exist" if not path.exists() else f"has no entry for {name}"
            raise ValueError(
                f"residual.params: tuned: {path} {what}; run `navgym tune --env {env_id} --episodes 256 "
                f"--out {path.parent}` first (or give residual.params explicitly)"
            )
        params = tuned[name]
        source = f"tuned: agents/baselines/tuned/{path.name}"
    defaults = specs[name].cls.defaults
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ValueError(
            f"residual.params: {unknown} are not parameters of {name} (it has {sorted(defaults)})"
        )
    try:
        base = make_baseline(env, name, **dict(params))
    except ValueError as e:
        raise ValueError(f"residual.params: {e}") from e
    resolved = {k: _plain(v) for k, v in base.params.items()}
    return ResidualSpec(name, task, resolved, spec["scale"], spec["observe_base"], source)


def _supervised_base(folder: str, env_id: str | None, env: Any) -> Any:
    """The supervised agent of ``folder`` on ``env`` (``ValueError`` naming ``residual.agent``).

    Its manifest's env id must be ``env_id`` (when given) and its observation layout the env's.
    A relative ``folder`` is read from the working directory, else from the project root (the
    zoo's ``agents/zoo/...`` paths of a run started there).
    """
    from agents.supervised.files import SupervisedLoadError, load_policy, read_manifest

    path = Path(folder)
    if not path.is_dir() and not path.is_absolute() and (PROJECT_ROOT / path).is_dir():
        folder = str(PROJECT_ROOT / path)  # a zoo path recorded from the project root
    try:
        manifest = read_manifest(folder)
        trained_on = manifest.get("env_id")
        if env_id is not None and trained_on not in (None, env_id):
            raise ValueError(f"residual.agent: {folder} is an agent of {trained_on}, not {env_id}")
        return load_policy(folder, env)
    except (SupervisedLoadError, FileNotFoundError) as e:
        raise ValueError(f"residual.agent: {e}") from e


def make_residual_baseline(spec: ResidualSpec, env: Any):
    """The base policy of ``spec`` for ``env``: the baseline, or the supervised agent of ``spec.agent``.

    The task must be the one ``spec`` was resolved for.
    """
    from agents.baselines import baseline_task, make_baseline

    if spec.agent:
        return _supervised_base(spec.agent, None, env)
    task = baseline_task(env)
    if task != spec.task:
        raise ValueError(
            f"residual: the baseline {spec.baseline} was resolved for task {spec.task}, env has {task}"
        )
    return make_baseline(env, spec.baseline, **dict(spec.params))


def augmented_space(observation_space: Any, action_space: Any) -> Any:
    """The observation space with the base action appended (bounds: the action's)."""
    from gymnasium import spaces

    low = np.concatenate([observation_space.low.ravel(), action_space.low.ravel()])
    high = np.concatenate([observation_space.high.ravel(), action_space.high.ravel()])
    return spaces.Box(low=low.astype(observation_space.dtype), high=high.astype(observation_space.dtype))


def augment(obs: np.ndarray, base_action: np.ndarray) -> np.ndarray:
    """``(B, d + n)``: the observations ``(B, d)`` with the base actions ``(B, n)`` appended."""
    obs = np.asarray(obs)
    a = np.asarray(base_action, dtype=obs.dtype).reshape(obs.shape[0], -1)
    return np.concatenate([obs, a], axis=-1)


def combine(base_action: np.ndarray, residual: np.ndarray, scale: float, action_space: Any) -> np.ndarray:
    """``clip(a_base + scale * a_res, low, high)`` in the action space's dtype (batched).

    ``residual`` is reshaped to the base actions' shape; a zero residual returns the base
    actions bit for bit (they are in the space already).
    """
    a_base = np.asarray(base_action, dtype=action_space.dtype)
    a_res = np.asarray(residual, dtype=action_space.dtype).reshape(a_base.shape)
    a = a_base + np.asarray(scale, dtype=action_space.dtype) * a_res
    return np.clip(a, action_space.low, action_space.high).astype(action_space.dtype)


def residual_action_space(action_space: Any) -> Any:
    """The agent's action space: ``[-1, 1]`` of the env action's shape."""
    from gymnasium import spaces

    return spaces.Box(-1.0, 1.0, shape=action_space.shape, dtype=np.float32)


class ResidualState(NamedTuple):
    """The ``predict`` state of a residual agent: the baseline's memory and the agent's own."""

    base: Any  # the baseline's per-episode memory ({name: (B, ...) array})
    agent: Any  # the agent's state (frames, LSTM states) or None


class ResidualRuntime:
    """The baseline of a loaded residual agent: base actions, augmentation and combination.

    Attributes:
        spec: the resolved :class:`ResidualSpec`.
        baseline: the baseline policy (reads raw observations).
        observation_space: the environment's (raw) observation space.
        action_space: the environment's action space (the combined action's).
    """

    def __init__(self, spec: ResidualSpec, baseline: Any, observation_space: Any) -> None:
        self.spec = spec
        self.baseline = baseline
        self.observation_space = observation_space
        self.action_space = baseline.action_space
        self.act_dim = int(np.prod(self.action_space.shape))

    @property
    def model_obs_dim(self) -> int:
        """Width of the observation the agent's model sees (one frame)."""
        return int(self.observation_space.shape[0]) + (self.act_dim if self.spec.observe_base else 0)

    def base(self, obs: np.ndarray, state: Any, starts: np.ndarray) -> tuple[np.ndarray, Any]:
        """Base actions ``(B, n)`` and the baseline's new memory (rows of ``starts`` reset)."""
        return self.baseline.predict(obs, state=state, episode_start=starts)

    def model_obs(self, obs: np.ndarray, base_action: np.ndarray) -> np.ndarray:
        return augment(obs, base_action) if self.spec.observe_base else obs

    def combine(self, base_action: np.ndarray, residual: np.ndarray) -> np.ndarray:
        return combine(base_action, residual, self.spec.scale, self.action_space)


class ResidualVecEnv(VecEnvWrapper):
    """SB3 ``VecEnvWrapper``: the agent's action is a residual on a baseline's (module docstring).

    Args:
        venv: the env (navgym's ``NavSB3VecEnv``, innermost: observations raw, Box actions).
        spec: the resolved :class:`ResidualSpec`.
        baseline: the baseline policy (default: built from ``spec`` for ``venv``).

    The wrapper's action space is ``[-1, 1]`` of the env action's shape; its observation space
    the env's, with the base action appended when ``spec.observe_base``.
    """

    def __init__(self, venv: Any, spec: ResidualSpec, baseline: Any = None) -> None:
        from gymnasium import spaces

        if not isinstance(venv.action_space, spaces.Box):
            raise ValueError(
                f"residual: a residual needs a Box action space; the env has {venv.action_space}"
            )
        self.residual = spec  # not ``spec``: SB3 reads a VecEnv's ``spec`` as the env spec
        self.baseline = baseline if baseline is not None else make_residual_baseline(spec, venv)
        self.env_action_space = venv.action_space
        self.env_observation_space = venv.observation_space
        obs_space = (
            augmented_space(venv.observation_space, venv.action_space)
            if spec.observe_base
            else venv.observation_space
        )
        super().__init__(
            venv, observation_space=obs_space, action_space=residual_action_space(venv.action_space)
        )
        self._state: Any = None
        self._base: np.ndarray | None = None
        #: The last combined actions sent to the env (for inspection and tests).
        self.last_actions: np.ndarray | None = None

    def _observe(self, obs: np.ndarray, base_action: np.ndarray) -> np.ndarray:
        return augment(obs, base_action) if self.residual.observe_base else obs

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        self._base, self._state = self.baseline.predict(
            obs, state=None, episode_start=np.ones(self.num_envs, dtype=bool)
        )
        return self._observe(obs, self._base)

    def step_async(self, actions: np.ndarray) -> None:
        if self._base is None:
            raise RuntimeError("call reset() before step()")
        self.last_actions = combine(self._base, actions, self.residual.scale, self.env_action_space)
        self.venv.step_async(self.last_actions)

    def step_wait(self):
        obs, reward, done, infos = self.venv.step_wait()
        done = np.asarray(done, dtype=bool)
        if self.residual.observe_base and done.any():
            # The terminal observations (value bootstrap of truncated episodes) get the base
            # action the finished episode's memory gives them; that memory is not kept.
            idx = [i for i in np.flatnonzero(done) if "terminal_observation" in infos[i]]
            if idx:
                last = np.array(obs, copy=True)
                last[idx] = np.stack([infos[i]["terminal_observation"] for i in idx])
                a_last, _ = self.baseline.predict(
                    last, state=self._state, episode_start=np.zeros(self.num_envs, dtype=bool)
                )
                aug = augment(last[idx], a_last[idx])
                for j, i in enumerate(idx):
                    infos[i]["terminal_observation"] = aug[j]
        self._base, self._state = self.baseline.predict(obs, state=self._state, episode_start=done)
        return self._observe(obs, self._base), reward, done, infos

    def manifest_record(self) -> dict[str, Any]:
        """The manifest's ``residual``: :meth:`ResidualSpec.record` and the raw observation space."""
        return {**self.residual.record(), "env_observation_space": space_to_dict(self.env_observation_space)}


def find_residual_env(venv: Any) -> ResidualVecEnv | None:
    """The :class:`ResidualVecEnv` in a chain of SB3 wrappers (``None``: there is none)."""
    while isinstance(venv, VecEnvWrapper):
        if isinstance(venv, ResidualVecEnv):
            return venv
        venv = venv.venv
    return None
