"""``python -m experiments.headroom [--env ID ...] [--tune-episodes 256] [--episodes 256] [--quick]``.

The headroom gate of issue #21: is there room for a learned knob on the v2 ids? For each id
(default: every registered ``-v2`` id), on the same held-out episodes (evaluation seeds of
:mod:`agents.seeds`):

* ``plain``: the plain filter (the task's neutral action every step);
* the best tuned **constant** knob (the ``constant`` baseline of the task's
  :func:`agents.baselines.registry.baseline_task` key, else a grid of constant actions here);
* every tuned classical **adaptive** baseline of that key in :mod:`agents.baselines`;
* the **clairvoyant** filter (env keyword ``clairvoyant=True``: the plain filter told the
  step's true Q, R and measurement bias; reads truth, an upper reference, never a baseline).

Every tuned policy is grid-searched on tuning seeds only (:func:`agents.tuning.tune`; the same
batching here for a constant-action grid), scored by
the mean episode RMSE (``--score return``: the mean return, as :mod:`agents.tuning`). The best
tuned baseline is the one with the best tuning score, evaluated on the held-out episodes;
``headroom = (RMSE_base - RMSE_clairvoyant) / RMSE_base`` (RMSE: the mean over episodes of each
episode's horizontal position RMSE), with a paired percentile-bootstrap CI over episodes. An id
passes when the headroom is at least 20 % and its CI excludes 0.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

import navgym  # noqa: F401  (registers the ids)
from agents import tuning
from agents.baselines import make_baseline
from agents.baselines.registry import BASELINES, BaselineSpec, baseline_task
from agents.evaluation.bootstrap import (
    DEFAULT_LEVEL,
    DEFAULT_RESAMPLES,
    bootstrap_mean_ci,
    paired_difference,
    paired_statistic_ci,
)
from agents.evaluation.metrics import episode_metrics
from agents.evaluation.report import git_commit
from agents.evaluation.runner import make_vector_env, rollout
from agents.seeds import check_seeds
from agents.seeds import seeds as seed_range
from experiments.outputs import markdown_table, write_csv, write_manifest
from navgym.envs.base import navigation_env
from navgym.envs.registration import ENVIRONMENTS

#: Tasks the gate of #21 applies to (other tasks are reported, not gated; Robust and Jumps: #26).
GATED_TASKS = ("Fading", "NoiseScale", "Mixture", "Robust", "Jumps")
#: The error a run is tuned and gated on (``--error``): the position error alone, or the error the
#: reward charges (position plus the platform's extra error: Jpa's weighted attitude error,
#: SignalTracking's weighted Doppler error; :func:`agents.evaluation.metrics.episode_metrics`).
ERROR_METRICS = {"position": "rmse_m", "scored": "scored_rmse_m"}
#: Smallest headroom that passes (its CI must also exclude 0).
GATE = 0.20
#: Offsets into the tuning and evaluation seed ranges (agents.tuning and navgym eval use 0 too).
TUNE_OFFSET = 0
EVAL_OFFSET = 0
#: What turns an env into its clairvoyant reference.
CLAIRVOYANT = {"clairvoyant": True}
#: Levels per action component of the constant-action grid (tasks without a ``constant`` baseline).
ACTION_LEVELS = 9
#: The quick mode (the test): short episodes, few of them, tiny grids.
QUICK = {"tune_episodes": 8, "episodes": 8, "steps": 40, "n_boot": 200, "action_levels": 3}


# ------------------------------------------------------------------------------------- seeds
def v2_ids() -> list[str]:
    """Registered ids ending in ``-v2`` (registry order)."""
    return [e[0] for e in ENVIRONMENTS if e[0].endswith("-v2")]


def study_seeds(
    n_tune: int, n_eval: int, tune_offset: int = TUNE_OFFSET, eval_offset: int = EVAL_OFFSET
) -> tuple[list[int], list[int]]:
    """Tuning and held-out seeds (:mod:`agents.seeds`), checked against their ranges and disjoint."""
    tune, held = seed_range("tune", n_tune, tune_offset), seed_range("eval", n_eval, eval_offset)
    check_seeds("tune", tune)
    check_seeds("eval", held)
    if set(tune) & set(held):  # the ranges are disjoint; this guards against changes to them
        raise ValueError("tuning and evaluation seeds overlap")
    return tune, held


# ---------------------------------------------------------------------------------- headroom
def headroom(
    baseline: np.ndarray,
    clairvoyant: np.ndarray,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    seed: int = 0,
) -> dict[str, Any]:
    """``(mean(baseline) - mean(clairvoyant)) / mean(baseline)`` with its paired bootstrap CI.

    ``baseline`` and ``clairvoyant`` are per-episode RMSEs on the *same* episodes (pairs with a
    non-finite value are dropped); the CI is
    :func:`agents.evaluation.bootstrap.paired_statistic_ci`'s (episodes resampled as pairs, the
    ratio recomputed, its ``(1 -+ level)/2`` quantiles). NaN when ``mean(baseline) <= 0``.

    Returns:
        ``{"headroom", "low", "high", "n", "significant", "baseline_rmse", "clairvoyant_rmse"}``
        (``significant``: the CI excludes 0).
    """
    b = np.asarray(baseline, dtype=np.float64).ravel()
    c = np.asarray(clairvoyant, dtype=np.float64).ravel()
    h, lo, hi, n = paired_statistic_ci(
        (b, c), lambda m: np.where(m[..., 0] > 0, 1.0 - m[..., 1] / m[..., 0], np.nan), n_boot, level, seed
    )
    ok = np.isfinite(b) & np.isfinite(c)
    nan = float("nan")
    return {
        "headroom": h,
        "low": lo,
        "high": hi,
        "n": n,
        "significant": bool(n > 1 and (lo > 0 or hi < 0)),
        "baseline_rmse": float(b[ok].mean()) if n else nan,
        "clairvoyant_rmse": float(c[ok].mean()) if n else nan,
    }


def passes(h: Mapping[str, Any], threshold: float = GATE) -> bool:
    """The gate of #21: headroom >= ``threshold`` and its CI above 0."""
    return bool(np.isfinite(h["headroom"]) and h["headroom"] >= threshold and h["low"] > 0)


