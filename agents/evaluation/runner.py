"""Batched rollouts and the paired evaluation of policies on the same seeded episodes.

Every policy runs on the **same** episodes: one native vector env with ``B`` = number of
episodes, reset with the list of evaluation seeds (sub-env ``i`` with seed ``seeds[i]``), one
batched rollout per policy. An episode is fully determined by (env id, kwargs, seed), so the
comparison is paired; rollouts are deterministic under the seeds.

Policies act through :class:`agents.policy_runner.PredictRunner`: the state ``predict`` returns
(a recurrent agent's LSTM states, a frame-stacked agent's frames, a baseline's memory) is carried
from step to step and reset per row when that row's episode starts.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES, bootstrap_mean_ci, paired_difference
from agents.evaluation.metrics import METRICS, PAIRED_METRICS, episode_metrics
from agents.policy_runner import (
    DescribedPolicy,
    PolicyRunner,
    Predictor,
    PredictRunner,
    policy_kind,
)
from agents.seeds import check_seeds
from navgym.envs.base import NavVectorEnv, navigation_env
from navgym.envs.distinct import EpisodeCache

__all__ = [
    "EvalResults",
    "Rollout",
    "evaluate",
    "make_vector_env",
    "native_vector_env",
    "policy_kind",
    "rollout",
    "run_policies",
    "summarize",
    "OneEpisodeStepper",
]

#: Per-step info keys recorded by :func:`rollout` (those present in the env's info).
STEP_KEYS = ("pos_err_m", "extra_err", "gnss_available", "nees", "knob", "resampled", "diverged")

#: A policy, or a factory called with the live vector env (a class, ``functools.partial``).
PolicyOrFactory = Predictor | Callable[[Any], Predictor]


@dataclass
class Rollout:
    """Per-step records ``(B, T)`` of one batched rollout (entries after an episode ends are NaN/0).

    Attributes:
        steps: ``{key: (B, T)}`` for ``STEP_KEYS`` present in the env's info, plus ``reward``
            (a vector knob is recorded as the mean of its entries).
        alive: ``(B, T)`` True on the steps of each episode.
        length: ``(B,)`` steps of each episode.
        terminated: ``(B,)`` True where the episode ended by divergence.
        dt: filter step [s].
    """

    steps: dict[str, np.ndarray]
    alive: np.ndarray
    length: np.ndarray
    terminated: np.ndarray
    dt: float


def make_vector_env(env_id: str, num_envs: int, env_kwargs: Mapping[str, Any] | None = None) -> Any:
    """The native batched env of ``env_id`` (``gym.make_vec(..., "vector_entry_point")``)."""
    import navgym  # noqa: F401  (registers the ids)

    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **dict(env_kwargs or {})
    )


def native_vector_env(env: Any) -> NavVectorEnv:
    """The navgym native vector env of ``env`` (through its wrappers); ``TypeError`` for a single env."""
    nav = navigation_env(env)
    if not isinstance(nav, NavVectorEnv):
        raise TypeError(f"need a native vector env (make_vector_env); got the single env {nav}")
    return nav


class OneEpisodeStepper:
    """:meth:`navgym.envs.base.NavVectorEnv.episode_stepper` of ``env`` (kept for callers)."""

    def __init__(self, env: Any) -> None:
        self._stepper = native_vector_env(env).episode_stepper()

    def step(self, action: Any) -> tuple:
        return self._stepper.step(action)


def rollout(
    env: Any,
    policy: Predictor,
    seeds: Sequence[int],
    deterministic: bool = True,
    pbar: Any = None,
    autoreset: bool = False,
) -> Rollout:
    """Run ``policy`` for one episode in each sub-env of the native vector ``env``.

    Args:
        env: native vector env with ``num_envs == len(seeds)``.
        policy: anything with SB3's ``predict`` (baselines, SB3 models, trained agents with
            memory, the oracle), stepped through a :class:`~agents.policy_runner.PredictRunner`
            (its state carried between steps, reset per episode).
        seeds: reset seed of each sub-env.
        deterministic: passed to ``predict``.
        pbar: optional tqdm bar advanced by one per step.
        autoreset: step through ``env.step`` (finished sub-envs autoreset, their records
            ignored) instead of :class:`OneEpisodeStepper` (default; same records, no wasted
            resets).

    Returns:
        The :class:`Rollout` (until every episode has terminated or been truncated).
    """
    B = int(env.num_envs)
    if len(seeds) != B:
        raise ValueError(f"need one seed per sub-env: {B} sub-envs, {len(seeds)} seeds")
    nav = navigation_env(env)
    T = nav.horizon
    obs, _ = env.reset(seed=[int(s) for s in seeds])
    runner: PolicyRunner = PredictRunner(policy, deterministic)
    runner.reset()
    stepper = None if autoreset else OneEpisodeStepper(env)
    steps: dict[str, np.ndarray] = {"reward": np.zeros((B, T))}
    alive_steps = np.zeros((B, T), dtype=bool)
    alive = np.ones(B, dtype=bool)
    length = np.zeros(B, dtype=np.int64)
    terminated = np.zeros(B, dtype=bool)
    for t in range(T):
        action = runner.act(obs)
        if stepper is None:  # autoreset
            obs, reward, term, trunc, info = env.step(action)
            runner.reset(np.asarray(term, dtype=bool) | np.asarray(trunc, dtype=bool))
        else:
            obs, reward, term, trunc, info = stepper.step(action)
        alive_steps[:, t] = alive
        steps["reward"][alive, t] = np.asarray(reward, dtype=np.float64)[alive]
        for k in STEP_KEYS:
            if k not in info:
                continue
            v = np.asarray(info[k])
            if v.ndim > 1:  # a vector knob (NoiseScale's two scales, per-row weights): its mean
                v = v.reshape(B, -1).mean(axis=1)
            if k not in steps:
                steps[k] = np.zeros((B, T), dtype=bool) if v.dtype == bool else np.full((B, T), np.nan)
            steps[k][alive, t] = v[alive]
        length[alive] += 1
        terminated |= np.asarray(term, dtype=bool) & alive
        alive &= ~(np.asarray(term, dtype=bool) | np.asarray(trunc, dtype=bool))
        if pbar is not None:
            pbar.update(1)
        if not alive.any():
            break
    return Rollout(steps, alive_steps, length, terminated, float(nav.platform.dt))


def describe_policy(policy: Any) -> dict[str, Any]:
    """What a manifest records about a policy: its :meth:`describe` (else its class) and kind."""
    if isinstance(policy, DescribedPolicy):
        d = dict(policy.describe())
    else:
        d = {"class": f"{type(policy).__module__}.{type(policy).__qualname__}"}
    d["kind"] = policy_kind(policy)
    return d


@dataclass
class EvalResults:
    """Results of :func:`evaluate` (see :mod:`agents.evaluation.report` for the files).

    Attributes:
        env_id, env_kwargs, seeds: the episodes.
        policies: ``{name: description}`` (class, parameters, kind).
        episodes: ``{name: {metric: (B,) array}}`` per-episode metrics.
        rollouts: ``{name: Rollout}`` per-step records (for plots).
        summary: one row per policy: ``metric`` mean and bootstrap CI (``metric_lo/_hi``).
        paired: one row per (policy, metric): mean difference policy - reference and its CI.
        reference: name of the reference policy (the best baseline by mean return, by default).
        config: bootstrap settings and the rest of the configuration.
    """

    env_id: str
    env_kwargs: dict[str, Any]
    seeds: list[int]
    policies: dict[str, dict[str, Any]]
    episodes: dict[str, dict[str, np.ndarray]]
    rollouts: dict[str, Rollout]
    summary: list[dict[str, Any]]
    paired: list[dict[str, Any]]
    reference: str | None
    config: dict[str, Any] = field(default_factory=dict)

    def row(self, name: str) -> dict[str, Any]:
        """The summary row of policy ``name``."""
        for r in self.summary:
            if r["policy"] == name:
                return r
        raise KeyError(name)


def evaluate(
    env_id: str,
    policies: Mapping[str, PolicyOrFactory],
    seeds: Sequence[int],
    env_kwargs: Mapping[str, Any] | None = None,
    *,
    reference: str | None = None,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
    deterministic: bool = True,
    seed_kind: str | None = "eval",
    progress: bool = True,
) -> EvalResults:
    """Run every policy on the same seeded episodes; per-episode metrics and paired comparisons.

    Args:
        env_id: registered id, e.g. ``"navgym/GpsInsFading-v0"``.
        policies: ``{name: policy}``; a class, or a value without ``predict``, is a factory
            called with the live vector env (e.g. ``GreedyOracle``, ``functools.partial(cls, ...)``).
        seeds: episode seeds, one per episode (B = ``len(seeds)``); checked against the
            ``seed_kind`` range of :mod:`agents.seeds` (``None`` skips the check).
        env_kwargs: keyword arguments of the env.
        reference: policy the paired differences are taken against; default the baseline with
            the best mean return.
        n_boot: bootstrap resamples (percentile bootstrap over episodes).
        level: confidence level of the intervals.
        boot_seed: seed of the bootstrap's NumPy generator.
        deterministic: passed to ``predict``.
        seed_kind: ``"eval"`` (default), ``"tune"``, ``"train"`` or None.
        progress: tqdm bar per policy.

    Returns:
        :class:`EvalResults`.
    """
    seeds = checked_seeds(seeds, seed_kind)
    env_kwargs = dict(env_kwargs or {})
    runs = run_policies(env_id, policies, seeds, env_kwargs, deterministic, progress)
    return results_of(env_id, env_kwargs, seeds, runs, reference, n_boot, level, boot_seed, deterministic)


def checked_seeds(seeds: Sequence[int], seed_kind: str | None) -> list[int]:
    """``seeds`` as ints, checked against the ``seed_kind`` range of :mod:`agents.seeds` (``None``: not).

    Raises:
        ValueError: no seed, or a seed outside the range.
    """
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("need at least one seed")
    if seed_kind is not None:
        check_seeds(seed_kind, seeds)
    return seeds


def results_of(
    env_id: str,
    env_kwargs: dict[str, Any],
    seeds: list[int],
    runs: PolicyRuns,
    reference: str | None,
    n_boot: int,
    level: float,
    boot_seed: int,
    deterministic: bool,
) -> EvalResults:
    """The :class:`EvalResults` of :func:`run_policies`' ``runs`` (summary, paired rows, config)."""
    descr, episodes, rollouts, T = runs
    reference, summary, paired = summarize(descr, episodes, reference, n_boot, level, boot_seed)
    config = {
        "n_boot": n_boot,
        "level": level,
        "boot_seed": boot_seed,
        "deterministic": deterministic,
        "steps": T,
    }
    return EvalResults(
        env_id, env_kwargs, seeds, descr, episodes, rollouts, summary, paired, reference, config
    )


