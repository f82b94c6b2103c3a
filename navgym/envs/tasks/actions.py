"""The one check of every task's action: :func:`check_action`.

A Box action must be an array of real numbers (no bools, complex numbers, strings or objects)
of the batch shape, finite; values outside the box are clipped and counted. A Discrete action
must be an integer in range (an integral float such as ``1.0`` names it too). Every rejection is
a ``ValueError`` naming the action and the action space, raised before anything changes.
"""

from __future__ import annotations

from typing import Any, cast

import numpy as np
from gymnasium import spaces


def _shown(action: Any, limit: int = 120) -> str:
    text = repr(action)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _accepted(space: spaces.Space, batch: tuple[int, ...]) -> tuple[list[tuple[int, ...]], int]:
    """The accepted shapes of actions of ``space`` with the leading axes ``batch``, and its size."""
    shape = tuple(space.shape or ())
    dim = 1  # the product of the shape (cheaper than np.prod for a few ints)
    for k in shape:
        dim *= int(k)
    return [(*batch, *shape)] + ([(*batch,), (*batch, 1)] if dim == 1 else []), dim


def check_single_shape(action: Any, space: spaces.Space) -> None:
    """A single env's action of a wrong shape refused with the single env's shapes (``ValueError``).

    The single env batches its action as ``(1, ...)`` for the core; this check runs before, so
    the error names ``space.shape`` (and ``()`` or ``(1,)`` for one number), not the batch axis.
    Anything that is not an array of real numbers is left to :func:`check_action`.
    """
    try:
        a = np.asarray(action)
    except (TypeError, ValueError):
        return
    if a.dtype.kind not in "iuf":
        return
    accepted, _ = _accepted(space, ())
    if a.shape not in accepted:
        want = " or ".join(str(s) for s in dict.fromkeys(accepted))
        raise ValueError(
            f"action {_shown(action)} is not an action of the action space {space}: "
            f"shape {a.shape}, expected {want}"
        )


def check_action(action: Any, space: spaces.Space, B: int) -> tuple[np.ndarray, np.ndarray]:
    """A batch of ``B`` actions of ``space``, validated: ``(values, clipped)``.

    Box: ``values (B, dim)`` float64 clipped into the box and ``clipped (B,)`` where a row was
    outside it. Discrete: ``values (B,)`` int64 and ``clipped`` all False. Accepted shapes are
    ``(B, *space.shape)``, and ``(B,)`` or ``(B, 1)`` when an action is one number.

    Raises:
        ValueError: naming the action and the space, for anything else: not an array of real
            numbers (bools, complex numbers, strings, objects), a wrong shape, NaN or inf, a
            Discrete action that is not an integer of the space.
    """

    def reject(why: str) -> ValueError:
        # formatted on error only: the space's repr costs more than the checks of a valid action
        where = f"the action space {space}" + (f" (batched over {B} sub-environments)" if B > 1 else "")
        return ValueError(f"action {_shown(action)} is not an action of {where}: {why}")

    try:
        a = np.asarray(action)
    except (TypeError, ValueError) as exc:  # ragged nested sequences
        raise reject(f"not an array of numbers ({exc})") from None
    if a.dtype.kind == "b":
        raise reject("bools are not actions (pass numbers)")
    if a.dtype.kind not in "iuf":
        raise reject(f"an action must consist of real numbers; got dtype {a.dtype}")
    accepted, dim = _accepted(space, (B,))
    if a.shape not in accepted:
        want = " or ".join(str(s) for s in dict.fromkeys(accepted))
        raise reject(f"shape {a.shape}, expected {want}")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise reject("it must be finite (got NaN or inf)")
    if isinstance(space, spaces.Discrete):
        lo, n = int(space.start), int(space.n)
        what = "0 or 1" if (lo, n) == (0, 2) else f"an integer in [{lo}, {lo + n - 1}]"
        if a.dtype.kind == "f" and (a != np.round(a)).any():  # 0.9 would silently mean 0
            raise reject(f"it must be {what} (an integer)")
        if ((a < lo) | (a > lo + n - 1)).any():
            raise reject(f"it must be {what}")
        return a.reshape(B).astype(np.int64), np.zeros(B, dtype=bool)
    box = cast(spaces.Box, space)  # a task's action space is a Box or Discrete
    low = np.asarray(box.low, dtype=np.float64).reshape(dim)
    high = np.asarray(box.high, dtype=np.float64).reshape(dim)
    x = a.astype(np.float64).reshape(B, dim)
    with np.errstate(over="ignore"):  # a float128 beyond float64 becomes inf, then the bound
        clipped = np.asarray(((x < low) | (x > high)).any(axis=1))
    return np.minimum(np.maximum(x, low), high), clipped  # np.clip's values (x is finite)
