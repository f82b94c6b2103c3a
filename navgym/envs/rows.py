"""Row operations on NamedTuples of batched arrays (episodes, filter states).

A vector environment resets some of its B episodes while the others go on: the new episodes'
rows replace the finished ones in every array with a leading episode axis, nested NamedTuples
included; metadata fields (not arrays with that axis) are kept.
"""

from __future__ import annotations

from typing import Any, NamedTuple

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


def epoch_index(t: np.ndarray) -> tuple[Any, Any]:
    """The index of row ``b``'s epoch ``t_b`` in arrays ``(B, T, ...)``: ``a[epoch_index(t)]``.

    Where every row is at the same epoch ``k`` (a batch reset together and stepped in lock step,
    as in tuning and evaluation) it is ``(:, k)``, a view; otherwise ``(arange(B), t)``, a gather.
    Either selects the same values; a view shares the episode's memory, so it is for values that
    are read or copied (an observation's columns), not handed out.
    """
    t = np.asarray(t)
    if t.size and (t == t.flat[0]).all():
        return slice(None), int(t.flat[0])
    return np.arange(t.shape[0]), t


def _is_namedtuple(a: Any) -> bool:
    return isinstance(a, tuple) and hasattr(a, "_fields")


def finite_rows(source: Any, B: int) -> np.ndarray:
    """``(B,)``: rows of every float array field (leading episode axis) free of NaN and inf.

    Log-weights (fields named ``log_w``) may hold ``-inf`` (a particle of weight 0); everything
    else must be finite.
    """
    ok = np.ones(B, dtype=bool)
    for name, a in zip(source._fields, source, strict=True):
        if _is_namedtuple(a):
            ok &= finite_rows(a, B)
        elif isinstance(a, np.ndarray) and a.ndim >= 1 and a.shape[0] == B and a.dtype.kind in "fc":
            flat = a.reshape(B, -1)
            good = ~np.isnan(flat) & (flat != np.inf) if name == "log_w" else np.isfinite(flat)
            ok &= good.all(axis=1)
    return ok


class StridedArray(NamedTuple):
    """An array stored as its buffer in memory order and the axes that view it (see :func:`pack_layout`)."""

    buffer: np.ndarray  #: C-contiguous, the array's axes in memory order
    axes: tuple[int, ...]  #: ``buffer.transpose(axes)`` is the array


def pack_layout(source: Any) -> Any:
    """``source`` with every dense array that is neither C nor Fortran ordered as a :class:`StridedArray`.

    Pickle writes arrays in C (or Fortran) order, so a view such as a particle cloud ``(B, N, n)``
    laid out ``(B, n, N)`` comes back with another layout, and NumPy's reductions over it round
    differently. :func:`unpack_layout` restores the layout exactly. Recurses into NamedTuples.
    """
    if _is_namedtuple(source):
        return type(source)(*(pack_layout(a) for a in source))
    if (
        isinstance(source, np.ndarray)
        and source.ndim >= 2
        and not (source.flags.c_contiguous or source.flags.f_contiguous)
    ):
        order = tuple(int(i) for i in np.argsort([-abs(s) for s in source.strides], kind="stable"))
        buffer = source.transpose(order)
        if buffer.flags.c_contiguous and all(s > 0 for s in buffer.strides):
            return StridedArray(buffer, tuple(int(i) for i in np.argsort(order)))
    return source


def unpack_layout(source: Any) -> Any:
    """The inverse of :func:`pack_layout`: views with the packed arrays' original strides."""
    if isinstance(source, StridedArray):
        return source.buffer.transpose(source.axes)
    if _is_namedtuple(source):
        return type(source)(*(unpack_layout(a) for a in source))
    return source
