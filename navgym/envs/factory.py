"""Keyword arguments shared by every navgym environment, and the core they build.

Each platform module defines ``make_platform(**platform_kwargs)``; :func:`split_kwargs` separates
the keyword arguments common to all environments (task, filter, episode length, reward) from
the platform's own ones (scenario distribution, IMU grade, ...).
"""

from __future__ import annotations

from typing import Any

from navgym.envs.core import NavCore
from navgym.envs.tasks import make_task


class UnknownKeywordError(TypeError, ValueError):
    """Unknown keyword arguments of an environment or a baseline.

    A ``TypeError`` as Python raises for unexpected keyword arguments, and a ``ValueError`` so
    that command lines report it as the user's input error in one line (``navgym.cli``).
    """


#: Task-related keyword arguments and the task option they set.
TASK_KWARGS = {
    "fading": ("filter", "lambda_max"),
    "mixture": ("filter", "eps_max", "variance_ratio"),
    "resample": ("n_particles", "resample_cost", "method", "roughening", "log_ess_feature", "particle_dtype"),
}
CORE_KWARGS = (
    "max_episode_steps",
    "reward_clip",
    "divergence_penalty",
    "penalize_remaining_steps",
    "eval_info",
)


def build_core(
    platform: Any, task: str, num_envs: int, kwargs: dict[str, Any], episode_steps: int
) -> NavCore:
    """A :class:`NavCore` for ``platform`` and ``task`` from the remaining keyword arguments.

    ``episode_steps`` is the simulated horizon (truth, scenario timing); ``max_episode_steps``
    (when given, as ``gym.make_vec`` does) only truncates earlier. ``gym.make`` keeps
    ``max_episode_steps`` for its ``TimeLimit`` wrapper, so a single env and a vector env built
    with the same keyword arguments simulate identical episodes.
    """
    task_opts = {k: kwargs.pop(k) for k in TASK_KWARGS[task.lower()] if k in kwargs}
    core_opts = {k: kwargs.pop(k) for k in CORE_KWARGS if k in kwargs}
    if kwargs:
        raise UnknownKeywordError(f"unexpected keyword arguments: {sorted(kwargs)}")
    truncate = core_opts.pop("max_episode_steps", None)
    return NavCore(
        platform, make_task(task, **task_opts), num_envs, episode_steps, truncate_steps=truncate, **core_opts
    )
