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
from agents.baselines.jumps import ConstantJump, LikelihoodJump
from agents.baselines.mixture import (
    FixedContamination,
    InnovationContamination,
    NominalContamination,
    PosteriorContamination,
    ZeroContamination,
)
from agents.baselines.noise_scale import ConstantScale, IaeScale, NisQScale, SageHusaScale
from agents.baselines.resample import AlwaysResample, EssThreshold, NeverResample, RedistributionRule
from agents.baselines.robust import ChiSquareThreshold, ConstantThreshold, SeedThreshold
from agents.baselines.row_mixture import RowChiSquare, RowConstant, RowHuber, RowInnovationAverage
from agents.baselines.row_scale import (
    CN0MaskExclusion,
    CN0Weighting,
    ElevationWeighting,
    ReportedAccuracyWeighting,
    RowChiSquareExclusion,
    RowInnovationScale,
    RowScaleConstant,
)
from navgym.envs.tasks import MixtureTask

__all__ = [
    "BASELINES",
    "TUNED_DIR",
    "BaselineSpec",
    "baseline_specs",
    "baseline_task",
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


#: RowScale grids: the rows' common s_r and the process-noise scale s_q (0.1 to 1e4).
_ROW_R = (0.3, 1.0, 3.0, 10.0, 30.0)
_ROW_Q = (0.1, 1.0, 10.0, 100.0, 1000.0, 1e4)
#: The IMU threshold rule on s_q of the RowScale context baselines: the threshold in the units of
#: the platform's ``imu_activity`` feature as a fraction of the feature's upper bound (1e9: never).
_IMU_RULE = {"imu_threshold": (0.01, 0.03, 0.1, 1e9), "s_q_low": (1.0, 10.0), "s_q_high": (100.0, 1e4)}


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
    "NoiseScale": _specs(
        BaselineSpec(
            "plain", ConstantScale, {"s_q": 1.0, "s_r": 1.0}, description="s_q = s_r = 1 (the plain filter)"
        ),
        BaselineSpec(
            "constant",
            ConstantScale,
            grid={
                "s_q": (0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 1e3, 1e4),
                "s_r": (0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 1e3, 1e4),
            },
            description="tuned constant s_q, s_r (clipped to the task's ranges)",
        ),
        BaselineSpec(
            "iae",
            IaeScale,
            grid={"window": (5.0, 10.0, 20.0, 50.0, 100.0), "gain": (0.25, 0.5, 1.0, 1.5)},
            description="innovation-based adaptive estimation of R (Mehra 1970; Mohamed & Schwarz 1999)",
        ),
        BaselineSpec(
            "sage_husa",
            SageHusaScale,
            grid={"b": (0.8, 0.9, 0.95, 0.98, 0.99), "beta": (0.5, 1.0, 1.5, 2.0)},
            description="Sage-Husa recursive R estimate with forgetting factor b (Sage & Husa 1969)",
        ),
        BaselineSpec(
            "iae_q",
            NisQScale,
            fixed={"window": 20.0, "gain": 1.0},
            grid={
                "gain_q": (1.0, 3.0, 10.0, 30.0),
                "threshold": (0.5, 1.0, 2.0),
                "few_rows": (1.0, 2.0, 3.0),
            },
            description="IAE of R plus s_q from the 1 s NIS average when few rows are received",
        ),
    ),
    #: Robust tasks (the robust threshold of the iterated EKF / ESKF, ``*Robust-v2``).
    "Robust": _specs(
        BaselineSpec("plain", ConstantThreshold, {"c": 1e9}, description="c = inf (the plain I-ESKF)"),
        BaselineSpec(
            "seed", SeedThreshold, description="c = 1.345 (Huber) / 4.685 (Tukey), Belles et al. 2022 Table 1"
        ),
        BaselineSpec(
            "constant",
            ConstantThreshold,
            grid={"c": (0.7, 1.0, 1.345, 2.0, 3.0, 5.0, 10.0)},
            description="tuned constant threshold c",
        ),
        BaselineSpec(
            "chi_square",
            ChiSquareThreshold,
            grid={"alpha": (0.001, 0.01), "c_low": (1.0, 2.0), "hold": (0.0, 5.0)},
            description="chi-square test of the NIS: c_low while it fails (and hold steps after), else plain",
        ),
    ),
    #: Jumps tasks (the jump prior of the random Dirac-Gauss PF, ``SignalTrackingJumps-v2``).
    "Jumps": _specs(
        BaselineSpec("plain", ConstantJump, {"p": 2e-3}, description="p = 2e-3 (the nominal 2 jumps / s)"),
        BaselineSpec(
            "constant",
            ConstantJump,
            grid={"p": (1e-5, 1e-4, 5e-4, 2e-3, 2e-2)},
            description="tuned constant jump probability p",
        ),
        BaselineSpec(
            "likelihood",
            LikelihoodJump,
            grid={"threshold": (-10.0, -12.0, -15.0), "p_high": (0.01, 0.1), "p_low": (1e-4,)},
            description="p_high for hold + 1 steps after the mean log-likelihood falls below threshold",
        ),
    ),
    #: Per-row Mixture tasks (``MixtureTask(per_row=True)``, the v2 ids): one eps per row.
    "RowMixture": _specs(
        BaselineSpec(
            "zero", RowConstant, {"eps": 0.0}, description="eps = 0 on every row (the plain base filter)"
        ),
        BaselineSpec(
            "constant",
            RowConstant,
            grid={"eps": (0.0, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5)},
            description="tuned constant eps, the same on every row",
        ),
        BaselineSpec(
            "chi_square",
            RowChiSquare,
            grid={"alpha": (0.001, 0.01, 0.05), "eps_low": (0.0, 0.02, 0.05, 0.1), "decay": (0.0, 0.5, 0.9)},
            description="RAIM-like chi-square exclusion per row: eps_max on failing rows",
        ),
        BaselineSpec(
            "innovation_avg",
            RowInnovationAverage,
            grid={
                "threshold": (0.2, 0.35, 0.5, 1.0),
                "gain": (0.5, 1.0, 2.0, 5.0, 100.0),
                "eps_low": (0.0, 0.02, 0.05),
            },
            description="eps_i from the per-row innovation average (persistent bias)",
        ),
        BaselineSpec(
            "huber",
            RowHuber,
            grid={"k": (1.0, 1.5, 2.0, 3.0), "alpha": (0.05, 0.2, 0.5), "eps_low": (0.0, 0.02, 0.05)},
            description="Huber-type smooth per-row weight from the EMA of squared innovations",
        ),
    ),
    #: RowScale tasks (``*RowScale-v3``): one R multiplier per row and the motion states' Q scale.
    #: The context baselines refuse an env without their context features (``applies``).
    "RowScale": _specs(
        BaselineSpec(
            "plain",
            RowScaleConstant,
            {"s_r": 1.0, "s_q": 1.0},
            description="every scale 1 (the plain filter)",
        ),
        BaselineSpec(
            "constant",
            RowScaleConstant,
            grid={"s_r": _ROW_R, "s_q": _ROW_Q},
            description="tuned constant s_r on every row and s_q",
        ),
        BaselineSpec(
            "chi_square",
            RowChiSquareExclusion,
            grid={"alpha": (0.001, 0.01, 0.05), "s_excl": (10.0, 100.0, 1e4), "s_q": _ROW_Q},
            description="RAIM-like chi-square test and exclusion per row (s_excl on excluded rows)",
        ),
        BaselineSpec(
            "row_iae",
            RowInnovationScale,
            grid={"b": (0.5, 0.8, 0.9, 0.95), "beta": (0.5, 1.0, 2.0), "s_q": _ROW_Q},
            description="per-row innovation-based adaptive R with a Sage-Husa forgetting factor",
        ),
        BaselineSpec(
            "cn0_weighting",
            CN0Weighting,
            grid={"cn0_ref": (35.0, 40.0, 45.0, 50.0), **_IMU_RULE},
            description="C/N0 weighting (SIGMA-epsilon, Hartinger & Brunner 1999), IMU rule on Q",
        ),
        BaselineSpec(
            "elevation_weighting",
            ElevationWeighting,
            grid={"k": (0.5, 1.0, 2.0), "c": (0.3, 1.0, 3.0), **_IMU_RULE},
            description="elevation weighting, sigma^2 = a^2 + b^2 / sin^2 el (RTKLIB E.6.24), IMU rule on Q",
        ),
        BaselineSpec(
            "cn0_mask_fde",
            CN0MaskExclusion,
            grid={"mask_dbhz": (25.0, 30.0, 35.0), "alpha": (0.01,), "s_excl": (100.0, 1e4), **_IMU_RULE},
            description="C/N0 mask, then chi-square fault detection and exclusion; IMU rule on Q",
        ),
        BaselineSpec(
            "reported_accuracy",
            ReportedAccuracyWeighting,
            grid={"c": (0.01, 0.03, 0.1, 0.3, 1.0), **_IMU_RULE},
            description="each fix weighted by the receiver's reported accuracy; IMU rule on Q",
        ),
    ),
}


