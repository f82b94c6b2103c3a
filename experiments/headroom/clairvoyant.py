"""The clairvoyant reference of the v2 ids, played on the same episodes as the policies.

The clairvoyant filter is the task's neutral action (the plain filter) on the env made with
:data:`CLAIRVOYANT` (``clairvoyant=True``: the filter told the step's true Q, R and measurement
bias; it reads truth, an upper reference, never a baseline). :func:`clairvoyant_episodes` plays
it, :func:`same_episodes` checks that its env replays the plain env's episodes (so the
comparison is paired), :func:`play_policies` plays any policies on the same episodes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

import navgym  # noqa: F401  (registers the ids)
from agents.baselines import ConstantAction
from agents.evaluation.metrics import episode_metrics
from agents.evaluation.runner import make_vector_env, rollout
from navgym.envs.base import navigation_env
from navgym.envs.distinct import EpisodeCache
from navgym.envs.registration import ENVIRONMENTS

__all__ = ["CLAIRVOYANT", "clairvoyant_episodes", "play_policies", "same_episodes", "v2_ids"]

#: What turns an env into its clairvoyant reference.
CLAIRVOYANT = {"clairvoyant": True}


def v2_ids() -> list[str]:
    """Registered ids ending in ``-v2`` (registry order)."""
    return [e[0] for e in ENVIRONMENTS if e[0].endswith("-v2")]


def play_policies(
    env_id: str, policies: Mapping[str, Any], seeds: Sequence[int], env_kwargs: Mapping[str, Any]
) -> dict[str, dict[str, np.ndarray]]:
    """Per-episode metrics ``{policy: {metric: (B,)}}`` of every policy on the same episodes
    (simulated once: :class:`navgym.envs.distinct.EpisodeCache`)."""
    env = make_vector_env(env_id, len(seeds), env_kwargs)
    divergence_m = float(navigation_env(env).platform.divergence_m)
    cache = EpisodeCache(maxsize=1)
    out = {}
    for name, p in policies.items():
        with cache.active():
            roll = rollout(env, p, seeds)
        out[name] = episode_metrics(roll, divergence_m)
    env.close()
    return out


def clairvoyant_episodes(
    env_id: str,
    env_kwargs: Mapping[str, Any],
    seeds: Sequence[int],
    clairvoyant_kwargs: Mapping[str, Any] = CLAIRVOYANT,
) -> tuple[dict[str, np.ndarray], bool]:
    """Per-episode metrics of the clairvoyant filter on ``seeds``, and whether it is paired.

    The clairvoyant is the task's neutral action (the plain filter) on the env made with
    ``clairvoyant_kwargs`` over ``env_kwargs``; the flag says whether that env replays the same
    episodes as the plain one (:func:`same_episodes` on the first two seeds).
    """
    layout = make_vector_env(env_id, 1, dict(env_kwargs))
    task = navigation_env(layout).task
    clair = ConstantAction(task.action_space, task.neutral_action(), "clairvoyant")
    layout.close()
    episodes = play_policies(env_id, {"clairvoyant": clair}, seeds, {**env_kwargs, **clairvoyant_kwargs})
    return episodes["clairvoyant"], same_episodes(env_id, env_kwargs, clairvoyant_kwargs, list(seeds)[:2])


def same_episodes(
    env_id: str, env_kwargs: Mapping[str, Any], clairvoyant_kwargs: Mapping[str, Any], seeds: Sequence[int]
) -> bool:
    """Whether the clairvoyant env plays the same episodes (scenario, truth) as the plain one."""
    ok = True
    for s in seeds:
        envs = [
            gym.make(env_id, **dict(env_kwargs)),
            gym.make(env_id, **{**env_kwargs, **clairvoyant_kwargs}),
        ]
        infos = [e.reset(seed=int(s))[1] for e in envs]
        ok &= repr(infos[0].get("scenario")) == repr(infos[1].get("scenario"))
        neutral = navigation_env(envs[0]).task.neutral_action()
        for _ in range(3):
            steps = [e.step(neutral) for e in envs]
            t0, t1 = (st[4].get("truth_pos") for st in steps)
            if t0 is not None and t1 is not None:
                ok &= bool(np.array_equal(np.asarray(t0), np.asarray(t1)))
        for e in envs:
            e.close()
    return bool(ok)