# --------------------------------------------------------------------------------- policies
class ConstantAction:
    """The same action every step: ``(G, *shape)`` actions, one per sub-env (G = B) or one for all.

    ``ConstantAction(space, task.neutral_action())`` is the plain filter; a batch of different
    actions runs a whole grid of constant knobs in one rollout.
    """

    is_baseline = True
    uses_truth = False

    def __init__(self, space: spaces.Space, action: Any, name: str = "constant action") -> None:
        self.name = name
        self.discrete = isinstance(space, spaces.Discrete)
        a = np.asarray(action)
        if self.discrete:
            self.actions = a.astype(np.int64).reshape(-1)
        else:
            shape = tuple(space.shape)
            self.actions = a.astype(np.float32).reshape(-1, *shape)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        obs = np.asarray(observation)
        if obs.ndim == 1:
            return self.actions[0].copy(), state
        B, G = obs.shape[0], self.actions.shape[0]
        if G not in (1, B):
            raise ValueError(f"{G} constant actions for a batch of {B}")
        return np.broadcast_to(self.actions, (B, *self.actions.shape[1:])).copy(), state

    def describe(self) -> dict[str, Any]:
        a = self.actions[0] if len(self.actions) == 1 else self.actions
        return {"name": self.name, "class": f"{__name__}.ConstantAction", "params": {"action": a.tolist()}}


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


