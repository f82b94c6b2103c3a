"""``navgym list``: the registry as a table (id, spaces, filter, episode length, reward, penalty)."""

from __future__ import annotations

import warnings
from typing import cast

import gymnasium as gym

from navgym.envs.base import navigation_env
from navgym.envs.registration import ENVIRONMENTS, register_all
from navgym.envs.tasks import ResampleTask
from navgym.tables import format_table


def registry_rows() -> list[list[object]]:
    """One row per registered id (those of :data:`~navgym.envs.registration.PLATFORM_GROUP` too).

    Ids whose platform module is not importable are marked.
    """
    register_all()
    rows: list[list[object]] = []
    for env_id, _module, _prefix, task, steps, _defaults in ENVIRONMENTS:
        try:
            with warnings.catch_warnings():  # "v0 is out of date" for ids that have a v1: listed anyway
                warnings.simplefilter("ignore", DeprecationWarning)
                env = gym.make(env_id)
        except ImportError as exc:  # platform module not available
            rows.append([env_id, task, "-", "-", "-", str(steps), f"unavailable: {exc}", "-"])
            continue
        core = navigation_env(env).core
        act = env.action_space
        if isinstance(act, gym.spaces.Discrete):
            act_s = f"Discrete({act.n})"
        else:
            box = cast(gym.spaces.Box, act)  # a navgym action space is Discrete or a Box
            act_s = f"Box({box.low[0]:g}, {box.high[0]:g}, {box.shape})"
        rows.append(
            [
                env_id,
                task,
                act_s,
                f"Box({core.obs_features.dim},)",
                core.task.filter_name,
                f"{steps} x {core.platform.dt:g} s",
                f"-min(err/{core.platform.error_scale_m:g} m, {core.reward_clip:g})"
                + (f" - {core.task.resample_cost:g}/resample" if isinstance(core.task, ResampleTask) else ""),
                f"-{core.divergence_penalty:g}"
                + (f" - {core.reward_clip:g}/step left" if core.penalize_remaining_steps else ""),
            ]
        )
        env.close()
    return rows


def print_registry() -> int:
    """Print the registry table; return 0."""
    headers = ["id", "task", "action space", "observation", "filter", "episode", "reward", "on divergence"]
    print(format_table(headers, registry_rows()))
    return 0
