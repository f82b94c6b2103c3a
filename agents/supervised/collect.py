"""Labelled data of the RowScale ids: batched rollouts of a behaviour policy on training seeds.

Each episode of ``seeds`` runs in one sub-env of a native vector env (all at once, no loop over
the batch); before each step the labels of the step the action will be applied at are peeked
(:func:`agents.supervised.labels.next_step_labels`) and the inputs computed from the current
observation (:class:`agents.supervised.features.RowFeatures`). Behaviours:

* ``"oracle"``: the env with ``regime_oracle=table`` (the task sets the scales from the truth;
  the action is ignored): the filter a good policy would run;
* ``"plain"``: every scale 1;
* ``"mixed"``: every other seed under the oracle (the first, third, ...), the others plain;
* any SB3-style policy (e.g. a first :class:`~agents.supervised.policy.SupervisedRowScalePolicy`,
  a DAgger round, Ross et al. 2011) on the plain env.

Seeds must be training seeds (:func:`agents.seeds.check_seeds`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from agents.baselines import ConstantAction
from agents.evaluation.runner import make_vector_env, native_vector_env
from agents.policy_runner import PredictRunner
from agents.seeds import check_seeds
from agents.supervised.features import RowFeatures
from agents.supervised.labels import next_step_labels

__all__ = ["BEHAVIOURS", "Dataset", "collect", "collect_episodes"]

#: Named behaviour policies (module docstring).
BEHAVIOURS = ("oracle", "plain", "mixed")


class Dataset(NamedTuple):
    """Inputs and labels of the steps of a set of episodes (``N`` steps in all)."""

    rows: np.ndarray  #: (N, m, F_r) float32 per-row inputs
    glob: np.ndarray  #: (N, F_g) float32 global inputs
    row_y: np.ndarray  #: (N, m) int64 row classes
    motion_y: np.ndarray  #: (N,) int64 motion classes
    episode: np.ndarray  #: (N,) int64 the step's episode seed

    @staticmethod
    def concat(parts: Sequence[Dataset]) -> Dataset:
        """The steps of ``parts`` one after the other."""
        return Dataset(*(np.concatenate(x) for x in zip(*parts, strict=True)))

    def take(self, sel: np.ndarray) -> Dataset:
        """The steps ``sel`` (a boolean mask or indices)."""
        return Dataset(*(x[sel] for x in self))


def collect_episodes(env: Any, seeds: Sequence[int], policy: Any = None) -> Dataset:
    """One episode per sub-env of the native vector ``env`` (``len(seeds)`` sub-envs) under ``policy``.

    ``policy`` ``None``: the task's neutral action (the plain filter; under ``regime_oracle`` the
    oracle, which ignores it). Steps after an episode ended are dropped.
    """
    nav = native_vector_env(env)
    B, T = int(env.num_envs), nav.horizon
    if len(seeds) != B:
        raise ValueError(f"need one seed per sub-env: {B} sub-envs, {len(seeds)} seeds")
    feats = RowFeatures.of(nav.observation_features, int(nav.task.m_max))
    if policy is None:
        policy = ConstantAction(env.single_action_space, nav.task.neutral_action(), "neutral")
    runner = PredictRunner(policy)
    obs, _ = env.reset(seed=[int(s) for s in seeds])
    stepper = nav.episode_stepper()
    memory = feats.init_memory(B)
    rows = np.zeros((B, T, feats.m, feats.n_row), np.float32)
    glob = np.zeros((B, T, feats.n_global), np.float32)
    row_y = np.zeros((B, T, feats.m), np.int64)
    motion_y = np.zeros((B, T), np.int64)
    alive = np.ones(B, dtype=bool)
    kept = np.zeros((B, T), dtype=bool)
    for t in range(T):
        labels = next_step_labels(env)
        rows[:, t], glob[:, t], memory = feats(obs, memory)
        row_y[:, t], motion_y[:, t] = labels
        kept[:, t] = alive
        obs, _, term, trunc, _ = stepper.step(runner.act(obs))
        alive &= ~(np.asarray(term, dtype=bool) | np.asarray(trunc, dtype=bool))
        if not alive.any():
            break
    episode = np.broadcast_to(np.asarray(seeds, dtype=np.int64)[:, None], (B, T))
    return Dataset(rows[kept], glob[kept], row_y[kept], motion_y[kept], episode[kept])


def collect(
    env_id: str,
    seeds: Sequence[int],
    behaviour: str | Any = "mixed",
    table: Sequence[float] | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    batch: int = 256,
) -> Dataset:
    """Labelled steps of the episodes ``seeds`` (training seeds) under ``behaviour``, ``batch`` at a time.

    ``table`` is the oracle's (needed by ``"oracle"`` and ``"mixed"``).
    """
    seeds = [int(s) for s in seeds]
    check_seeds("train", seeds)
    kwargs = dict(env_kwargs or {})
    if isinstance(behaviour, str):
        if behaviour not in BEHAVIOURS:
            raise ValueError(f"behaviour must be one of {BEHAVIOURS} or a policy; got {behaviour!r}")
        if behaviour != "plain" and table is None:
            raise ValueError(f"behaviour {behaviour!r} needs the oracle's table")
        if behaviour == "mixed":
            groups = [(seeds[::2], True, None), (seeds[1::2], False, None)]
        else:
            groups = [(seeds, behaviour == "oracle", None)]
    else:
        groups = [(seeds, False, behaviour)]
    parts = []
    for group, oracle, policy in groups:
        extra = {"regime_oracle": tuple(float(v) for v in table)} if oracle and table is not None else {}
        for i in range(0, len(group), batch):
            chunk = group[i : i + batch]
            env = make_vector_env(env_id, len(chunk), {**kwargs, **extra})
            try:
                parts.append(collect_episodes(env, chunk, policy))
            finally:
                env.close()
    if not parts:
        raise ValueError("no episodes to collect")
    return Dataset.concat(parts)
