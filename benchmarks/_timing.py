"""Shared timing helpers for the benchmark commands (single core, best of k)."""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

import numpy as np


@contextmanager
def single_core(threads: int = 1):
    """BLAS/OpenMP pools limited to one thread (threadpoolctl), the row-parallel passes to ``threads``.

    ``threads = 1`` (the default) gives per-core figures; more lets the particle passes of
    :mod:`filters.core.threads` split the batch (``--threads`` of the env benchmarks).
    """
    from threadpoolctl import threadpool_limits

    from filters.core.threads import num_threads

    with threadpool_limits(limits=1), num_threads(threads):
        yield


def add_threads_argument(parser: argparse.ArgumentParser) -> None:
    """``--threads``: threads of the row-parallel particle passes (1: per-core figures)."""
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="threads of the row-parallel particle passes (filters.core.threads); default 1, the "
        "per-core figures; more needs wall-clock timing",
    )


def check_threads(threads: int, clock: str = "wall") -> str:
    """Validate ``--threads`` against the clock (``--clock``); the cores phrase of the table headers."""
    if threads < 1:
        raise ValueError(f"--threads must be >= 1; got {threads}")
    if threads > 1 and clock != "wall":
        raise ValueError(
            f"--threads {threads} needs --clock wall: the cpu clock counts the timing thread's "
            "time alone, not the other threads'"
        )
    return "one core" if threads == 1 else f"{threads} threads for the particle passes"


#: Clocks of :func:`best_time`: wall time, or the CPU time of the calling thread (``--clock cpu``
#: of the benchmarks: on a machine shared with other work it leaves out the time the thread
#: waited for a core, not the slowdown of shared caches and memory bandwidth).
CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.thread_time}


def add_clock_argument(parser: argparse.ArgumentParser) -> None:
    """``--clock``: a key of :data:`CLOCKS` (wall time, or the timing thread's CPU time)."""
    parser.add_argument(
        "--clock",
        default="wall",
        choices=sorted(CLOCKS),
        help="wall time, or the CPU time of the timing thread (for a machine shared with other work)",
    )


def add_clock_and_path_arguments(parser: argparse.ArgumentParser) -> None:
    """``--clock`` (:func:`add_clock_argument`) and ``--path`` (the filters' NumPy or compiled path)."""
    add_clock_argument(parser)
    parser.add_argument(
        "--path",
        nargs="+",
        default=["numpy", "compiled"],
        choices=["numpy", "compiled"],
        help="the filters' own path: NumPy forced (numpy_only) or the compiled kernels where they apply",
    )


def best_time(
    fn: Callable[[], object], repeats: int = 5, min_time: float = 0.05, clock: str = "wall"
) -> float:
    """Best time of one call of ``fn`` over ``repeats`` rounds, each long enough to time.

    A round calls ``fn`` ``k`` times with ``k`` chosen so the round lasts ``min_time`` seconds;
    ``clock`` is a key of :data:`CLOCKS`.
    """
    now = CLOCKS[clock]
    fn()  # warm-up (caches, lazy imports)
    t0 = now()
    fn()
    once = max(now() - t0, 1e-7)
    k = max(1, int(min_time / once))
    best = np.inf
    for _ in range(repeats):
        t0 = now()
        for _ in range(k):
            fn()
        best = min(best, (now() - t0) / k)
    return float(best)


def machine() -> dict[str, object]:
    """What the figures were measured on."""
    import scipy

    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "processor": platform.processor() or platform.machine(),
        "cpus_available": len(os.sched_getaffinity(0))
        if hasattr(os, "sched_getaffinity")
        else os.cpu_count(),
    }


def write_json(path: str | Path, payload: dict) -> Path:
    """Write ``payload`` (with machine facts) as indented JSON, creating folders."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"machine": machine(), **payload}, indent=2))
    return path
