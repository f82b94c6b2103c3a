"""The tuned policies of the headroom study: the constant knob and the adaptive baselines.

Every candidate is grid-searched on tuning seeds only: a registered baseline of the task's
:func:`agents.baselines.registry.baseline_task` key through :func:`agents.tuning.tune`
(:func:`tune_spec`), and, where the task has no ``constant`` baseline, a grid of constant actions
(:func:`action_grid`) batched the same way (:func:`agents.tuning.search.score_points`,
:func:`tune_actions`). The score is the mean episode RMSE (``score="return"``: the mean return,
as :mod:`agents.tuning`); ties go to the first point in grid order.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces

from agents import tuning
from agents.baselines import ConstantAction, make_baseline
from agents.baselines.registry import BASELINES, BaselineSpec, baseline_task
from agents.evaluation.runner import make_vector_env
from agents.seeds import check_seeds
from navgym.envs.base import navigation_env

__all__ = [
    "ACTION_LEVELS",
    "Candidate",
    "action_grid",
    "candidates",
    "small_grid",
    "tune_actions",
    "tune_grid",
    "tune_spec",
]

#: Levels per action component of the constant-action grid (tasks without a ``constant`` baseline).
ACTION_LEVELS = 9


def action_grid(space: spaces.Space, neutral: Any, levels: int = ACTION_LEVELS) -> np.ndarray:
    """Constant actions to search when the task has no ``constant`` baseline, neutral first.

    Discrete: every action. Box: ``levels`` values from low to high per component, the product
    over components for one or two components and the same value on every component beyond
    (a product would explode). The neutral action is always a point.
    """
    neutral = np.asarray(neutral)
    if isinstance(space, spaces.Discrete):
        pts = [int(neutral.reshape(-1)[0])] + [int(space.start) + i for i in range(int(space.n))]
        return np.array(list(dict.fromkeys(pts)), dtype=np.int64)
    shape = tuple(space.shape)
    low = np.broadcast_to(np.asarray(space.low, dtype=np.float64), shape).reshape(-1)
    high = np.broadcast_to(np.asarray(space.high, dtype=np.float64), shape).reshape(-1)
    axes = [np.linspace(lo, hi, levels) for lo, hi in zip(low, high, strict=True)]
    if len(axes) <= 2:
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(axes))
    else:
        pts = np.linspace(low, high, levels)
    pts = np.concatenate([neutral.astype(np.float64).reshape(1, -1), pts])
    _, first = np.unique(np.round(pts, 12), axis=0, return_index=True)
    return pts[np.sort(first)].reshape(-1, *shape).astype(np.float32)


@dataclass
class Candidate:
    """A tuned policy: what was tuned, its best point and how to build it for an env."""

    name: str
    role: str  #: "constant" or "adaptive"
    source: str  #: where the policy comes from
    params: dict[str, Any]
    tune_rmse: float
    tune_return: float
    tune_diverged: float
    grid_size: int
    build: Callable[[Any], Any] = field(repr=False)
    seconds: float = 0.0


def _best(rows: Sequence[Mapping[str, Any]], score: str, key: str = "rmse_m") -> int:
    """Index of the best grid row (ties: the first in grid order); ``key``: the RMSE column."""
    if score == "rmse":
        return min(range(len(rows)), key=lambda i: (rows[i][key], i))
    return max(range(len(rows)), key=lambda i: (rows[i]["mean_return"], -i))


def small_grid(grid: Mapping[str, Sequence[float]]) -> dict[str, tuple[float, ...]]:
    """The first and last value of each parameter (the quick mode's grids)."""
    return {k: tuple(dict.fromkeys((v[0], v[-1]))) for k, v in grid.items()}


def tune_spec(
    env_id: str,
    spec: BaselineSpec,
    role: str,
    *,
    n_tune: int,
    tune_offset: int,
    env_kwargs: Mapping[str, Any],
    score: str,
    quick: bool,
    max_batch: int | None,
    key: str = "rmse_m",
) -> Candidate:
    """Grid search of a registered baseline on tuning seeds (:func:`agents.tuning.tune`)."""
    grid = small_grid(spec.grid) if quick else dict(spec.grid)
    res = tuning.tune(
        env_id,
        spec.name,
        grid,
        episodes=n_tune,
        seed_offset=tune_offset,
        env_kwargs=env_kwargs,
        max_batch=max_batch,
        progress=False,
    )
    rows = res["grid"]
    b = rows[_best(rows, score, key)]
    params = dict(b["params"])
    name = spec.name
    return Candidate(
        name,
        role,
        "agents.baselines",
        params,
        b[key],
        b["mean_return"],
        b["diverged"],
        len(rows),
        lambda env: make_baseline(env, name, **params),
        res["seconds"],
    )


def tune_grid(
    env_id: str,
    points: Sequence[Any],
    make_policy: Callable[[Any, Sequence[Any], int], Any],
    *,
    tune_seeds: Sequence[int],
    env_kwargs: Mapping[str, Any],
    max_batch: int | None,
) -> list[dict[str, Any]]:
    """Score grid ``points`` on the tuning seeds, batched like :func:`agents.tuning.tune`.

    ``make_policy(env, chunk, n)`` builds the policy of a chunk of points for a vector env of
    ``len(chunk) * n`` sub-envs (point-major; :func:`agents.tuning.search.score_points`). Returns
    one row per point: ``{"point", "mean_return", "rmse_m", "scored_rmse_m", "diverged"}``.
    """
    check_seeds("tune", tune_seeds)
    scores = tuning.score_points(
        env_id, points, make_policy, tune_seeds, env_kwargs=env_kwargs, max_batch=max_batch
    )
    return [{"point": p, **r} for p, r in zip(points, scores, strict=True)]


def tune_actions(
    env_id: str,
    actions: np.ndarray,
    *,
    tune_seeds: Sequence[int],
    env_kwargs: Mapping[str, Any],
    score: str,
    max_batch: int | None,
    key: str = "rmse_m",
) -> Candidate:
    """Grid search of constant actions (:func:`action_grid`) on the tuning seeds."""
    t0 = time.perf_counter()

    def make(env: Any, chunk: Sequence[np.ndarray], n: int) -> ConstantAction:
        return ConstantAction(navigation_env(env).task.action_space, np.repeat(np.asarray(chunk), n, axis=0))

    rows = tune_grid(
        env_id, list(actions), make, tune_seeds=tune_seeds, env_kwargs=env_kwargs, max_batch=max_batch
    )
    b = rows[_best(rows, score, key)]
    action = np.asarray(b["point"])
    return Candidate(
        "constant",
        "constant",
        f"grid of {len(rows)} constant actions (here)",
        {"action": np.round(action.astype(np.float64), 4).tolist()},
        b[key],
        b["mean_return"],
        b["diverged"],
        len(rows),
        lambda env: ConstantAction(navigation_env(env).task.action_space, action, "constant"),
        round(time.perf_counter() - t0, 1),
    )


def candidates(
    env_id: str,
    *,
    tune_seeds: Sequence[int],
    tune_offset: int,
    env_kwargs: Mapping[str, Any],
    score: str,
    quick: bool,
    action_levels: int,
    max_batch: int | None,
    error_key: str = "rmse_m",
) -> tuple[list[Candidate], list[str]]:
    """The tuned constant knob and tuned adaptive baselines of ``env_id``; notes on what is missing."""
    probe = make_vector_env(env_id, 1, env_kwargs)
    task = navigation_env(probe).task
    space, neutral = task.action_space, task.neutral_action()
    key = baseline_task(probe)  # the task's name; "RowMixture" for a per-row Mixture task
    probe.close()
    specs = BASELINES.get(key, {})
    notes: list[str] = []
    out: list[Candidate] = []
    common = {
        "n_tune": len(tune_seeds),
        "tune_offset": tune_offset,
        "env_kwargs": env_kwargs,
        "score": score,
        "quick": quick,
        "max_batch": max_batch,
        "key": error_key,
    }
    for name, spec in specs.items():
        if not spec.tunable:
            continue  # plain, zero, nominal, never, always: fixed (plain is evaluated anyway)
        role = "constant" if name == "constant" else "adaptive"
        try:
            out.append(tune_spec(env_id, spec, role, **common))
        except Exception as exc:  # a baseline of the task that does not fit this id's layout
            notes.append(f"baseline `{name}` of agents/baselines does not run on {env_id}: {exc!r}")
    if not any(c.role == "constant" for c in out):
        if "constant" not in specs:
            notes.append(
                f"agents/baselines has no `constant` baseline for {key}: constant actions tuned here"
            )
        grid = action_grid(space, neutral, action_levels)
        out.insert(
            0,
            tune_actions(
                env_id,
                grid,
                tune_seeds=tune_seeds,
                env_kwargs=env_kwargs,
                score=score,
                max_batch=max_batch,
                key=error_key,
            ),
        )
    if not any(c.role == "adaptive" for c in out):
        notes.append(
            f"no classical adaptive baseline of agents/baselines runs on {env_id} (baselines key {key}): "
            "missing; the best tuned baseline is the constant knob alone."
        )
    return out, notes
