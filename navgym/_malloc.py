"""glibc allocator tuning for batched NumPy workloads.

Batched filter steps allocate many short-lived arrays of a few hundred kB. With glibc's default
``M_MMAP_THRESHOLD`` (128 kB, adjusted dynamically) such arrays may be ``mmap``-ed and unmapped
on every call, paying page faults on each touch, which makes batched steps several times slower
(``docs/performance.md``, "Allocator"). Raising the mmap and trim thresholds keeps those blocks
on the heap.

It changes a process-wide setting, so it is **opt-in**: call :func:`navgym.tune_malloc` (the
benchmark commands do, at start), or set ``NAVGYM_MALLOPT=1`` to have ``import navgym`` call it.
Without either, importing navgym changes no process setting. ``NAVGYM_NO_MALLOPT=1`` vetoes it
(to measure without it). It is a no-op on non-glibc platforms.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

M_TRIM_THRESHOLD = -1
M_TOP_PAD = -2
M_MMAP_THRESHOLD = -3
_done = False


def tune_malloc(mmap_threshold: int = 256 * 2**20, trim_threshold: int = 512 * 2**20) -> bool:
    """Raise glibc's mmap/trim thresholds (``mallopt``), once per process; return True when applied.

    Args:
        mmap_threshold: bytes from which ``malloc`` uses ``mmap`` (``M_MMAP_THRESHOLD``).
        trim_threshold: free bytes at the heap top above which it is returned to the system
            (``M_TRIM_THRESHOLD``).

    Returns:
        Whether the thresholds are set: False on non-glibc platforms, when ``mallopt`` refuses a
        value, or with ``NAVGYM_NO_MALLOPT`` set.
    """
    global _done
    if _done or os.environ.get("NAVGYM_NO_MALLOPT"):
        return _done
    name = ctypes.util.find_library("c")
    if not name:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    ok = bool(mallopt(M_MMAP_THRESHOLD, mmap_threshold)) and bool(mallopt(M_TRIM_THRESHOLD, trim_threshold))
    mallopt(M_TOP_PAD, 64 * 2**20)
    _done = ok
    return ok