def play_policies(
    env_id: str, policies: Mapping[str, Any], seeds: Sequence[int], env_kwargs: Mapping[str, Any]
) -> dict[str, dict[str, np.ndarray]]:
    """Per-episode metrics ``{policy: {metric: (B,)}}`` of every policy on the same episodes."""
    env = make_vector_env(env_id, len(seeds), env_kwargs)
    divergence_m = float(navigation_env(env).platform.divergence_m)
    out = {name: episode_metrics(rollout(env, p, seeds), divergence_m) for name, p in policies.items()}
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
    ``len(chunk) * n`` sub-envs (point-major). Returns one row per point:
    ``{"point", "mean_return", "rmse_m", "scored_rmse_m", "diverged"}``.
    """
    check_seeds("tune", tune_seeds)
    n = len(tune_seeds)
    probe = make_vector_env(env_id, 1, env_kwargs)
    nav = navigation_env(probe)
    divergence_m = float(nav.platform.divergence_m)
    probe.close()
    mb = max_batch or tuning.MAX_BATCH.get(nav.task.name, tuning.DEFAULT_MAX_BATCH)
    per_chunk = max(1, mb // n)
    rows = []
    for i in range(0, len(points), per_chunk):
        chunk = points[i : i + per_chunk]
        G = len(chunk)
        env = make_vector_env(env_id, G * n, env_kwargs)
        roll = rollout(env, make_policy(env, chunk, n), list(tune_seeds) * G)
        m = episode_metrics(roll, divergence_m)
        env.close()
        for g in range(G):
            sl = slice(g * n, (g + 1) * n)
            rows.append(
                {
                    "point": chunk[g],
                    "mean_return": float(np.mean(m["return"][sl])),
                    "rmse_m": float(np.mean(m["rmse_m"][sl])),
                    "scored_rmse_m": float(np.mean(m["scored_rmse_m"][sl])),
                    "diverged": float(np.mean(m["diverged"][sl])),
                }
            )
    return rows


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


# ------------------------------------------------------------------------------------ study
def study_env(
    env_id: str,
    *,
    tune_seeds: Sequence[int],
    eval_seeds: Sequence[int],
    tune_offset: int = TUNE_OFFSET,
    env_kwargs: Mapping[str, Any] | None = None,
    clairvoyant_kwargs: Mapping[str, Any] = CLAIRVOYANT,
    score: str = "rmse",
    quick: bool = False,
    action_levels: int = ACTION_LEVELS,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    max_batch: int | None = None,
    threshold: float = GATE,
    error: str = "position",
) -> dict[str, Any]:
    """Tune, evaluate and gate one id: ``{"rows", "gate", "notes", "tuned", "seconds"}``.

    ``error``: a key of :data:`ERROR_METRICS`, the error tuned, compared and gated on.
    """
    if error not in ERROR_METRICS:
        raise ValueError(f"error must be one of {sorted(ERROR_METRICS)}; got {error!r}")
    key = ERROR_METRICS[error]
    t0 = time.perf_counter()
    env_kwargs = dict(env_kwargs or {})
    cands, notes = candidates(
        env_id,
        tune_seeds=tune_seeds,
        tune_offset=tune_offset,
        env_kwargs=env_kwargs,
        score=score,
        quick=quick,
        action_levels=action_levels,
        max_batch=max_batch,
        error_key=key,
    )
    layout = make_vector_env(env_id, 1, env_kwargs)
    task = navigation_env(layout).task
    task_name = str(task.name)
    policies: dict[str, Any] = {"plain": ConstantAction(task.action_space, task.neutral_action(), "plain")}
    for c in cands:
        policies[c.name] = c.build(layout)
    layout.close()
    check_seeds("eval", eval_seeds)
    episodes = play_policies(env_id, policies, eval_seeds, env_kwargs)
    episodes["clairvoyant"], paired_ok = clairvoyant_episodes(
        env_id, env_kwargs, eval_seeds, clairvoyant_kwargs
    )
    if not paired_ok:
        notes.append("the clairvoyant env does not replay the same episodes: the comparison is not paired")
    rmse = {name: m[key] for name, m in episodes.items()}
    diverged = {name: m["diverged"] for name, m in episodes.items()}
    by_name = {c.name: c for c in cands}
    best = min(cands, key=lambda c: c.tune_rmse if score == "rmse" else -c.tune_return)
    rows = []
    for i, name in enumerate(rmse):
        c = by_name.get(name)
        mean, lo, hi, _ = bootstrap_mean_ci(rmse[name], n_boot, level, seed=100 * i)
        d = (
            paired_difference(rmse[name], rmse["plain"], n_boot, level, seed=100 * i + 1)
            if name != "plain"
            else None
        )
        role = "plain" if name == "plain" else "clairvoyant" if name == "clairvoyant" else c.role
        note = ""
        if c is not None and d is not None and d["mean_diff"] > 0:
            note = "worse than plain out of sample" + (" (CI excludes 0)" if d["significant"] else "")
        rows.append(
            {
                "env": env_id,
                "task": task_name,
                "policy": name,
                "role": role,
                "best_tuned": name == best.name,
                "params": json.dumps(c.params) if c is not None else "",
                "grid_points": c.grid_size if c is not None else 0,
                "tune_rmse_m": c.tune_rmse if c is not None else float("nan"),
                "rmse_m": mean,
                "rmse_lo": lo,
                "rmse_hi": hi,
                "d_rmse_vs_plain_m": d["mean_diff"] if d else 0.0,
                "d_rmse_vs_plain_lo": d["low"] if d else 0.0,
                "d_rmse_vs_plain_hi": d["high"] if d else 0.0,
                "d_rmse_vs_plain_significant": bool(d["significant"]) if d else False,
                "diverged_pct": 100.0 * float(np.mean(diverged[name])),
                "note": note,
            }
        )
    h = headroom(rmse[best.name], rmse["clairvoyant"], n_boot, level, seed=7)
    held_best = min(cands, key=lambda c: float(np.mean(rmse[c.name])))
    h_held = headroom(rmse[held_best.name], rmse["clairvoyant"], n_boot, level, seed=8)
    gated = task_name in GATED_TASKS
    ok = passes(h, threshold)
    if held_best.name != best.name:
        notes.append(
            f"the best on the tuning episodes (`{best.name}`) is not the best on the held-out ones "
            f"(`{held_best.name}`; headroom against it {100 * h_held['headroom']:.1f} %)"
        )
    gate = {
        "env": env_id,
        "task": task_name,
        "error": error,
        "best_tuned_baseline": best.name,
        "baseline_rmse_m": h["baseline_rmse"],
        "clairvoyant_rmse_m": h["clairvoyant_rmse"],
        "headroom_pct": 100.0 * h["headroom"],
        "headroom_lo_pct": 100.0 * h["low"],
        "headroom_hi_pct": 100.0 * h["high"],
        "headroom_vs_heldout_best_pct": 100.0 * h_held["headroom"],
        "adaptive_baselines": " ".join(c.name for c in cands if c.role == "adaptive") or "none",
        "paired": paired_ok,
        "episodes": h["n"],
        "verdict": ("PASS" if ok else "FAIL") if gated else "not gated",
    }
    tuned = {
        c.name: {
            "role": c.role,
            "source": c.source,
            "params": c.params,
            "grid_points": c.grid_size,
            "tune_rmse_m": c.tune_rmse,
            "tune_return": c.tune_return,
            "tune_diverged": c.tune_diverged,
            "seconds": c.seconds,
        }
        for c in cands
    }
    return {"rows": rows, "gate": gate, "notes": notes, "tuned": tuned, "seconds": time.perf_counter() - t0}


# ----------------------------------------------------------------------------------- report
def _ci(x: float, lo: float, hi: float, digits: int = 3) -> str:
    return f"{x:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def policy_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """Markdown table of one id's policies."""
    md = []
    for r in rows:
        d = (
            "-"
            if r["policy"] == "plain"
            else _ci(r["d_rmse_vs_plain_m"], r["d_rmse_vs_plain_lo"], r["d_rmse_vs_plain_hi"])
            + ("*" if r["d_rmse_vs_plain_significant"] else "")
        )
        md.append(
            {
                "policy": r["policy"] + (" (best tuned)" if r["best_tuned"] else ""),
                "role": r["role"],
                "tuned params": r["params"] or "-",
                "tuning RMSE m": "-" if not np.isfinite(r["tune_rmse_m"]) else f"{r['tune_rmse_m']:.3f}",
                "held-out RMSE m [95% CI]": _ci(r["rmse_m"], r["rmse_lo"], r["rmse_hi"]),
                "ΔRMSE vs plain m [95% CI]": d,
                "diverged %": f"{r['diverged_pct']:.1f}",
                "note": r["note"] or "",
            }
        )
    return markdown_table(md)


