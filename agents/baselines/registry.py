"""The baselines of each task, their parameter grids, and the tuned parameters on disk.

Tuned parameters (from :mod:`agents.tuning`, on tuning seeds only) live in
``agents/baselines/tuned/<EnvName-vK>.json`` (the id without the ``navgym/`` namespace), with
the command that produced them, so evaluation never re-tunes.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.baselines.base import BaselinePolicy, navigation_env
from agents.baselines.fading import ConstantFading, SageHusaFading, StrongTracking, SuboptimalFading
from agents.baselines.mixture import (
    FixedContamination,
    InnovationContamination,
    NominalContamination,
    PosteriorContamination,
    ZeroContamination,
)
from agents.baselines.resample import AlwaysResample, EssThreshold, NeverResample, RedistributionRule

__all__ = [
    "BASELINES",
    "TUNED_DIR",
    "BaselineSpec",
    "baseline_specs",
    "load_tuned",
    "make_baseline",
    "make_baselines",
    "tuned_path",
]

#: Where the tuned parameters are committed.
TUNED_DIR = Path(__file__).resolve().parent / "tuned"


@dataclass(frozen=True)
class BaselineSpec:
    """A registered baseline: its class, fixed parameters and tuning grid (empty: not tuned)."""

    name: str
    cls: type[BaselinePolicy]
    fixed: Mapping[str, float] = field(default_factory=dict)
    grid: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    description: str = ""

    @property
    def tunable(self) -> bool:
        return bool(self.grid)


def _specs(*specs: BaselineSpec) -> dict[str, BaselineSpec]:
    return {s.name: s for s in specs}


#: Baselines per task name, in table order.
BASELINES: dict[str, dict[str, BaselineSpec]] = {
    "Fading": _specs(
        BaselineSpec("plain", ConstantFading, {"lam": 1.0}, description="lambda = 1 (the plain filter)"),
        BaselineSpec(
            "constant",
            ConstantFading,
            grid={"lam": (1.0, 1.01, 1.02, 1.03, 1.05, 1.07, 1.1, 1.2, 1.5, 2.0, 3.0, 5.0, 10.0)},
            description="tuned constant lambda",
        ),
        BaselineSpec(
            "suboptimal",
            SuboptimalFading,
            grid={
                "rho": (0.1, 0.3, 0.6, 0.9),
                "beta": (0.5, 1.0, 2.0, 3.0, 5.0, 8.0),
                "gamma": (0.25, 0.5, 1.0, 2.0),
            },
            description="suboptimal fading factor (Benzerrouk 2014, eq. 67-70)",
        ),
        BaselineSpec(
            "strong_tracking",
            StrongTracking,
            grid={"rho": (0.02, 0.1, 0.3, 0.6, 0.9, 0.95), "beta": (1.0, 2.0, 3.0, 5.0, 8.0, 12.0)},
            description="strong tracking filter (Zhou & Frank 1996)",
        ),
        BaselineSpec(
            "sage_husa",
            SageHusaFading,
            grid={"b": (0.05, 0.2, 0.5, 0.8, 0.95), "beta": (1.0, 2.0, 3.0, 5.0, 8.0, 12.0)},
            description="Sage-Husa-weighted innovation covariance -> lambda",
        ),
    ),
    "Mixture": _specs(
        BaselineSpec("zero", ZeroContamination, description="eps = 0 (the plain base filter)"),
        BaselineSpec(
            "nominal",
            NominalContamination,
            description="eps = nominal contamination of the scenario distribution",
        ),
        BaselineSpec(
            "constant",
            FixedContamination,
            grid={"eps": (0.0, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5)},
            description="tuned constant eps",
        ),
        BaselineSpec(
            "innovation",
            InnovationContamination,
            grid={"threshold": (2.5, 3.0, 4.0), "alpha": (0.05, 0.1, 0.2, 0.5), "gain": (0.5, 1.0, 2.0, 4.0)},
            description="EMA of the fraction of large normalized innovations",
        ),
        BaselineSpec(
            "posterior",
            PosteriorContamination,
            grid={"alpha": (0.02, 0.05, 0.1, 0.2, 0.5), "floor": (0.001, 0.01, 0.03, 0.1)},
            description="recursive EM of eps from the outlier posterior",
        ),
    ),
    "Resample": _specs(
        BaselineSpec("never", NeverResample, description="never resample"),
        BaselineSpec("always", AlwaysResample, description="resample every step"),
        BaselineSpec(
            "ess",
            EssThreshold,
            grid={"threshold": (0.001, 0.005, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.7)},
            description="resample when ESS/N < threshold",
        ),
        BaselineSpec(
            "redistribution", RedistributionRule, description="redistribution rule of Carvalho et al. 1997"
        ),
    ),
}


def baseline_specs(task_or_env: Any) -> dict[str, BaselineSpec]:
    """The baselines of a task name (``"Fading"``...) or of an env / env id."""
    task = task_or_env if task_or_env in BASELINES else navigation_env(task_or_env).task.name
    return BASELINES[task]


def make_baseline(env: Any, name: str, **params: Any) -> BaselinePolicy:
    """Baseline ``name`` of ``env``'s task with ``params`` over its fixed parameters and defaults."""
    specs = baseline_specs(env)
    if name not in specs:
        raise ValueError(f"no baseline {name!r} for this task; have {sorted(specs)}")
    spec = specs[name]
    return spec.cls(env, **{**spec.fixed, **params})


def tuned_path(env_id: str, directory: str | Path | None = None) -> Path:
    """``<directory>/<EnvName-vK>.json`` (default directory :data:`TUNED_DIR`)."""
    return Path(directory or TUNED_DIR) / f"{env_id.split('/')[-1]}.json"


def load_tuned(
    env_id: str, path: str | Path | None = None, missing_ok: bool = True
) -> dict[str, dict[str, float]]:
    """Tuned parameters ``{baseline: {param: value}}`` of ``env_id`` (``{}`` if none and ``missing_ok``)."""
    p = Path(path) if path is not None else tuned_path(env_id)
    if not p.exists():
        if missing_ok:
            return {}
        raise FileNotFoundError(
            f"no tuned parameters for {env_id} at {p}; run python -m agents.tuning --env {env_id}"
        )
    data = json.loads(p.read_text())
    if data.get("env_id") not in (None, env_id):
        raise ValueError(f"{p} holds parameters of {data['env_id']}, not {env_id}")
    return {name: dict(entry["params"]) for name, entry in data.get("baselines", {}).items()}


def make_baselines(
    env: Any, tuned: Mapping[str, Mapping[str, float]] | None = None, names: Iterable[str] | None = None
) -> dict[str, BaselinePolicy]:
    """Every baseline of ``env``'s task (or ``names``), with ``tuned`` parameters where given.

    Args:
        env: an env, vector env or env id (layout and action mapping).
        tuned: ``{baseline: params}``, e.g. :func:`load_tuned`; tunable baselines absent from
            it keep their class defaults.
        names: subset and order (default: all of the task, registry order).
    """
    specs = baseline_specs(env)
    tuned = tuned or {}
    return {n: make_baseline(env, n, **dict(tuned.get(n, {}))) for n in (names or specs)}
