"""Gymnasium spaces as a saved agent records them, and checking an environment against them.

A manifest (:mod:`agents.training.manifest`) stores the model's observation and action spaces
as JSON (:func:`space_to_dict`: type, shape, dtype, bounds / n); loading rebuilds them
(:func:`space_from_dict`) and compares them with the environment's (:func:`check_spaces`; the
message says which space differs and how). A frame-stacked model's observation space is
``n_stack`` frames of the environment's (:func:`unstacked_space`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from agents.training.agent_files import AgentLoadError

__all__ = [
    "check_spaces",
    "env_spaces",
    "space_difference",
    "space_from_dict",
    "space_summary",
    "space_to_dict",
    "unstacked_space",
]


def unstacked_space(space: Any, n_stack: int) -> Any:
    """The observation space of one frame of ``VecFrameStack``'s stacked Box ``space``.

    SB3 stacks a flat Box's bounds with ``np.repeat`` (each bound ``n_stack`` times in a row):
    every ``n_stack``-th bound is the frame's.
    """
    if n_stack == 1:
        return space
    if not isinstance(space, spaces.Box) or len(space.shape) != 1 or space.shape[0] % n_stack:
        raise AgentLoadError(f"cannot unstack {n_stack} frames of the observation space {space}")
    return spaces.Box(low=space.low[::n_stack], high=space.high[::n_stack], dtype=space.dtype)


def space_to_dict(space: Any) -> dict[str, Any]:
    """A JSON description of a Gymnasium space (Box, Discrete, MultiDiscrete, MultiBinary)."""
    if isinstance(space, spaces.Box):
        return {
            "type": "Box",
            "shape": list(space.shape),
            "dtype": str(space.dtype),
            "low": space.low.tolist(),
            "high": space.high.tolist(),
        }
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start), "dtype": str(space.dtype)}
    if isinstance(space, spaces.MultiDiscrete):
        return {
            "type": "MultiDiscrete",
            "nvec": np.asarray(space.nvec).tolist(),
            "start": np.asarray(space.start).tolist(),
            "dtype": str(space.dtype),
        }
    if isinstance(space, spaces.MultiBinary):
        return {"type": "MultiBinary", "n": np.asarray(space.n).tolist()}
    raise ValueError(f"cannot describe a {type(space).__name__} space in a manifest")


def space_from_dict(d: Mapping[str, Any]) -> Any:
    """The Gymnasium space of a :func:`space_to_dict` description."""
    try:
        kind = d["type"]
        if kind == "Box":
            dtype = np.dtype(d["dtype"])
            low = np.asarray(d["low"], dtype=dtype).reshape(d["shape"])
            high = np.asarray(d["high"], dtype=dtype).reshape(d["shape"])
            return spaces.Box(low=low, high=high, shape=tuple(d["shape"]), dtype=dtype)
        if kind == "Discrete":
            return spaces.Discrete(int(d["n"]), start=int(d.get("start", 0)))
        if kind == "MultiDiscrete":
            return spaces.MultiDiscrete(
                np.asarray(d["nvec"]), dtype=np.dtype(d.get("dtype", "int64")), start=d.get("start")
            )
        if kind == "MultiBinary":
            return spaces.MultiBinary(d["n"])
    except (KeyError, TypeError, ValueError) as e:
        raise AgentLoadError(f"invalid space description {dict(d)!r}: {type(e).__name__}: {e}") from e
    raise AgentLoadError(f"unknown space type {kind!r} in {dict(d)!r}")


def space_difference(expected: Any, actual: Any) -> str | None:
    """``None`` when two spaces are the same (type, shape, dtype, bounds / n), else what differs."""
    a = expected if isinstance(expected, Mapping) else space_to_dict(expected)
    b = actual if isinstance(actual, Mapping) else space_to_dict(actual)
    if a.get("type") != b.get("type"):
        return f"{a.get('type')} vs {b.get('type')}"
    for key in ("shape", "dtype", "n", "start", "nvec"):
        if a.get(key) != b.get(key):
            return f"{key} {a.get(key)} vs {b.get(key)}"
    for key in ("low", "high"):
        if key in a or key in b:
            x, y = np.asarray(a.get(key), dtype=float), np.asarray(b.get(key), dtype=float)
            if x.shape != y.shape or not np.array_equal(x, y):
                if x.shape == y.shape:
                    i = int(np.flatnonzero(x.ravel() != y.ravel())[0])
                    return f"{key} bound [{i}] {x.ravel()[i]:g} vs {y.ravel()[i]:g}"
                return f"{key} bounds {x.tolist()} vs {y.tolist()}"
    return None


def env_spaces(env: Any) -> tuple[Any, Any]:
    """``(observation space, action space)`` of one sub-environment of ``env``.

    ``env`` is a Gymnasium env, a Gymnasium vector env (its ``single_*`` spaces), an SB3
    ``VecEnv`` (whose spaces are a sub-environment's) or a registered env id (made once to read
    its spaces).
    """
    if isinstance(env, str):
        import navgym  # noqa: F401 - registers the environments
        from navgym.envs.registration import superseded_ids_quiet

        with superseded_ids_quiet():
            made = gym.make(env)
        try:
            return made.observation_space, made.action_space
        finally:
            made.close()
    if isinstance(env, gym.vector.VectorEnv):
        return env.single_observation_space, env.single_action_space
    return env.observation_space, env.action_space


def space_summary(space: Any) -> str:
    """A one-line description of a space (``Box(25,) float32``, ``Discrete(2)``)."""
    d = space if isinstance(space, Mapping) else space_to_dict(space)
    if d.get("type") == "Box":
        return f"Box{tuple(d['shape'])} {d['dtype']}"
    if d.get("type") == "Discrete":
        return f"Discrete({d['n']})"
    if d.get("type") == "MultiDiscrete":
        return f"MultiDiscrete({d['nvec']})"
    return f"{d.get('type')}({d.get('n')})"


def check_spaces(agent_obs: Any, agent_act: Any, env: Any, what: str) -> None:
    """``AgentLoadError`` when ``env``'s spaces are not the agent's (the message says which)."""
    obs, act = env_spaces(env)
    for name, mine, theirs in (("observation", agent_obs, obs), ("action", agent_act, act)):
        diff = space_difference(mine, theirs)
        if diff is not None:
            raise AgentLoadError(
                f"{what} was saved for the {name} space {space_summary(mine)}, the environment has "
                f"{space_summary(theirs)} ({diff})"
            )
