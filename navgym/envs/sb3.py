"""Adapter from a native navgym vector environment to stable-baselines3's ``VecEnv``.

SB3 does not accept Gymnasium vector envs: its ``VecEnv`` resets finished sub-environments
inside ``step_wait`` (same step) and reports the last observation as
``infos[i]["terminal_observation"]``. :class:`NavSB3VecEnv` drives the batched
:class:`~navgym.envs.core.NavCore` directly with those semantics, so training keeps the batched
speed. Importing this module needs stable-baselines3 (the ``agents`` extra).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvWrapper

from navgym.envs.base import NavVectorEnv, register_unwrapper
from navgym.envs.step_info import SB3_INFO_KEYS

__all__ = ["SB3_INFO_KEYS", "NavSB3VecEnv", "unwrap_sb3"]


class NavSB3VecEnv(VecEnv):
    """SB3 ``VecEnv`` over the batched core of a navgym vector env.

    Args:
        env: a :class:`NavVectorEnv` (``gym.make_vec(id, num_envs=B)``), or an env id.
        num_envs: number of sub-environments when ``env`` is an id.
        seed: base seed; sub-env i uses ``seed + i`` (as the Gymnasium vector env does).
        **kwargs: keyword arguments of the environment when ``env`` is an id.
    """

    def __init__(
        self, env: NavVectorEnv | str, num_envs: int = 1, seed: int | None = None, **kwargs: Any
    ) -> None:
        made = (
            gym.make_vec(env, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
            if isinstance(env, str)
            else env
        )
        base = made.unwrapped if isinstance(made, gym.vector.VectorEnv) else made
        if not isinstance(base, NavVectorEnv):
            raise ValueError(f"env must be a navgym native vector env; got {type(base).__name__}")
        self.venv = base
        self.core = base.core
        super().__init__(base.num_envs, base.single_observation_space, base.single_action_space)
        self._seeds: list[int | None] = [None] * self.num_envs
        if seed is not None:
            self.seed(seed)
        self._actions: np.ndarray | None = None
        self._started = False
        self.rngs = [seeding.np_random(s)[0] for s in self._seeds]

    # ------------------------------------------------------------------------------ VecEnv API
    def reset(self) -> np.ndarray:
        for i, s in enumerate(self._seeds):
            if s is not None:
                self.rngs[i] = seeding.np_random(s)[0]
        self._seeds = [None] * self.num_envs
        options = self._options[0] if self._options and self._options[0] else {}
        scen = options.get("scenario")
        obs = self.core.reset(np.arange(self.num_envs), self.rngs, [scen] * self.num_envs)
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._reset_options()
        self._started = True
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        if not self._started:
            raise RuntimeError("call reset() before step()")
        self._actions = actions  # validated by the task in step_wait (ValueError)

    def step_wait(self):
        if not self._started or self._actions is None:
            raise RuntimeError("call reset() and step_async() before step_wait()")
        a, self._actions = self._actions, None
        # (num_envs, *shape) as SB3 gives it; the task's check_action names anything else
        obs, reward, terminated, truncated, info = self.core.advance(a, self.rngs)
        done = terminated | truncated
        infos = info.sb3()
        for i in range(self.num_envs):
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        idx = np.flatnonzero(done)
        if idx.size:
            obs = obs.copy()
            for j in idx:
                infos[j]["terminal_observation"] = obs[j].copy()
            obs[idx] = self.core.reset(idx, [self.rngs[j] for j in idx], [None] * idx.size)
        return obs, reward.astype(np.float32), done, infos

    def close(self) -> None:
        return None

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        if seed is None:
            seed = int(np.random.SeedSequence().generate_state(1)[0])
        self._seeds = [seed + i for i in range(self.num_envs)]
        return self._seeds

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.venv, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        return [
            getattr(self.venv, method_name)(*method_args, **method_kwargs) for _ in self._get_indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]


def unwrap_sb3(env: Any) -> NavVectorEnv | None:
    """The navgym vector env under SB3's ``VecEnv`` wrappers and :class:`NavSB3VecEnv`, else None.

    Registered with :func:`navgym.envs.base.register_unwrapper` (``navigation_env`` sees through
    SB3's wrappers once this module is imported, as it is by whoever made one).
    """
    while isinstance(env, VecEnvWrapper):
        env = env.venv
    return env.venv if isinstance(env, NavSB3VecEnv) else None


register_unwrapper(unwrap_sb3)