def gate_table(gates: Sequence[Mapping[str, Any]]) -> str:
    """Markdown table of the gate, one row per id."""
    return markdown_table(
        [
            {
                "env": g["env"],
                "task": g["task"],
                "best tuned baseline": g["best_tuned_baseline"],
                "baseline RMSE m": f"{g['baseline_rmse_m']:.3f}",
                "clairvoyant RMSE m": f"{g['clairvoyant_rmse_m']:.3f}",
                "headroom % [95% CI]": _ci(g["headroom_pct"], g["headroom_lo_pct"], g["headroom_hi_pct"], 1),
                "adaptive baselines": g["adaptive_baselines"],
                "verdict": g["verdict"],
            }
            for g in gates
        ]
    )


def report(results: Mapping[str, Mapping[str, Any]], config: Mapping[str, Any]) -> str:
    """The markdown report."""
    gates = [r["gate"] for r in results.values()]
    s = config["seeds"]
    text = [
        "# Headroom gate (issue #21): clairvoyant filter vs the best tuned baseline\n",
        f"{s['tune']['n']} tuning episodes (seeds {s['tune']['first']}..{s['tune']['last']}), "
        f"{s['eval']['n']} held-out episodes (seeds {s['eval']['first']}..{s['eval']['last']}); "
        f"tuning score: mean episode {config['score']}; RMSE: mean over episodes of the horizontal "
        + (
            "position RMSE"
            if config.get("error", "position") == "position"
            else "RMSE of the scored error (position plus the platform's extra error, as the reward charges)"
        )
        + f"; {int(100 * config['level'])} % percentile-bootstrap CIs over episodes "
        f"({config['n_boot']} resamples), "
        f"paired. Headroom = (best tuned baseline RMSE - clairvoyant RMSE) / best tuned baseline RMSE; "
        f"PASS: headroom >= {100 * config['gate']:.0f} % and its CI excludes 0."
        + (" **Quick mode** (short episodes, tiny grids): not a result." if config["quick"] else "")
        + "\n",
        "## Gate\n",
        gate_table(gates),
    ]
    for env_id, r in results.items():
        text.append(f"## `{env_id}` ({r['seconds']:.0f} s)\n")
        text.append(policy_table(r["rows"]))
        text.append("`*`: the paired CI of ΔRMSE excludes 0.\n")
        for n in r["notes"]:
            text.append(f"- {n}")
        text.append("")
    text.append(f"Wall time: {config['wall_s']:.0f} s.\n")
    return "\n".join(text)


