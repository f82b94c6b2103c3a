"""Row operations on NamedTuples of batched arrays (episodes, filter states).

A vector environment resets some of its B episodes while the others go on: the new episodes'
rows replace the finished ones in every array with a leading episode axis, nested NamedTuples
included; metadata fields (not arrays with that axis) are kept.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def replace_rows(target: Any, idx: np.ndarray, source: Any, inplace: bool = False) -> Any:
    """NamedTuple ``target`` with rows ``idx`` of its arrays replaced by ``source``'s rows.

    With ``inplace`` the writeable arrays of ``target`` are modified (no copy of the whole batch:
    the episode data the core owns); otherwise, or for read-only views, a copy is made. Fields
    that are not arrays with a leading episode axis (metadata) are taken from ``target``.
    """
    if target is None:
        return source
    out = []
    for a, b in zip(target, source, strict=True):
        if (
            isinstance(a, np.ndarray)
            and a.ndim >= 1
            and isinstance(b, np.ndarray)
            and b.shape[1:] == a.shape[1:]
        ):
            if not (inplace and a.flags.writeable):
                a = a.copy(order="K")  # keep the layout (e.g. a particle cloud's (B, n, N) buffer)
            a[idx] = b
        elif isinstance(a, tuple) and hasattr(a, "_fields"):
            a = replace_rows(a, idx, b, inplace)
        out.append(a)
    return type(target)(*out)


def take_rows(source: Any, idx: np.ndarray) -> Any:
    """NamedTuple with the rows ``idx`` of every array field (metadata kept)."""
    out = []
    for a in source:
        if isinstance(a, np.ndarray) and a.ndim >= 1:
            a = a[idx]
        elif isinstance(a, tuple) and hasattr(a, "_fields"):
            a = take_rows(a, idx)
        out.append(a)
    return type(source)(*out)
