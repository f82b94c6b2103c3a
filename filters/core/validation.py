"""Argument checks shared by the step functions.

Every check raises ``ValueError`` naming the argument and the expected shape, the filters'
contract for bad input (``docs/architecture.md``, "filters"). The checks are O(B n^2) and cheap
next to the filter arithmetic.
"""

from __future__ import annotations

import numpy as np

from filters.core.types import GaussianState


def as_float_array(x: object, name: str) -> np.ndarray:
    """``np.asarray(x, float64)`` with a ``ValueError`` naming ``name`` on failure."""
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array: {exc}") from None


def check_gaussian(state: GaussianState, name: str = "state") -> tuple[int, int]:
    """Check a :class:`GaussianState`; return ``(B, n)``."""
    m = np.asarray(state.m)
    P = np.asarray(state.P)
    if m.ndim != 2:
        raise ValueError(f"{name}.m must have shape (B, n); got {m.shape}")
    B, n = m.shape
    if P.shape != (B, n, n):
        raise ValueError(f"{name}.P must have shape (B, n, n) = {(B, n, n)}; got {P.shape}")
    # One sum is the fast check; it also overflows for finite entries near the float range (a
    # diverging member), which are not bad input: those go on to the health flags.
    with np.errstate(over="ignore", invalid="ignore"):
        m_sum, P_sum = m.sum(), P.sum()
    if not np.isfinite(m_sum) and not np.isfinite(m).all():
        raise ValueError(f"{name}.m has non-finite entries")
    if not np.isfinite(P_sum) and not np.isfinite(P).all():
        raise ValueError(f"{name}.P has non-finite entries")
    return B, n


def batched_matrix(A: object, B: int, shape: tuple[int, int], name: str) -> np.ndarray:
    """Accept ``shape`` or ``(B, *shape)``; return a float array, finite, of either shape."""
    A = as_float_array(A, name)
    if A.shape != shape and A.shape != (B, *shape):
        raise ValueError(f"{name} must have shape {shape} or {(B, *shape)}; got {A.shape}")
    if not np.isfinite(A).all():
        raise ValueError(f"{name} has non-finite entries")
    return A


def batched_vector(x: object, B: int, name: str, allow_scalar: bool = True) -> np.ndarray:
    """Accept a scalar or a ``(B,)`` array; return a ``(B,)`` float array."""
    x = as_float_array(x, name)
    if x.ndim == 0 and allow_scalar:
        return np.full(B, float(x))
    if x.shape != (B,):
        raise ValueError(f"{name} must be a scalar or have shape ({B},); got {x.shape}")
    return x


def check_measurement(z: object, mask: object, B: int, m: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Check ``z (B, m)`` and ``mask (B, m)``.

    A non-finite entry of ``z`` in an unmasked row raises ``ValueError``: masked rows may hold
    anything (NaN included); an unmasked NaN is a caller's bug that must not pass silently.

    Returns:
        ``(z, mask)`` with masked entries of ``z`` set to 0 and ``mask`` boolean.

    """
    z = as_float_array(z, "z")
    if z.ndim != 2 or z.shape[0] != B or (m is not None and z.shape[1] != m):
        want = f"({B}, {m if m is not None else 'm'})"
        raise ValueError(f"z must have shape {want}; got {z.shape}")
    if mask is None:
        mask = np.ones(z.shape, dtype=bool)
    else:
        mask = np.asarray(mask)
        if mask.shape != z.shape:
            raise ValueError(f"mask must have shape {z.shape} like z; got {mask.shape}")
        mask = mask.astype(bool, copy=False)
    finite = np.isfinite(z)
    if not finite[mask].all():
        raise ValueError("z has non-finite entries in unmasked rows (mask them instead)")
    if not finite.all():
        z = np.where(mask, z, 0.0)
    return z, mask


def fading_factor(fading: object, B: int) -> np.ndarray | None:
    """Check a fading factor (scalar or ``(B,)``, finite, >= 1 not required but > 0)."""
    if fading is None:
        return None
    lam = batched_vector(fading, B, "fading")
    if not (np.isfinite(lam).all() and (lam > 0).all()):
        raise ValueError("fading must be finite and positive")
    return lam
