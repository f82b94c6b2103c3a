"""The switch between the compiled (Numba) kernels of ``filters/`` and their NumPy twins.

Some hot loops of ``filters/`` have a compiled kernel beside the NumPy code that defines them
(``docs/architecture.md``, "filters": compiled kernels). The public step functions choose the
kernel internally where the layout, dtype and sizes allow it and fall back to the NumPy path
otherwise; both give the same results to rounding (``tests/filters`` hold them equal on the same
draws). This module is the one documented switch that forces the NumPy path everywhere, for
debugging and for the equality tests:

* the environment variable ``NAVGYM_NUMPY_ONLY=1`` (read when :mod:`filters` is imported;
  any value other than ``""`` and ``"0"`` counts) disables every compiled kernel;
* ``with numpy_only(): ...`` disables them inside the block (in the current thread or
  asyncio task; it nests, and ``numpy_only(False)`` re-enables them inside it unless the
  environment variable is set).

First use compiles each kernel and caches the machine code next to its module (Numba's
``cache=True``, in ``__pycache__``); later processes load it from there.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

__all__ = ["ENV_VAR", "compiled_enabled", "numpy_only"]

#: Environment variable that forces the NumPy path in every process that reads it.
ENV_VAR = "NAVGYM_NUMPY_ONLY"
_ENV_FORCED = os.environ.get(ENV_VAR, "") not in ("", "0")
_numpy_only: ContextVar[bool] = ContextVar("navgym_filters_numpy_only", default=False)


def compiled_enabled() -> bool:
    """True unless ``NAVGYM_NUMPY_ONLY`` is set or a :func:`numpy_only` block is active."""
    return not (_ENV_FORCED or _numpy_only.get())


@contextmanager
def numpy_only(enabled: bool = True) -> Iterator[None]:
    """Force the NumPy path of every ``filters`` step inside the block (module docstring).

    Args:
        enabled: True forces NumPy; False lets the compiled kernels run again inside an
            outer ``numpy_only()`` block (the environment variable still wins).
    """
    token = _numpy_only.set(bool(enabled))
    try:
        yield
    finally:
        _numpy_only.reset(token)
