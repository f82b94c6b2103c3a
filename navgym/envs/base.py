"""Gymnasium shells over :class:`~navgym.envs.core.NavCore`: single env and native vector env.

Both follow the environment contracts of ``DESIGN.md``: observation from the estimator only
(truth goes to ``info``), float32 ``Box`` actions in [-1, 1] or ``Discrete``, non-finite actions
raise ``ValueError``, determinism from per-environment generators. The vector env autoresets in
Gymnasium's ``NEXT_STEP`` mode.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv

from navgym.envs.core import NavCore

#: Keys of the core's info copied into a single env's info (arrays lose the batch axis).
INFO_KEYS_SCALAR = (
    "pos_err_m",
    "nees",
    "nis",
    "n_meas",
    "healthy",
    "diverged",
    "gnss_available",
    "knob",
    "action_clipped",
    "t",
)


def _single_info(info: dict[str, np.ndarray], i: int, scenario: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in info.items():
        x = v[i]
        out[k] = x.item() if np.ndim(x) == 0 else x
    out["reward_terms"] = {
        "accuracy": out.pop("reward_accuracy"),
        "cost": out.pop("reward_cost"),
        "divergence_penalty": out.pop("reward_penalty"),
    }
    out["scenario"] = scenario
    return out


class NavEnv(gym.Env):
    """Single navigation environment: a :class:`NavCore` with B = 1 (see the platform cards)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

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
        self._needs_reset = True

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        scenario = (options or {}).get("scenario")
        obs = self.core.reset(np.array([0]), [self.np_random], [scenario])
        self._needs_reset = False
        self._history = []
        info = {"scenario": self.core.scenarios[0]}
        return obs[0], info

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("call reset() before step()")
        # the task validates the action (ValueError) before the core changes anything
        obs, reward, terminated, truncated, info = self.core.step(np.asarray(action)[None], [self.np_random])
        single = _single_info(info, 0, self.core.scenarios[0])
        if self.render_mode is not None:
            self._history.append(
                {k: single[k] for k in ("truth_pos", "est_pos", "gnss_available", "pos_err_m", "cov_ne")}
            )
        if terminated[0] or truncated[0]:
            self._needs_reset = True
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), single

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        from navgym.envs.rendering import render_track

        return render_track(self._history, self.core.platform.name)

    def __getstate__(self):
        return self.__dict__.copy()


class NavVectorEnv(VectorEnv):
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
        scenarios = (options or {}).get("scenario")
        if scenarios is None or not isinstance(scenarios, (list, tuple)):
            scenarios = [scenarios] * B
        obs = self.core.reset(np.arange(B), self.rngs, scenarios)
        self._autoreset[:] = False
        self._started = True
        return obs, {"scenario": np.array(self.core.scenarios, dtype=object)}

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(actions)
        self.core.validate_action(a)  # before the autoreset draws anything (ValueError)
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
        obs, reward, terminated, truncated, info = self.core.step(a, rngs)
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
        infos: dict[str, Any] = {}
        valid = np.ones(self.num_envs, dtype=bool)
        valid[reset_idx] = False
        for k, v in info.items():
            infos[k] = v
            infos["_" + k] = valid
        return obs, reward, terminated, truncated, infos
