"""Per-config summary of a sweep: mean and t-interval over seeds of the trials' metrics."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from agents.reporting import markdown_table

__all__ = ["SUMMARY_METRICS", "seed_ci", "summarize_trials", "summary_table"]

#: Trial metrics summarised per config: held-out mean return, RMSE [m], divergence rate, wall time [s].
SUMMARY_METRICS = ("return", "rmse_m", "diverged", "train_wall_s")


def seed_ci(values: Sequence[float], level: float = 0.95) -> tuple[float, float, float, int]:
    """``(mean, lo, hi, n)``: Student-t interval of the mean over seeds (NaN bounds for n < 2)."""
    from scipy import stats

    x = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    n = int(x.size)
    if n == 0:
        return float("nan"), float("nan"), float("nan"), 0
    mean = float(x.mean())
    if n < 2:
        return mean, float("nan"), float("nan"), n
    half = float(stats.t.ppf(0.5 + level / 2, n - 1) * x.std(ddof=1) / math.sqrt(n))
    return mean, mean - half, mean + half, n


def summarize_trials(
    rows: Sequence[Mapping[str, Any]], labels: Sequence[str], level: float = 0.95
) -> list[dict[str, Any]]:
    """One row per config (in config order): seeds done and each metric's mean, ``_lo``, ``_hi``."""
    out = []
    for c, label in enumerate(labels):
        mine = [r for r in rows if r["config_id"] == c]
        row: dict[str, Any] = {"config": c, "label": label, "seeds": len(mine)}
        for m in SUMMARY_METRICS:
            mean, lo, hi, _ = seed_ci([float(r[m]) for r in mine if m in r], level)
            row.update({m: mean, f"{m}_lo": lo, f"{m}_hi": hi})
        out.append(row)
    return out


def _fmt(v: float, digits: int) -> str:
    return "nan" if not math.isfinite(v) else f"{v:.{digits}f}"


def _ci(row: Mapping[str, Any], m: str, digits: int) -> str:
    mean, lo, hi = row[m], row[f"{m}_lo"], row[f"{m}_hi"]
    if not math.isfinite(lo):
        return _fmt(mean, digits)
    return f"{_fmt(mean, digits)} [{_fmt(lo, digits)}, {_fmt(hi, digits)}]"


def summary_table(summary: Sequence[Mapping[str, Any]]) -> str:
    """The summary as a markdown table (mean [95 % CI] over seeds); ends with a newline."""
    rows = [
        (
            r["label"],
            r["seeds"],
            _ci(r, "return", 1),
            _ci(r, "rmse_m", 2),
            _fmt(r["diverged"], 3),
            _fmt(r["train_wall_s"], 0),
        )
        for r in summary
    ]
    head = ("config", "seeds", "held-out return", "RMSE [m]", "diverged", "train wall [s]")
    return markdown_table(rows, head, align="lrrrrr")
