"""Observation features: named, bounded, documented columns of a flat float32 ``Box``.

Every environment declares its observation as a list of :class:`Feature`; the
:class:`FeatureSet` builds the ``Box`` (finite bounds), stacks the columns computed by the
platform and the task, and clips them into the box. The env card's Observation Space table is
generated from the same list, so documentation and space cannot drift apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces


@dataclass(frozen=True)
class Feature:
    """One observation column (or a block of ``size`` columns) with its bounds and meaning."""

    name: str
    low: float
    high: float
    unit: str
    description: str
    size: int = 1


class FeatureSet:
    """An ordered list of features: the observation space and the clipping into it."""

    def __init__(self, features: list[Feature]) -> None:
        self.features = list(features)
        lows, highs = [], []
        for f in self.features:
            if not (np.isfinite(f.low) and np.isfinite(f.high) and f.low < f.high):
                raise ValueError(f"feature {f.name!r} needs finite bounds low < high")
            lows += [f.low] * f.size
            highs += [f.high] * f.size
        self.low = np.asarray(lows, dtype=np.float32)
        self.high = np.asarray(highs, dtype=np.float32)
        self.dim = len(lows)

    def index(self, name: str) -> slice:
        """Columns of feature ``name`` in the observation (``ValueError`` if absent)."""
        i = 0
        for f in self.features:
            if f.name == name:
                return slice(i, i + f.size)
            i += f.size
        raise ValueError(f"no observation feature {name!r}; have {[f.name for f in self.features]}")

    @property
    def names(self) -> list[str]:
        """Feature names in observation order."""
        return [f.name for f in self.features]

    @property
    def space(self) -> spaces.Box:
        """The single-environment observation space."""
        return spaces.Box(self.low, self.high, dtype=np.float32)

    def build(self, columns: dict[str, np.ndarray]) -> np.ndarray:
        """Stack ``columns[name]`` (``(B,)`` or ``(B, size)``) in order; clip into the box.

        Non-finite values (possible only after a divergence) are replaced by the bound they lie
        beyond (NaN by the lower bound), so the observation stays inside the space.
        """
        obs = None
        i = 0
        for f in self.features:
            c = np.asarray(columns[f.name])
            c = c.reshape(c.shape[0], f.size)
            if obs is None:
                obs = np.empty((c.shape[0], self.dim))
            obs[:, i : i + f.size] = c  # float64, as np.asarray(c, np.float64) gives it
            i += f.size
        if obs is None:
            raise ValueError("a FeatureSet has at least one feature")
        # clip(nan_to_num(obs, nan=-inf), low, high) in two ufuncs: fmax takes the lower bound for
        # NaN, and +-inf go to the bound they lie beyond as before
        return np.minimum(np.fmax(obs, self.low), self.high).astype(np.float32)

    def table(self) -> str:
        """Markdown table for the env card (index, name, bounds, unit, meaning)."""
        rows = ["| index | name | min | max | unit | description |", "|---|---|---|---|---|---|"]
        i = 0
        for f in self.features:
            idx = f"{i}" if f.size == 1 else f"{i}-{i + f.size - 1}"
            rows.append(f"| {idx} | {f.name} | {f.low:g} | {f.high:g} | {f.unit} | {f.description} |")
            i += f.size
        return "\n".join(rows)


# ------------------------------------------------------------------ features every platform has
def innovation_features(
    m_max: int, innovation: str, rows_name: str = "rows_used", rows: str = "rows used", unit_rows: str = ""
) -> list[Feature]:
    """The innovation block every platform observes: normalized innovations, NIS, rows used.

    ``innovation`` describes the rows (e.g. "pseudo-range innovations / sqrt(S_ii), 0 where
    masked"); ``rows_name`` and ``rows`` name the count (e.g. "satellites", "satellites used").
    """
    return [
        Feature("innovation", -10.0, 10.0, "-", innovation, m_max),
        Feature("log_nis", 0.0, 10.0, "-", f"log(1 + NIS / {rows})"),
        Feature(rows_name, 0.0, 1.0, "-", unit_rows or f"{rows} / {m_max}"),
    ]


def innovation_values(
    info: Any, mask: np.ndarray, m_max: int, rows_name: str = "rows_used"
) -> dict[str, np.ndarray]:
    """Values of :func:`innovation_features` after an update.

    ``innovation_i / sqrt(S_ii)`` on the received rows (0 elsewhere), ``log(1 + NIS / n)`` with
    ``n`` the rows used, and ``n / m_max``.
    """
    S_diag = np.maximum(np.diagonal(info.S, axis1=1, axis2=2), 1e-12)
    n_used = np.maximum(info.n_meas, 1)
    return {
        "innovation": np.where(mask, info.innovation / np.sqrt(S_diag), 0.0),
        "log_nis": np.log1p(np.maximum(info.nis, 0.0) / n_used),
        rows_name: info.n_meas / m_max,
    }


def innovation_initial_values(B: int, m_max: int, rows_name: str = "rows_used") -> dict[str, np.ndarray]:
    """Values of :func:`innovation_features` at reset: no measurement processed yet."""
    return {"innovation": np.zeros((B, m_max)), "log_nis": np.zeros(B), rows_name: np.zeros(B)}


@dataclass(frozen=True)
class CovarianceBlock:
    """A log-sigma feature ``log10 sqrt(sum_i P_ii)`` over the state indices of one block."""

    name: str
    indices: tuple[int, ...]
    low: float
    high: float
    unit: str
    description: str

    @property
    def feature(self) -> Feature:
        """The observation column of this block."""
        return Feature(self.name, self.low, self.high, self.unit, self.description)


def covariance_values(P: np.ndarray, blocks: Sequence[CovarianceBlock]) -> dict[str, np.ndarray]:
    """``log10 sqrt(sum of the block's variances)`` per block, from ``P (B, n, n)``."""
    d = np.maximum(np.diagonal(P, axis1=1, axis2=2), 1e-300)
    out = {}
    for b in blocks:
        s = d[:, b.indices[0]]
        for i in b.indices[1:]:
            s = s + d[:, i]
        out[b.name] = 0.5 * np.log10(s)
    return out