def baseline_task(task_or_env: Any) -> str:
    """The key of :data:`BASELINES` of a key, an env or an env id.

    The task's name, except a per-row Mixture task (``per_row=True``, the v2 ids):
    ``"RowMixture"`` (one action per row; the v0/v1 Mixture baselines act on one weight).
    """
    if isinstance(task_or_env, str) and task_or_env in BASELINES:
        return task_or_env
    task = navigation_env(task_or_env).task
    if isinstance(task, MixtureTask) and task.per_row:
        return "RowMixture"
    return str(task.name)


def baseline_specs(task_or_env: Any) -> dict[str, BaselineSpec]:
    """The baselines of a :data:`BASELINES` key (``"Fading"``...) or of an env / env id.

    For an env, only those whose context features (``cls.context``: the RowScale context
    baselines read a receiver's C/N0, elevation, accuracy figure or IMU statistic) its
    observation has; for a key, all of them.
    """
    specs = BASELINES[baseline_task(task_or_env)]
    if isinstance(task_or_env, str) and task_or_env in BASELINES:
        return specs
    names = set(navigation_env(task_or_env).observation_features.names)
    return {k: s for k, s in specs.items() if set(s.cls.context) <= names}


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


def best_tuned(env_id: str, path: str | Path | None = None) -> tuple[str, float]:
    """The best tuned baseline of ``env_id``: the highest tuning ``score`` in its tuned file.

    The file is :func:`tuned_path` (or ``path``); ties go to the first in the file. Its scores
    come from tuning seeds only, so the choice sees no held-out episode.

    Returns:
        ``(name, score)``.
    """
    p = Path(path) if path is not None else tuned_path(env_id)
    if not p.is_file():
        raise FileNotFoundError(
            f"no tuned baselines for {env_id} at {p}: run navgym tune --env {env_id} --out {p.parent}"
        )
    base = json.loads(p.read_text()).get("baselines") or {}
    if not base:
        raise ValueError(f"{p} lists no baselines")
    name = max(base, key=lambda n: float(base[n]["score"]))
    return name, float(base[name]["score"])


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
