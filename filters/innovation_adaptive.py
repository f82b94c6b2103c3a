"""Innovation-based adaptive estimation of R and chi-square fault detection and exclusion.

Two classical ways a filter reacts to its own innovations ``v = z - z_hat`` with predictive
covariance ``S = H P- H^T + R`` (``UpdateInfo.innovation``, ``UpdateInfo.S``), as pure
functions on small NamedTuple memories, batched over B filters, masks respected:

* **Innovation-based adaptive estimation** (IAE; Mehra 1970, Mohamed & Schwarz 1999, eq. 20-23):
  over a window of the last ``N`` epochs the innovation covariance is estimated as
  ``C_v = (1/N) sum_j v_j v_j^T`` and ``R_hat = C_v - H P- H^T = C_v - (S - R)``. For
  independent rows (diagonal ``R``) each row is estimated from the epochs in which it was
  received: ``R_hat_ii = mean(v_i^2) - mean(S_ii - R_ii)``, floored at a fraction of the nominal
  ``R_ii`` (a window of few samples can give a negative difference). :func:`iae_update` returns
  the per-row ratio ``R_hat_ii / R_ii``, the scale a noise-scaling knob applies.
* **Chi-square fault detection and exclusion** (a RAIM-like test; Brown & Chin 1997 for the
  parity form, here on the innovations): the epoch is consistent when
  ``NIS = v^T S^-1 v <= chi2_{1-alpha}(n_used)``; otherwise the row with the largest normalized
  innovation ``v_i^2 / S_ii`` is excluded and the test repeated on the remaining rows (the
  innovations of a prior predictive density do not depend on which rows are kept), up to
  ``max_exclusions`` rows.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.stats import chi2

from filters.core.compiled import compiled_enabled
from filters.core.nis_kernels import masked_nis_pass, masked_sum_of_squares_pass
from filters.core.validation import as_float_array

__all__ = [
    "IaeMemory",
    "iae_init",
    "iae_update",
    "chi_square_exclusion",
    "chi2_thresholds",
    "ExclusionResult",
]


class IaeMemory(NamedTuple):
    """Window of the last ``N`` epochs per filter and row (a ring buffer).

    Attributes:
        v2: squared innovations ``v_i^2``, ``(B, N, m)``.
        hph: ``S_ii - R_ii`` (the filter's own predicted spread ``(H P- H^T)_ii``), ``(B, N, m)``.
        used: whether row i was received at that epoch, ``(B, N, m)``.
        k: epochs seen, ``(B,)`` (the ring position is ``k % N``).

    """

    v2: np.ndarray
    hph: np.ndarray
    used: np.ndarray
    k: np.ndarray


def iae_init(B: int, m: int, window: int) -> IaeMemory:
    """An empty window of ``window`` epochs for ``B`` filters with ``m`` rows."""
    if window < 1:
        raise ValueError(f"window must be >= 1; got {window}")
    z = np.zeros((B, window, m))
    return IaeMemory(z, z.copy(), np.zeros((B, window, m), dtype=bool), np.zeros(B, dtype=np.int64))


def iae_update(
    memory: IaeMemory,
    innovation: np.ndarray,
    S: np.ndarray,
    R: np.ndarray,
    mask: np.ndarray,
    floor: float = 0.1,
) -> tuple[IaeMemory, np.ndarray]:
    """Add one epoch and return ``(memory, ratio (B, m))`` with ``ratio_i = R_hat_ii / R_ii``.

    Args:
        memory: the window (:func:`iae_init`).
        innovation: ``v (B, m)`` of this epoch (any value on masked rows).
        S: its predictive covariance ``(B, m, m)`` (only the diagonal is used).
        R: the filter's nominal ``R``, ``(m, m)`` or ``(B, m, m)`` (its diagonal).
        mask: ``(B, m)`` rows received this epoch.
        floor: lower bound of the ratio (> 0).

    Returns:
        The new memory and the per-row ratio; a row never received in the window keeps 1.

    """
    B, N, m = memory.v2.shape
    v = as_float_array(innovation, "innovation")
    S = as_float_array(S, "S")
    R = as_float_array(R, "R")
    mask = np.asarray(mask, dtype=bool)
    if v.shape != (B, m) or S.shape != (B, m, m) or mask.shape != (B, m):
        raise ValueError(f"innovation, S, mask must have shapes ({B}, {m}), ({B}, {m}, {m}), ({B}, {m})")
    if R.shape not in ((m, m), (B, m, m)):
        raise ValueError(f"R must have shape ({m}, {m}) or ({B}, {m}, {m}); got {R.shape}")
    if not floor > 0:
        raise ValueError(f"floor must be > 0; got {floor}")
    r = np.broadcast_to(np.diagonal(R, axis1=-2, axis2=-1), (B, m))
    s = np.diagonal(S, axis1=1, axis2=2)
    slot = memory.k % N
    rows = np.arange(B)
    v2, hph, used = memory.v2.copy(), memory.hph.copy(), memory.used.copy()
    v2[rows, slot] = np.where(mask, v * v, 0.0)
    hph[rows, slot] = np.where(mask, s - r, 0.0)
    used[rows, slot] = mask
    new = IaeMemory(v2, hph, used, memory.k + 1)
    count = used.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        r_hat = (v2.sum(axis=1) - hph.sum(axis=1)) / count
        ratio = np.where(count > 0, r_hat / r, 1.0)
    return new, np.maximum(ratio, floor)


class ExclusionResult(NamedTuple):
    """Outcome of :func:`chi_square_exclusion`.

    Attributes:
        mask: rows kept, ``(B, m)``.
        excluded: rows excluded by the test, ``(B, m)``.
        nis: ``v^T S^-1 v`` over the kept rows, ``(B,)``.
        consistent: the kept rows pass the test, ``(B,)`` (False when ``max_exclusions`` was
            reached and the rest still fails).

    """

    mask: np.ndarray
    excluded: np.ndarray
    nis: np.ndarray
    consistent: np.ndarray


def _nis(v: np.ndarray, S: np.ndarray | None, keep: np.ndarray) -> np.ndarray:
    """``v^T S^-1 v`` over the kept rows (others replaced by an identity block and v = 0).

    ``S = None``: whitened innovations (``S = I``), the sum of the kept ``v_i^2``. The compiled
    twins (:func:`filters.core.nis_kernels.masked_nis_pass`, and
    :func:`~filters.core.nis_kernels.masked_sum_of_squares_pass` for ``S = None``, which gives
    ``masked_nis_pass``'s numbers for ``S = I`` bit for bit) compute it unless
    :func:`filters.core.compiled.numpy_only` forces this NumPy form or some kept block is not
    positive definite.
    """
    if S is None:
        if compiled_enabled() and v.dtype == np.float64:
            nis = np.empty(v.shape[0])
            masked_sum_of_squares_pass(np.ascontiguousarray(v), np.ascontiguousarray(keep), nis)
            return nis
        v_k = np.where(keep, v, 0.0)
        return np.einsum("bi,bi->b", v_k, v_k)
    if compiled_enabled() and v.dtype == np.float64 and S.dtype == np.float64:
        nis = np.empty(v.shape[0])
        if masked_nis_pass(np.ascontiguousarray(v), np.ascontiguousarray(S), np.ascontiguousarray(keep), nis):
            return nis
    m = v.shape[1]
    k2 = keep[:, :, None] & keep[:, None, :]
    S_k = np.where(k2, S, np.eye(m))
    v_k = np.where(keep, v, 0.0)
    return np.einsum("bi,bi->b", v_k, np.linalg.solve(S_k, v_k[..., None])[..., 0])


@lru_cache(maxsize=32)
def chi2_thresholds(alpha: float, m: int) -> np.ndarray:
    """``chi2_{1-alpha}(k)`` for ``k = 0 .. m`` rows (index k; k = 0 holds the one-row value).

    The test's threshold for every row count at once, computed once per ``(alpha, m)``:
    ``scipy.stats.chi2.ppf`` costs about 0.4 ms a call, more than the rest of an epoch's test.
    Read-only.
    """
    table = chi2.ppf(1.0 - alpha, np.maximum(np.arange(m + 1), 1))
    table.flags.writeable = False
    return table


def chi_square_exclusion(
    innovation: np.ndarray,
    S: np.ndarray | None,
    mask: np.ndarray,
    alpha: float | np.ndarray = 0.01,
    max_exclusions: int | np.ndarray = 2,
) -> ExclusionResult:
    """Chi-square test of the innovations and exclusion of the worst rows (module docstring).

    Args:
        innovation: ``v (B, m)`` from the prior predictive density (before the update).
        S: ``(B, m, m)`` its covariance, or None for whitened innovations (``S = I``: the NIS
            is the sum of the kept ``v_i^2``, with the numbers ``S = I`` gives).
        mask: ``(B, m)`` rows received.
        alpha: false-alarm probability of the test, in (0, 1): one for every filter, or one
            per filter ``(B,)`` (a tuning grid's rows).
        max_exclusions: most rows excluded per epoch (an integer >= 0; at least one row is
            always kept): one for every filter, or one per filter ``(B,)``.

    Each filter's result depends on its own inputs and parameters only, so per-filter
    parameters give what separate calls per parameter value give, bit for bit.
    """
    v = as_float_array(innovation, "innovation")
    keep = np.asarray(mask, dtype=bool).copy()
    B, m = v.shape
    if S is not None:
        S = as_float_array(S, "S")
    if (S is not None and S.shape != (B, m, m)) or keep.shape != (B, m):
        raise ValueError(f"S and mask must have shapes ({B}, {m}, {m}) and ({B}, {m})")
    a = np.asarray(alpha, dtype=np.float64)
    k = np.asarray(max_exclusions, dtype=np.float64)
    for name, x in (("alpha", a), ("max_exclusions", k)):
        if x.shape not in ((), (B,)):
            raise ValueError(f"{name} must be a scalar or one per filter ({B},); got shape {x.shape}")
    # scalars checked as Python floats: a handful of 0-d ufunc calls cost more than the test
    if not (0.0 < float(a) < 1.0 if a.ndim == 0 else ((a > 0.0) & (a < 1.0)).all()):
        raise ValueError(f"alpha must lie in (0, 1); got {alpha}")
    k_int = k.astype(np.int64) if np.isfinite(k).all() else np.full(k.shape, -1)
    if not ((k_int == k) & (k_int >= 0)).all():
        raise ValueError(f"max_exclusions must be an integer >= 0; got {max_exclusions}")
    if a.ndim == 0:
        table = chi2_thresholds(float(a), m)

        def threshold(n: np.ndarray) -> np.ndarray:
            return table[n]
    else:
        values, which = np.unique(a, return_inverse=True)
        tables = np.stack([chi2_thresholds(float(x), m) for x in values])[which]  # (B, m + 1)
        rows = np.arange(B)

        def threshold(n: np.ndarray) -> np.ndarray:
            return tables[rows, n]

    z2 = v * v if S is None else v * v / np.maximum(np.diagonal(S, axis1=1, axis2=2), 1e-300)
    nis = _nis(v, S, keep)
    n = keep.sum(axis=1)
    ok = (n == 0) | (nis <= threshold(n))
    per_filter = k_int.ndim == 1
    for it in range(int(k_int.max()) if k_int.size else 0):
        act = ~ok & (n > 1) & (it < k_int) if per_filter else ~ok & (n > 1)
        if not act.any():
            break
        worst = np.argmax(np.where(keep, z2, -np.inf), axis=1)
        keep[act, worst[act]] = False
        nis = _nis(v, S, keep)
        n = keep.sum(axis=1)
        ok = (n == 0) | (nis <= threshold(n))
    return ExclusionResult(keep, np.asarray(mask, dtype=bool) & ~keep, nis, ok)
