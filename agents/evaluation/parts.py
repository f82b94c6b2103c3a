"""Held-out evaluation split into parts of the seeds, run apart and merged, equal bit for bit.

:func:`split_seeds` cuts the evaluation seeds into contiguous parts, every policy runs on each
part (:func:`run_part`, the rollouts of :func:`agents.evaluation.runner.evaluate`), and
:func:`merge_parts` concatenates the per-episode metrics and rollouts in seed order and
summarises them with the same bootstrap (:func:`~agents.evaluation.runner.summarize`). An
episode depends on its seed only (the environment's rows are independent, the baselines act per
row), so the arrays equal those of one process. One caveat is measured, not assumed: torch's
CPU matrix product works on blocks of rows and computes some tail rows (a batch's last 1-3 rows
past a block of 16, or a batch of 1-3 rows) with other kernels whose last bits differ, so a
learned policy's action for an episode can depend on the episode's place in the batch. The
parts are therefore cut at multiples of :data:`ALIGN` (64) rows from the start of the batch and
hold at least :data:`ALIGN` episodes each (fewer parts are run when there are not enough
episodes): every row then has the same place in its blocks, and the batch's tail the same
length, as in one process (``docs/scaling.md`` records the splits checked with the zoo agents;
unaligned parts, e.g. 10 + 9 rows, are not equal).

Two runners: :func:`forked_evaluate` runs the parts in forked processes of this machine
(:func:`agents.workers.map_chunks`; the policies are inherited, not pickled), and
:func:`agents.scale.distributed_eval.distributed_evaluate` in Ray tasks (a cluster). Each part's
process computes with one torch thread.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES
from agents.evaluation.runner import EvalResults, PolicyRuns, Rollout, checked_seeds, results_of, run_policies
from agents.workers import map_chunks

__all__ = [
    "ALIGN",
    "forked_evaluate",
    "merge_parts",
    "merge_rollouts",
    "run_part",
    "split_seeds",
]

#: Parts are cut at multiples of ALIGN episodes and hold at least ALIGN (module docstring).
ALIGN = 64

#: ``{label: policy or factory}``, or a function returning it (called where the part runs).
PolicySource = Mapping[str, Any] | Callable[[], Mapping[str, Any]]


def split_seeds(seeds: Sequence[int], workers: int, align: int = ALIGN) -> list[list[int]]:
    """``seeds`` in at most ``workers`` contiguous parts of >= ``align`` seeds each.

    Every part but the last holds the same multiple of ``align`` seeds; the last holds the rest
    (so it ends with the same tail as the whole batch). Fewer seeds than ``2 * align``: one part.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1; got {workers}")
    seeds = [int(s) for s in seeds]
    n = max(1, min(int(workers), len(seeds) // max(1, align)))
    if n == 1:
        return [seeds]
    per = (len(seeds) // n) // align * align
    cuts = [i * per for i in range(n)] + [len(seeds)]
    return [seeds[a:b] for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def merge_rollouts(parts: Sequence[Rollout]) -> Rollout:
    """The rollouts of consecutive parts of the seeds as one (rows concatenated in order)."""
    keys = list(parts[0].steps)
    if any(list(p.steps) != keys for p in parts):
        raise ValueError("the parts recorded different step keys")
    return Rollout(
        {k: np.concatenate([p.steps[k] for p in parts]) for k in keys},
        np.concatenate([p.alive for p in parts]),
        np.concatenate([p.length for p in parts]),
        np.concatenate([p.terminated for p in parts]),
        parts[0].dt,
    )


def run_part(
    env_id: str,
    source: PolicySource,
    seeds: list[int],
    env_kwargs: dict[str, Any],
    deterministic: bool,
) -> PolicyRuns:
    """One part's rollouts, with one torch thread (the body of a worker)."""
    import torch

    torch.set_num_threads(1)
    policies = source() if callable(source) else source
    return run_policies(env_id, policies, seeds, env_kwargs, deterministic, progress=False)


def merge_parts(
    env_id: str,
    seeds: Sequence[int],
    env_kwargs: Mapping[str, Any],
    outs: Sequence[PolicyRuns],
    *,
    reference: str | None = None,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
    deterministic: bool = True,
) -> EvalResults:
    """The :class:`~agents.evaluation.runner.EvalResults` of the parts ``outs`` (in seed order).

    ``config["workers"]`` is the number of parts.

    Raises:
        RuntimeError: the parts built different policies.
    """
    descr = outs[0][0]
    names = list(descr)
    if any(list(o[0]) != names for o in outs):
        raise RuntimeError("the workers built different policies")
    episodes = {n: {m: np.concatenate([o[1][n][m] for o in outs]) for m in outs[0][1][n]} for n in names}
    rollouts = {n: merge_rollouts([o[2][n] for o in outs]) for n in names}
    runs = (descr, episodes, rollouts, outs[0][3])
    res = results_of(
        env_id, dict(env_kwargs), list(seeds), runs, reference, n_boot, level, boot_seed, deterministic
    )
    res.config["workers"] = len(outs)
    return res


def forked_evaluate(
    env_id: str,
    policies: PolicySource,
    seeds: Sequence[int],
    env_kwargs: Mapping[str, Any] | None = None,
    *,
    workers: int = 2,
    reference: str | None = None,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
    deterministic: bool = True,
    seed_kind: str | None = "eval",
    on_done: Callable[[int], None] | None = None,
) -> EvalResults:
    """:func:`agents.evaluation.runner.evaluate` with the episodes split over forked processes.

    Args:
        env_id: registered env id.
        policies: ``{label: policy or factory}`` or a function returning it (called in each
            worker); inherited by the forked workers, so nothing is pickled on the way in.
        seeds: episode seeds (checked against the ``seed_kind`` range).
        env_kwargs: env keyword arguments.
        workers: processes at a time; the parts are :func:`split_seeds` (fewer when a part
            would hold < :data:`ALIGN` episodes). Where ``fork`` is unavailable the parts run
            one after the other here.
        reference: reference policy of the paired differences (default: best baseline).
        n_boot: bootstrap resamples.
        level: confidence level.
        boot_seed: bootstrap seed.
        deterministic: passed to ``predict``.
        seed_kind: seed range to check (``None``: no check).
        on_done: called with a part's index as it finishes (a progress bar).

    Returns:
        The ``EvalResults`` of ``evaluate`` on the same arguments, bit for bit
        (``config["workers"]``: the parts run).
    """
    if int(workers) < 1:
        raise ValueError(f"workers must be at least 1; got {workers}")
    seeds = checked_seeds(seeds, seed_kind)
    kwargs = dict(env_kwargs or {})
    parts = split_seeds(seeds, workers)
    outs = map_chunks(
        lambda i: run_part(env_id, policies, parts[i], kwargs, deterministic),
        len(parts),
        int(workers),
        on_done,
    )
    return merge_parts(
        env_id,
        seeds,
        kwargs,
        outs,
        reference=reference,
        n_boot=n_boot,
        level=level,
        boot_seed=boot_seed,
        deterministic=deterministic,
    )
