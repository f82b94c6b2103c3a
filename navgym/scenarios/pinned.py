"""Checks of a pinned :class:`~navgym.scenarios.Scenario` (``reset(options={"scenario": ...})``).

A pinned scenario bypasses the :class:`~navgym.scenarios.ScenarioDistribution` whose keyword
arguments bound every drawn value, so the environments check it at ``reset`` against the same
bounds (:func:`check_values`: a jamming noise of ``1e300`` m is refused as ``jamming_sigma`` is)
and against the events the platform models (:func:`check_events`: a platform without bursts
refuses a pinned burst as it refuses ``burst_probability``). Both raise ``ValueError`` before
anything is simulated, so no sub-env of a vector env is left with an episode that cannot step.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from typing import Any

from navgym.scenarios.distribution import (
    MAX_ERROR_M,
    MAX_NOISE_SCALE,
    MAX_VAR_RATIO,
    MAX_VELOCITY_SIGMA,
    MAX_YAW_RATE_SIGMA,
)
from navgym.scenarios.scenario import Scenario

__all__ = ["EVENT_KEYWORDS", "check_events", "check_values", "modelled_events"]

#: A scenario's event fields and the keyword argument (its probability) that draws them.
EVENT_KEYWORDS = {
    "outages": "outage_probability",
    "partial_outages": "partial_probability",
    "impulsive": "impulsive_probability",
    "jamming": "jamming_probability",
    "outliers": "outlier_probability",
    "bursts": "burst_probability",
    "multipath": "multipath_probability",
    "canyons": "canyon_probability",
}

#: Per event field, its bounded values: (attribute, keyword argument, largest magnitude).
_BOUNDS: dict[str, tuple[tuple[str, str, float], ...]] = {
    "impulsive": (("var_ratio", "impulsive_var_ratio", MAX_VAR_RATIO),),
    "jamming": (("jam_sigma", "jamming_sigma", MAX_ERROR_M),),
    "outliers": (("scale", "outlier_scale", MAX_ERROR_M),),
    "bursts": (
        ("velocity_sigma", "burst_velocity_sigma", MAX_VELOCITY_SIGMA),
        ("yaw_rate_sigma", "burst_yaw_rate_sigma", MAX_YAW_RATE_SIGMA),
    ),
    "multipath": (("bias", "multipath_bias", MAX_ERROR_M), ("sigma", "multipath_sigma", MAX_ERROR_M)),
    "canyons": (("noise_scale", "canyon_noise_scale", MAX_NOISE_SCALE),),
}


def check_values(scenario: Scenario) -> None:
    """Refuse a value of ``scenario`` beyond its keyword argument's bound (``ValueError``).

    The events' own checks (non-negative, finite, probabilities) hold already; these are the
    upper bounds of :class:`~navgym.scenarios.ScenarioDistribution` (a multipath bias by its
    magnitude: the keyword draws its sign).
    """
    for field, bounds in _BOUNDS.items():
        for i, event in enumerate(getattr(scenario, field)):
            for attribute, keyword, largest in bounds:
                value = float(getattr(event, attribute))
                if abs(value) > largest:
                    raise ValueError(
                        f"options['scenario'].{field}[{i}].{attribute} must be within {largest:g} in "
                        f"magnitude (the bound of the keyword argument {keyword}); got {value!r}"
                    )


def modelled_events(
    scenario_arguments: Collection[str], task_defaults: Iterable[Mapping[str, Any]]
) -> frozenset[str]:
    """The event fields a platform models: those whose probability keyword it takes or sets.

    ``scenario_arguments`` are the platform's scenario keyword arguments, ``task_defaults`` its
    tasks' scenario defaults (a platform may draw an event it does not let the user tune).
    """
    set_by_default = {k for d in task_defaults for k, v in d.items() if isinstance(v, float | int) and v > 0}
    return frozenset(
        field for field, k in EVENT_KEYWORDS.items() if k in scenario_arguments or k in set_by_default
    )


def check_events(scenario: Scenario, modelled: Collection[str], platform: str) -> None:
    """Refuse the events of ``scenario`` that ``platform`` does not model (``ValueError``).

    ``modelled`` holds the event fields the platform models (:func:`modelled_events`).
    """
    pinned = [field for field in EVENT_KEYWORDS if getattr(scenario, field) and field not in modelled]
    if pinned:
        keywords = ", ".join(EVENT_KEYWORDS[f] for f in pinned)
        raise ValueError(
            f"options['scenario'] pins {', '.join(pinned)}, which the {platform} platform does not "
            f"model (as it refuses the keyword arguments {keywords}); it models "
            f"{', '.join(sorted(modelled)) or 'no events'}"
        )
