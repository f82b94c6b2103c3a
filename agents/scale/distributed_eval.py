"""Held-out evaluation split over Ray workers, equal bit for bit to the single-process one.

:func:`distributed_evaluate` splits the evaluation seeds into contiguous parts, runs every
policy on each part in a Ray task (:func:`agents.evaluation.runner.run_policies`, the rollouts
of :func:`~agents.evaluation.runner.evaluate`), concatenates the per-episode metrics and
rollouts in seed order and summarises them with the same bootstrap
(:func:`~agents.evaluation.runner.summarize`). An episode depends on its seed only (the
environment's rows are independent, the baselines act per row), so the arrays equal those of
one process. One caveat is measured, not assumed: torch's CPU matrix
product works on blocks of rows and computes some tail rows (a batch's last 1-3 rows past a
block of 16, or a batch of 1-3 rows) with other kernels whose last bits differ, so a learned
policy's action for an episode can depend on the episode's place in the batch. The parts are
therefore cut at multiples of :data:`ALIGN` (64) rows from the start of the batch and hold at
least :data:`ALIGN` episodes each (fewer workers are used when there are not enough
episodes): every row then has the same place in its blocks, and the batch's tail the same
length, as in one process (``docs/scaling.md`` records the splits checked with the zoo agents;
unaligned parts, e.g. 10 + 9 rows, are not equal). The workers should also run the CPU kind of
the single-process run (another instruction set can change a learned policy's last bits).
``tests/agents/scale/test_distributed_eval.py`` checks the
equality with baselines and a zoo agent on local Ray.

Policies reach the workers either as a builder (a picklable function returning ``{label:
policy}``; ``navgym eval --workers N`` sends :func:`agents.evaluation.cli.parse_policies` with
the specs, so every worker loads its own copies) or as the policies themselves (pickled by Ray).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES
from agents.evaluation.runner import EvalResults, Rollout, run_policies, summarize
from agents.scale.ray_runtime import init_ray, require_ray
from agents.seeds import check_seeds

__all__ = ["ALIGN", "distributed_evaluate", "merge_rollouts", "split_seeds"]

#: Parts are cut at multiples of ALIGN episodes and hold at least ALIGN (module docstring).
ALIGN = 64

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


def _part(
    env_id: str,
    source: PolicySource,
    seeds: list[int],
    env_kwargs: dict[str, Any],
    deterministic: bool,
) -> tuple[dict, dict, dict, int]:
    """One worker's rollouts (the body of the Ray task)."""
    import torch

    torch.set_num_threads(1)
    policies = source() if callable(source) else source
    return run_policies(env_id, policies, seeds, env_kwargs, deterministic, progress=False)


def distributed_evaluate(
    env_id: str,
    policies: PolicySource,
    seeds: Sequence[int],
    env_kwargs: Mapping[str, Any] | None = None,
    *,
    workers: int = 2,
    address: str | None = None,
    reference: str | None = None,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
    deterministic: bool = True,
    seed_kind: str | None = "eval",
    num_cpus: int | None = None,
) -> EvalResults:
    """:func:`agents.evaluation.runner.evaluate` with the episodes split over Ray workers.

    Args:
        env_id: registered env id.
        policies: ``{label: policy or factory}`` or a function returning it (run on each worker).
        seeds: episode seeds (checked against the ``seed_kind`` range).
        env_kwargs: env keyword arguments.
        workers: Ray tasks (one CPU each); fewer when a part would hold < :data:`ALIGN` episodes.
        address: Ray cluster address; ``None``: local Ray (started if needed).
        reference: reference policy of the paired differences (default: best baseline).
        n_boot: bootstrap resamples.
        level: confidence level.
        boot_seed: bootstrap seed.
        deterministic: passed to ``predict``.
        seed_kind: seed range to check (``None``: no check).
        num_cpus: CPUs of a local Ray (default: all cores).

    Returns:
        The :class:`~agents.evaluation.runner.EvalResults` of ``evaluate`` on the same
        arguments (``config["workers"]``: the parts actually run).
    """
    require_ray("distributed evaluation")
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("need at least one seed")
    if seed_kind is not None:
        check_seeds(seed_kind, seeds)
    env_kwargs = dict(env_kwargs or {})
    parts = split_seeds(seeds, workers)
    ray = init_ray(address, num_cpus)
    task = ray.remote(num_cpus=1)(_part)
    source = ray.put(policies)
    outs = ray.get([task.remote(env_id, source, p, env_kwargs, deterministic) for p in parts])
    descr = outs[0][0]
    names = list(descr)
    if any(list(o[0]) != names for o in outs):
        raise RuntimeError("the workers built different policies")
    episodes = {n: {m: np.concatenate([o[1][n][m] for o in outs]) for m in outs[0][1][n]} for n in names}
    rollouts = {n: merge_rollouts([o[2][n] for o in outs]) for n in names}
    T = outs[0][3]
    reference, summary, paired = summarize(descr, episodes, reference, n_boot, level, boot_seed)
    config = {
        "n_boot": n_boot,
        "level": level,
        "boot_seed": boot_seed,
        "deterministic": deterministic,
        "steps": T,
        "workers": len(parts),
    }
    return EvalResults(
        env_id, env_kwargs, seeds, descr, episodes, rollouts, summary, paired, reference, config
    )
