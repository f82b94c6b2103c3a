"""Helpers of the compiled-vs-NumPy equality tests: run both paths, count kernel calls."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from contextlib import nullcontext
from types import ModuleType
from typing import Any

import pytest

from filters.core.compiled import numpy_only


def both_paths(fn: Callable[[], Any]) -> tuple[Any, Any]:
    """``fn()`` on the compiled path, then on the NumPy path forced by :func:`numpy_only`."""
    out = {}
    for path in ("compiled", "numpy"):
        with numpy_only() if path == "numpy" else nullcontext():
            out[path] = fn()
    return out["compiled"], out["numpy"]


def count_calls(monkeypatch: pytest.MonkeyPatch, module: ModuleType, names: Iterable[str]) -> dict[str, int]:
    """Wrap the kernels ``names`` of ``module`` so that each call is counted; the live counts.

    A test asserts a count to show that the kernel it compares with the NumPy path really ran.
    """
    counts = dict.fromkeys(names, 0)
    for name in counts:
        original = getattr(module, name)

        def counted(*args, _name=name, _f=original):
            counts[_name] += 1
            return _f(*args)

        monkeypatch.setattr(module, name, counted)
    return counts
