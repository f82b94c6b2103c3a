"""Held-out evaluation split over Ray workers, equal bit for bit to the single-process one.

:func:`distributed_evaluate` splits the evaluation seeds into contiguous parts
(:func:`agents.evaluation.parts.split_seeds`, aligned to :data:`ALIGN` rows for the reason given
there), runs every policy on each part in a Ray task (:func:`agents.evaluation.parts.run_part`)
and merges them (:func:`agents.evaluation.parts.merge_parts`). The workers should run the CPU
kind of the single-process run (another instruction set can change a learned policy's last
bits). ``tests/agents/scale/test_distributed_eval.py`` checks the equality with baselines and a
zoo agent on local Ray; :func:`agents.evaluation.parts.forked_evaluate` is the same split over
the processes of one machine, without Ray.

Policies reach the workers either as a builder (a picklable function returning ``{label:
policy}``; ``navgym eval --workers N --ray`` sends :func:`agents.evaluation.cli.parse_policies`
with the specs, so every worker loads its own copies) or as the policies themselves (pickled by
Ray).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES
from agents.evaluation.parts import ALIGN, PolicySource, merge_parts, merge_rollouts, run_part, split_seeds
from agents.evaluation.runner import EvalResults, checked_seeds
from agents.scale.ray_runtime import init_ray, require_ray

__all__ = ["ALIGN", "distributed_evaluate", "merge_rollouts", "split_seeds"]


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
    seeds = checked_seeds(seeds, seed_kind)
    env_kwargs = dict(env_kwargs or {})
    parts = split_seeds(seeds, workers)
    ray = init_ray(address, num_cpus)
    task = ray.remote(num_cpus=1)(run_part)
    source = ray.put(policies)
    outs = ray.get([task.remote(env_id, source, p, env_kwargs, deterministic) for p in parts])
    return merge_parts(
        env_id,
        seeds,
        env_kwargs,
        outs,
        reference=reference,
        n_boot=n_boot,
        level=level,
        boot_seed=boot_seed,
        deterministic=deterministic,
    )