#: :func:`run_policies`' result: ``(descriptions, per-episode metrics, rollouts, horizon)``.
PolicyRuns = tuple[dict[str, dict[str, Any]], dict[str, dict[str, np.ndarray]], dict[str, Rollout], int]


def run_policies(
    env_id: str,
    policies: Mapping[str, PolicyOrFactory],
    seeds: Sequence[int],
    env_kwargs: Mapping[str, Any] | None = None,
    deterministic: bool = True,
    progress: bool = True,
) -> PolicyRuns:
    """The rollouts of :func:`evaluate`: ``(descriptions, per-episode metrics, rollouts, horizon)``.

    Every policy runs on one native vector env with a sub-env per seed (seeds not checked here).
    An episode's records depend on its seed only, so a split of ``seeds`` into parts run apart
    and concatenated gives the same arrays (:mod:`agents.scale.distributed_eval`). The episodes
    are simulated once for all the policies (:class:`navgym.envs.distinct.EpisodeCache`, which
    holds a copy of them meanwhile).
    """
    env = make_vector_env(env_id, len(seeds), env_kwargs)
    cache = EpisodeCache(maxsize=1)
    T = navigation_env(env).horizon
    descr: dict[str, dict[str, Any]] = {}
    episodes: dict[str, dict[str, np.ndarray]] = {}
    rollouts: dict[str, Rollout] = {}
    divergence_m = float(navigation_env(env).platform.divergence_m)
    try:
        for name, p in policies.items():
            policy = p if isinstance(p, Predictor) and not isinstance(p, type) else p(env)
            descr[name] = describe_policy(policy)
            pbar = _bar(progress, T, f"eval {name}")
            try:
                with cache.active():
                    roll = rollout(env, policy, seeds, deterministic=deterministic, pbar=pbar)
            finally:
                if pbar is not None:
                    pbar.close()
            rollouts[name] = roll
            episodes[name] = episode_metrics(roll, divergence_m)
    finally:
        env.close()
    return descr, episodes, rollouts, T


