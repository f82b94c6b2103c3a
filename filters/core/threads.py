"""Row-parallel compiled passes: a batch's rows split over a few threads.

Every compiled pass of ``filters/`` works on a batch of independent rows (filters, particle
clouds, generators): row ``b``'s result depends on row ``b``'s inputs alone, through the same
arithmetic whatever the batch. So the rows can be cut into contiguous chunks and the chunks run
at once on several cores, and the result is the same bit for bit as one call over the whole
batch. The kernels that run this way are compiled with ``nogil=True`` (Numba releases the GIL
inside them), so Python threads run them in parallel; :func:`over_rows` is the one place that
splits a pass.

Why threads here and not Numba's ``parallel=True``: Numba picks its threading layer at first
use, and the one available on most Linux machines (GNU OpenMP) is not fork-safe, while the
tuning and evaluation workers are forked (:mod:`agents.workers`). A
:class:`~concurrent.futures.ThreadPoolExecutor` created per process (a forked child makes its
own) has none of that, and the calling thread takes chunks like the pool's threads.

How many threads: :func:`get_num_threads`, by default the cores this process may run on
(as NumPy's BLAS and Numba do), or the environment variable ``NAVGYM_NUM_THREADS``;
:func:`set_num_threads` changes it and :func:`num_threads` sets it inside a block. Processes
that already run one per core (the forked tuning workers, ``SubprocVecEnv``'s) should use 1.
A pass runs on one thread when its work is below :data:`MIN_WORK` elements (the hand-off to a
thread costs some tens of microseconds), so small batches, such as 16 training sub-envs, are
not affected.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import numpy as np

__all__ = [
    "ENV_VAR",
    "CHUNKS_PER_THREAD",
    "MIN_WORK",
    "available_cores",
    "chunks",
    "get_num_threads",
    "matmul",
    "num_threads",
    "over_rows",
    "set_num_threads",
]

#: Environment variable: the number of threads of the row-parallel passes (default: the cores).
ENV_VAR = "NAVGYM_NUM_THREADS"

#: Elements (a row's size times the rows) below which a pass runs on the calling thread alone.
MIN_WORK = 1 << 16


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the OS tells it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)  # pragma: no cover - platforms without affinity


def _from_environment() -> int:
    raw = os.environ.get(ENV_VAR, "").strip()
    if not raw:
        return available_cores()
    try:
        value = int(raw)
    except ValueError:
        raise ValueError(f"{ENV_VAR} must be a positive integer; got {raw!r}") from None
    if value < 1:
        raise ValueError(f"{ENV_VAR} must be a positive integer; got {raw!r}")
    return value


_threads = _from_environment()
_min_work = MIN_WORK
_pool: ThreadPoolExecutor | None = None
_pool_key: tuple[int, int] | None = None  # (process id, workers) the pool was made for
_pool_lock = threading.Lock()
_local = threading.local()  # .inside: this thread runs a chunk (a nested pass stays on it)


def _after_fork_in_child() -> None:
    """A forked child starts without the parent's pool (its threads are not copied) or lock state."""
    global _pool, _pool_key, _pool_lock
    _pool, _pool_key, _pool_lock = None, None, threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)


def get_num_threads() -> int:
    """The threads a row-parallel pass may use (module docstring)."""
    return _threads


def set_num_threads(n: int) -> None:
    """Use ``n >= 1`` threads for the row-parallel passes from now on (1: the calling thread only)."""
    global _threads
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"n must be a positive integer; got {n!r}")
    _threads = n


@contextmanager
def num_threads(n: int, min_work: int | None = None) -> Iterator[None]:
    """:func:`set_num_threads` inside the block, the previous value after it.

    Args:
        n: threads (>= 1).
        min_work: also the work below which a pass stays on one thread (default
            :data:`MIN_WORK`; tests lower it to split small batches).
    """
    global _min_work
    if min_work is not None and (isinstance(min_work, bool) or not isinstance(min_work, int) or min_work < 0):
        raise ValueError(f"min_work must be a non-negative integer; got {min_work!r}")
    previous, previous_work = _threads, _min_work
    set_num_threads(n)  # checks n before anything changes
    if min_work is not None:
        _min_work = min_work
    try:
        yield
    finally:
        set_num_threads(previous)
        _min_work = previous_work