# -------------------------------------------------------------------------------------- CLI
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.headroom", description=__doc__.splitlines()[0])
    p.add_argument("--env", nargs="+", default=None, help="env ids (default: every registered -v2 id)")
    p.add_argument("--tune-episodes", type=int, default=256, help="tuning episodes per grid point")
    p.add_argument("--episodes", type=int, default=256, help="held-out evaluation episodes")
    p.add_argument("--tune-offset", type=int, default=TUNE_OFFSET, help="offset into the tuning seed range")
    p.add_argument(
        "--eval-offset", type=int, default=EVAL_OFFSET, help="offset into the evaluation seed range"
    )
    p.add_argument("--score", choices=("rmse", "return"), default="rmse", help="tuning score")
    p.add_argument(
        "--error",
        choices=tuple(ERROR_METRICS),
        default="position",
        help="the error tuned and gated on: position alone, or scored (position plus the platform's "
        "extra error, as the reward charges it)",
    )
    p.add_argument("--env-kwargs", default="{}", help="env keyword arguments as JSON")
    p.add_argument("--n-boot", type=int, default=DEFAULT_RESAMPLES)
    p.add_argument("--max-batch", type=int, default=None, help="sub-envs per batched tuning rollout")
    p.add_argument("--quick", action="store_true", help="8 + 8 episodes of 40 steps, tiny grids (the test)")
    p.add_argument("--strict", action="store_true", help="exit 1 when a gated id fails")
    p.add_argument("--out", default="results/headroom")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    git_at_start = git_commit()  # the code that ran (the manifest's "git" is read when it is written)
    ids = args.env or v2_ids()
    if not ids:
        p.error("no -v2 id is registered; pass --env ID")
    env_kwargs = json.loads(args.env_kwargs)
    n_tune, n_eval, n_boot, levels = args.tune_episodes, args.episodes, args.n_boot, ACTION_LEVELS
    if args.quick:
        n_tune, n_eval, n_boot, levels = (
            QUICK["tune_episodes"],
            QUICK["episodes"],
            QUICK["n_boot"],
            QUICK["action_levels"],
        )
        env_kwargs = {"episode_steps": QUICK["steps"], "max_episode_steps": QUICK["steps"], **env_kwargs}
    tune_seeds, eval_seeds = study_seeds(n_tune, n_eval, args.tune_offset, args.eval_offset)
    results = {}
    for env_id in ids:
        r = study_env(
            env_id,
            tune_seeds=tune_seeds,
            eval_seeds=eval_seeds,
            tune_offset=args.tune_offset,
            env_kwargs=env_kwargs,
            score=args.score,
            quick=args.quick,
            action_levels=levels,
            n_boot=n_boot,
            max_batch=args.max_batch,
            error=args.error,
        )
        results[env_id] = r
        g = r["gate"]
        print(
            f"{env_id}: headroom {g['headroom_pct']:.1f} % "
            f"[{g['headroom_lo_pct']:.1f}, {g['headroom_hi_pct']:.1f}] "
            f"(best tuned baseline {g['best_tuned_baseline']} {g['baseline_rmse_m']:.3f} m, clairvoyant "
            f"{g['clairvoyant_rmse_m']:.3f} m) -> {g['verdict']}  ({r['seconds']:.0f} s)",
            flush=True,
        )
    wall = time.perf_counter() - t0

    def _seeds(kind: str, s: list[int], offset: int) -> dict[str, Any]:
        return {"kind": kind, "n": len(s), "offset": offset, "first": s[0], "last": s[-1]}

    config = {
        "ids": ids,
        "quick": args.quick,
        "score": args.score,
        "error": args.error,
        "gate": GATE,
        "level": DEFAULT_LEVEL,
        "n_boot": n_boot,
        "env_kwargs": env_kwargs,
        "clairvoyant_kwargs": CLAIRVOYANT,
        "action_levels": levels,
        "seeds": {
            "tune": _seeds("tune", tune_seeds, args.tune_offset),
            "eval": _seeds("eval", eval_seeds, args.eval_offset),
        },
        "wall_s": round(wall, 1),
    }
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table.csv", [row for r in results.values() for row in r["rows"]])
    write_csv(out / "gate.csv", [r["gate"] for r in results.values()])
    (out / "report.md").write_text(report(results, config))
    write_manifest(
        out,
        "experiments.headroom",
        argv,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        git_at_start=git_at_start,
        config=config,
        tuned={env_id: r["tuned"] for env_id, r in results.items()},
        gate=[r["gate"] for r in results.values()],
        notes={env_id: r["notes"] for env_id, r in results.items()},
    )
    print(gate_table([r["gate"] for r in results.values()]))
    print(f"wrote {out}/ (table.csv, gate.csv, report.md, manifest.json) in {wall:.0f} s")
    failed = [r["gate"]["env"] for r in results.values() if r["gate"]["verdict"] == "FAIL"]
    return 1 if args.strict and failed else 0


if __name__ == "__main__":
    sys.exit(main())