def summarize(
    descr: Mapping[str, Mapping[str, Any]],
    episodes: Mapping[str, Mapping[str, np.ndarray]],
    reference: str | None = None,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
) -> tuple[str | None, list[dict[str, Any]], list[dict[str, Any]]]:
    """``(reference, summary rows, paired rows)`` of :func:`evaluate` from per-episode metrics.

    ``reference`` ``None``: the baseline with the best mean return (``None`` without baselines).
    """
    if reference is None:
        cands = [n for n in episodes if descr[n]["kind"] == "baseline"]
        reference = max(cands, key=lambda n: float(np.mean(episodes[n]["return"]))) if cands else None
    elif reference not in episodes:
        raise ValueError(f"reference {reference!r} is not among the policies {list(episodes)}")
    summary, paired = [], []
    for i, name in enumerate(episodes):
        row: dict[str, Any] = {"policy": name, "kind": descr[name]["kind"], "reference": name == reference}
        for j, m in enumerate(METRICS):
            x = episodes[name][m]
            mean, lo, hi, n = bootstrap_mean_ci(x, n_boot, level, seed=boot_seed + 1000 * i + j)
            row.update({m: mean, f"{m}_lo": lo, f"{m}_hi": hi, f"{m}_n": n})
            fin = np.isfinite(x)
            row[f"{m}_median"] = float(np.median(x[fin])) if fin.any() else float("nan")
        summary.append(row)
        if reference is not None and name != reference:
            for j, m in enumerate(PAIRED_METRICS):
                d = paired_difference(
                    episodes[name][m],
                    episodes[reference][m],
                    n_boot,
                    level,
                    seed=boot_seed + 1000 * i + 500 + j,
                )
                paired.append({"policy": name, "reference": reference, "metric": m, **d})
    return reference, summary, paired


def _bar(progress: bool, total: int, desc: str) -> Any:
    if not progress:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, leave=False, disable=None)  # None: off where stderr is no terminal
