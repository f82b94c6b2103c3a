"""Shared timing helpers for the benchmark commands (single core, best of k)."""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

import numpy as np


@contextmanager
def single_core():
    """Limit BLAS/OpenMP pools to one thread (threadpoolctl) for per-core figures."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


def best_time(fn: Callable[[], object], repeats: int = 5, min_time: float = 0.05) -> float:
    """Best wall time of one call of ``fn`` over ``repeats`` rounds, each long enough to time.

    A round calls ``fn`` ``k`` times with ``k`` chosen so the round lasts ``min_time`` seconds.
    """
    fn()  # warm-up (caches, lazy imports)
    t0 = time.perf_counter()
    fn()
    once = max(time.perf_counter() - t0, 1e-7)
    k = max(1, int(min_time / once))
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(k):
            fn()
        best = min(best, (time.perf_counter() - t0) / k)
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
