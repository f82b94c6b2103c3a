"""Independent chunks of work run in forked worker processes; the results in chunk order.

A tuning grid is scored in chunks of grid points (:func:`agents.tuning.search.score_points`), each
chunk one native vector env, its own rollout and its own metrics: nothing passes between chunks,
so they can run on several cores at once; an evaluation's seeds are split into parts the same
way (:func:`agents.evaluation.parts.forked_evaluate`). On a machine with ``k`` cores ``k`` chunks at
a time cut the wall time of a tune by up to ``k`` (``docs/performance.md``, "Where the speed
targets stand"). The particle passes of an env step may themselves run on several threads
(:mod:`filters.core.threads`); each worker gets the parent's threads divided by the workers (at
least 1), so that the workers together do not ask for more cores than the parent had.

The workers are **forked** (``multiprocessing``'s ``"fork"`` start method): a chunk's job is a
closure over the env id, the seeds and the baseline's policy factory, which pickling cannot
carry, and a forked child inherits it together with the imported modules and the compiled
kernels, so it starts in milliseconds. The job is left in a module global for the children
to read and cleared after. Where ``fork`` is not available (Windows) the chunks run one after
the other. Ray Tune (``navgym tune --ray``, :mod:`agents.scale.ray_tuning`) is the scale-out
beyond one machine.

A chunk's result is the same in a worker as in the parent (the same deterministic code on the
same inputs): the search's scores do not depend on the number of workers
(``tests/agents/test_evaluation.py``).
"""

from __future__ import annotations

import multiprocessing
import sys
from collections.abc import Callable
from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait
from typing import Any, TypeVar

from filters.core.threads import available_cores, get_num_threads, set_num_threads

__all__ = ["MAX_DEFAULT_WORKERS", "available_cores", "can_fork", "default_workers", "map_chunks"]

T = TypeVar("T")

#: The most workers :func:`default_workers` proposes: each holds a chunk's episodes and filters
#: (about 0.7 GB for 1024 QuadrotorRowScale-v3 episodes), so memory, not cores, bounds it on
#: large machines; ask for more explicitly.
MAX_DEFAULT_WORKERS = 8

#: The job of the running :func:`map_chunks`, read by its forked children (``None`` otherwise).
_JOB: Callable[[int], Any] | None = None


def can_fork() -> bool:
    """Whether worker processes can be forked here (not on Windows)."""
    return "fork" in multiprocessing.get_all_start_methods()


def default_workers() -> int:
    """Workers for a search: the available cores, at most :data:`MAX_DEFAULT_WORKERS`; 1 without fork."""
    return min(available_cores(), MAX_DEFAULT_WORKERS) if can_fork() else 1


def _run(i: int) -> Any:
    """Chunk ``i`` of the inherited job (in a forked child)."""
    job = _JOB
    if job is None:  # pragma: no cover - only a child forked outside map_chunks would see this
        raise RuntimeError("no chunk job in this worker")
    return job(i)


def map_chunks(
    job: Callable[[int], T],
    n: int,
    workers: int = 1,
    on_done: Callable[[int], None] | None = None,
) -> list[T]:
    """``[job(0), ..., job(n - 1)]``, with up to ``workers`` chunks at a time in forked processes.

    Args:
        job: computes chunk ``i``; its result must pickle (it comes back from the worker).
        n: number of chunks.
        workers: processes at a time; 1 (or one chunk, or no ``fork``) runs the chunks here, in
            order.
        on_done: called with ``i`` in this process as chunk ``i`` finishes (a progress bar).

    Returns:
        The results in chunk order.

    Raises:
        ValueError: ``workers`` below 1.
        Exception: the first chunk's error (the chunks not yet started are cancelled).
    """
    if int(workers) < 1:
        raise ValueError(f"workers must be at least 1; got {workers}")
    if int(workers) == 1 or n <= 1 or not can_fork():
        out = []
        for i in range(n):
            out.append(job(i))
            if on_done is not None:
                on_done(i)
        return out
    global _JOB
    _JOB = job
    # a child flushes the stdio buffers it inherits when it exits: empty them first
    sys.stdout.flush()
    sys.stderr.flush()
    results: dict[int, T] = {}
    try:
        ctx = multiprocessing.get_context("fork")
        procs = min(int(workers), n)
        share = max(1, get_num_threads() // procs)
        # each forked worker's row-parallel passes get its share of the parent's threads
        with ProcessPoolExecutor(procs, ctx, set_num_threads, (share,)) as pool:
            pending = {pool.submit(_run, i): i for i in range(n)}
            while pending:
                done, _ = wait(pending, return_when=FIRST_EXCEPTION)
                for f in done:
                    i = pending.pop(f)
                    exc = f.exception()
                    if exc is not None:
                        pool.shutdown(wait=True, cancel_futures=True)
                        raise exc
                    results[i] = f.result()
                    if on_done is not None:
                        on_done(i)
    finally:
        _JOB = None
    return [results[i] for i in range(n)]