def _executor(workers: int) -> ThreadPoolExecutor:
    """The pool of ``workers`` threads of this process (a forked child does not inherit the parent's)."""
    global _pool, _pool_key
    key = (os.getpid(), workers)
    with _pool_lock:
        if _pool is None or _pool_key != key:
            if _pool is not None and _pool_key is not None and _pool_key[0] == key[0]:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="navgym-rows")
            _pool_key = key
        return _pool


def chunks(rows: int, parts: int) -> list[tuple[int, int]]:
    """``parts`` contiguous ``(start, stop)`` ranges covering ``range(rows)``, sizes within one."""
    parts = max(1, min(parts, rows))
    q, r = divmod(rows, parts)
    out, start = [], 0
    for p in range(parts):
        stop = start + q + (1 if p < r else 0)
        out.append((start, stop))
        start = stop
    return out


def _drain(fn: Callable[[int, int], object], todo: Iterator[tuple[int, int]], errors: list) -> None:
    """Run the chunks of ``todo`` until none is left, each taken by one thread only.

    ``next`` on a list iterator is one step under the GIL, so the threads share ``todo`` without
    a lock. A chunk's error is kept in ``errors`` and the other chunks still run (they write
    the outputs). Marked as inside a chunk: a pass ``fn`` calls runs on this thread (no pool
    deadlock).
    """
    _local.inside = True
    try:
        for start, stop in todo:
            try:
                fn(start, stop)
            except BaseException as exc:
                errors.append(exc)
    finally:
        _local.inside = False


#: Chunks per thread of a split pass: the threads take them as they come free, so a pool thread
#: that wakes late (some tens of microseconds on a virtual machine) costs part of a chunk, not the
#: whole of one; more chunks cost one more call of the pass each.
CHUNKS_PER_THREAD = 2


def over_rows(rows: int, row_size: int, fn: Callable[[int, int], object]) -> None:
    """``fn(start, stop)`` over contiguous chunks of ``range(rows)``, on several threads if it pays.

    ``fn`` must compute rows ``start:stop`` only (a compiled ``nogil`` kernel on the row slices
    of its arrays), so that the chunks are independent and the result does not depend on the
    split. One call ``fn(0, rows)`` on this thread when one thread is set, when there are fewer
    than two rows, when ``rows * row_size`` is below the work threshold (module docstring), or
    inside a chunk of another :func:`over_rows` (a nested pass). Otherwise the rows are cut
    into :data:`CHUNKS_PER_THREAD` chunks per thread, which this thread and the pool's take as
    they come free (a pool thread that has not started when this one runs out is not waited
    for); the first error raised by a chunk is raised here after every chunk has run.

    Args:
        rows: the batch size.
        row_size: the elements a row's pass touches (its cost, for the threshold).
        fn: the pass over rows ``start:stop``.
    """
    threads = min(_threads, rows)
    if threads <= 1 or rows * row_size < _min_work or getattr(_local, "inside", False):
        fn(0, rows)
        return
    todo = iter(chunks(rows, threads * CHUNKS_PER_THREAD))
    errors: list[BaseException] = []
    pool = _executor(threads - 1)
    futures = [pool.submit(_drain, fn, todo, errors) for _ in range(threads - 1)]
    _drain(fn, todo, errors)
    for f in futures:
        if not f.cancel():  # started: it is running a chunk, wait for it
            f.result()
    if errors:
        raise errors[0]


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` of a stack of matrices, the stack split over threads by :func:`over_rows`.

    ``a (B, r, k)`` or ``(r, k)`` times ``b (B, k, c)`` or ``(k, c)``, at least one of them
    stacked: NumPy's ``matmul`` releases the GIL and computes each matrix of the stack by the
    same call whatever the stack around it, so the product equals ``np.matmul(a, b)`` bit for
    bit. Other shapes are passed to ``np.matmul`` unchanged.
    """
    stacked = [x.ndim == 3 for x in (a, b)]
    if not any(stacked) or a.ndim not in (2, 3) or b.ndim not in (2, 3):
        return np.matmul(a, b)
    B = a.shape[0] if stacked[0] else b.shape[0]
    if (stacked[0] and a.shape[0] != B) or (stacked[1] and b.shape[0] != B):
        return np.matmul(a, b)  # NumPy's broadcasting (or its error)
    r, c = a.shape[-2], b.shape[-1]
    out = np.empty((B, r, c), dtype=np.result_type(a, b))

    def rows(start: int, stop: int) -> None:
        np.matmul(a[start:stop] if stacked[0] else a, b[start:stop] if stacked[1] else b, out=out[start:stop])

    over_rows(B, r * a.shape[-1] + a.shape[-1] * c, rows)
    return out
