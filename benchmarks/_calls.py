"""How many calls a piece of work makes, and how much of it runs inside compiled kernels.

A step of B = 16 episodes that costs hundreds of microseconds while its arithmetic is a few
thousand flops is bound by call overhead, not by work: each Python function call or NumPy
call on a small array costs about a microsecond or more. :func:`count_calls` runs the work
once under :mod:`cProfile` (the standard library's deterministic profiler) and reports the
calls it counts (Python functions, built-in functions and methods; not ufuncs) and the calls into Numba
kernels with the time inside them. Numba reports a kernel call to an active profiler under the
kernel's Python source (``numba/_dispatcher.cpp``), which is how kernels are told apart here.
The profiler slows the Python calls several-fold but not a kernel's compiled loop, so the
kernel time it reports (with the kernel's dispatch) is close to the plain run's.
"""

from __future__ import annotations

import cProfile
import gc
import pstats
from collections.abc import Callable
from typing import NamedTuple


class CallCount(NamedTuple):
    """Calls of one run under the profiler (:func:`count_calls`)."""

    #: calls the profiler counts: Python functions and built-in C functions and methods (NumPy's
    #: array functions and methods); not ufunc calls such as ``np.maximum(a, b)``, which it does
    #: not see, so a lower bound of the calls that cost overhead
    calls: int
    kernel_calls: int  #: calls into compiled Numba kernels (among ``calls``)
    kernel_seconds: float  #: time inside those kernels, their dispatch included
    seconds: float  #: the run's time under the profiler (inflated by it)


def _kernel_sources() -> set[tuple[str, int, str]]:
    """``(file, first line, name)`` of every Numba dispatcher alive: pstats' key of its calls."""
    try:
        from numba.core.registry import CPUDispatcher
    except ImportError:  # pragma: no cover - Numba is a dependency
        return set()
    sources = set()
    for obj in gc.get_objects():
        if isinstance(obj, CPUDispatcher):
            code = obj.py_func.__code__
            sources.add((code.co_filename, code.co_firstlineno, code.co_name))
    return sources


def count_calls(work: Callable[[], object]) -> CallCount:
    """Run ``work()`` once under :mod:`cProfile`; its calls and its compiled kernels' share."""
    profiler = cProfile.Profile()
    profiler.enable()
    try:
        work()
    finally:
        profiler.disable()
    profiled = pstats.Stats(profiler)
    stats = profiled.stats  # type: ignore[attr-defined]
    kernels = _kernel_sources()
    calls = kernel_calls = 0
    kernel_seconds = 0.0
    for key, (_, ncalls, tottime, _, _) in stats.items():
        calls += ncalls
        if key in kernels:
            kernel_calls += ncalls
            kernel_seconds += tottime
    return CallCount(calls, kernel_calls, kernel_seconds, float(profiled.total_tt))  # type: ignore[attr-defined]
