"""Percentile bootstrap over episodes (seeded NumPy generator) for means and paired differences."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

__all__ = [
    "DEFAULT_LEVEL",
    "DEFAULT_RESAMPLES",
    "bootstrap_mean_ci",
    "paired_difference",
    "paired_statistic_ci",
]

DEFAULT_RESAMPLES = 2000
DEFAULT_LEVEL = 0.95


def bootstrap_mean_ci(
    x: np.ndarray, n_boot: int = DEFAULT_RESAMPLES, level: float = DEFAULT_LEVEL, seed: int = 0
) -> tuple[float, float, float, int]:
    """Mean of the finite values of ``x`` and its percentile bootstrap CI.

    Episodes are resampled with replacement ``n_boot`` times (``np.random.default_rng(seed)``);
    the CI is the ``(1 - level)/2`` and ``(1 + level)/2`` quantiles of the resampled means.

    Returns:
        ``(mean, low, high, n)``; NaNs when no value is finite, ``low = high = mean`` for n = 1.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1); got {level}")
    if n_boot < 1:
        raise ValueError(f"n_boot must be >= 1; got {n_boot}")
    x = np.asarray(x, dtype=np.float64).ravel()
    x = x[np.isfinite(x)]
    n = x.size
    if n == 0:
        return float("nan"), float("nan"), float("nan"), 0
    mean = float(x.mean())
    if n == 1:
        return mean, mean, mean, 1
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, n, size=(n_boot, n))
    means = x[idx].mean(axis=1)
    lo, hi = np.quantile(means, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return mean, float(lo), float(hi), n


def paired_difference(
    a: np.ndarray, b: np.ndarray, n_boot: int = DEFAULT_RESAMPLES, level: float = DEFAULT_LEVEL, seed: int = 0
) -> dict[str, float]:
    """Mean of ``a - b`` over the episodes where both are finite, with its bootstrap CI.

    ``a`` and ``b`` are per-episode values of two policies on the *same* episodes, so the
    bootstrap resamples episodes (pairs), which keeps the episode-to-episode variation out of the
    difference.

    Returns:
        ``{"mean_diff", "low", "high", "n", "significant"}`` (``significant``: the CI excludes 0).
    """
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"paired samples need equal lengths; got {a.shape} and {b.shape}")
    ok = np.isfinite(a) & np.isfinite(b)
    mean, lo, hi, n = bootstrap_mean_ci(a[ok] - b[ok], n_boot, level, seed)
    sig = bool(n > 1 and (lo > 0 or hi < 0))
    return {"mean_diff": mean, "low": lo, "high": hi, "n": n, "significant": sig}


def paired_statistic_ci(
    samples: Sequence[np.ndarray],
    statistic: Callable[[np.ndarray], np.ndarray],
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    seed: int = 0,
) -> tuple[float, float, float, int]:
    """``statistic`` of the means of ``k`` paired samples, with its percentile bootstrap CI.

    ``samples`` are ``k`` per-episode arrays on the *same* episodes (an episode with a non-finite
    value in any is dropped). ``statistic`` maps the column means, an array ``(..., k)``, to the
    statistic (vectorized over the leading axes), e.g. a ratio of mean RMSEs. Each of ``n_boot``
    resamples draws episodes with replacement, jointly for the ``k`` samples
    (``np.random.default_rng(seed)``, as :func:`bootstrap_mean_ci`); resamples whose statistic
    is not finite are left out; the CI is the ``(1 -+ level)/2`` quantiles of the others.

    Returns:
        ``(value, low, high, n)``: NaNs when no episode is left or the full sample's statistic is
        not finite; ``low = high = value`` for n = 1; a NaN CI when no resample is finite.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1); got {level}")
    if n_boot < 1:
        raise ValueError(f"n_boot must be >= 1; got {n_boot}")
    cols = [np.asarray(a, dtype=np.float64).ravel() for a in samples]
    if len({c.shape for c in cols}) > 1:
        raise ValueError(f"paired samples need equal lengths; got {[c.shape for c in cols]}")
    x = np.stack(cols, axis=-1)  # (n, k)
    x = x[np.isfinite(x).all(axis=1)]
    n = x.shape[0]
    nan = float("nan")
    if n == 0:
        return nan, nan, nan, 0
    with np.errstate(divide="ignore", invalid="ignore"):
        value = float(statistic(x.mean(axis=0)))
    if not np.isfinite(value):
        return nan, nan, nan, n
    if n == 1:
        return value, value, value, 1
    idx = np.random.default_rng(seed).integers(0, n, size=(n_boot, n))
    with np.errstate(divide="ignore", invalid="ignore"):
        boot = np.asarray(statistic(x[idx].mean(axis=1)), dtype=np.float64)
    boot = boot[np.isfinite(boot)]
    if boot.size == 0:
        return value, nan, nan, n
    lo, hi = np.quantile(boot, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return value, float(lo), float(hi), n
