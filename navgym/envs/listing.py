"""``navgym list``: the registry as a table (id, spaces, filter, episode length, reward, penalty, status).

The status column marks the superseded ids and, among the v3 ids, those worth training on: the
ones that passed gate G1 (:func:`navgym.envs.ids.status`).
"""

from __future__ import annotations

import warnings
from typing import cast

import gymnasium as gym

from navgym.envs.base import navigation_env
from navgym.envs.ids import status
from navgym.envs.registration import ENVIRONMENTS, register_all
from navgym.envs.tasks import ResampleTask
from navgym.tables import format_table


def registry_rows() -> list[list[object]]:
    """One row per registered id (those of :data:`~navgym.envs.registration.PLATFORM_GROUP` too).

    Ids whose platform module is not importable are marked.
    """
    register_all()
    ids = [e.id for e in ENVIRONMENTS]
    rows: list[list[object]] = []
    for env_id, _module, _prefix, task, steps, _defaults in ENVIRONMENTS:
        try:
            with warnings.catch_warnings():  # "v0 is out of date" for ids that have a v1: listed anyway
                warnings.simplefilter("ignore", DeprecationWarning)
                env = gym.make(env_id)
        except ImportError as exc:  # platform module not available
            rows.append([env_id, task, "-", "-", "-", str(steps), f"unavailable: {exc}", "-", "-"])
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
                status(env_id, ids),
            ]
        )
        env.close()
    return rows


HEADERS = [
    "id", "task", "action space", "observation", "filter", "episode", "reward", "on divergence", "status",
]  # fmt: skip


def _matches(row: list[object], pattern: str) -> bool:
    """Whether ``pattern`` (a substring, or a glob with ``*?[``) matches the id or the task."""
    import fnmatch

    p = pattern.lower()
    fields = [str(row[0]).lower(), str(row[1]).lower()]
    if any(c in p for c in "*?["):
        return any(fnmatch.fnmatchcase(f, p) for f in fields)
    return any(p in f for f in fields)


def print_registry(as_json: bool = False, pattern: str | None = None) -> int:
    """Print the registry table (or JSON objects keyed by :data:`HEADERS`); return 0.

    ``pattern``: only the ids whose id or task contains it (or matches it, a glob), case-insensitive.
    """
    rows = [r for r in registry_rows() if pattern is None or _matches(r, pattern)]
    if as_json:
        import json

        keys = [h.replace(" ", "_") for h in HEADERS]
        print(json.dumps([dict(zip(keys, (str(v) for v in r), strict=True)) for r in rows], indent=1))
    else:
        print(format_table(HEADERS, rows))
    return 0
