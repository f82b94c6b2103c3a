"""The no-truth check shared by the platforms' tests: perturb the truth, the observation stays."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np


def assert_truth_not_observed(
    core: Any, rngs: Any, action: np.ndarray, perturb: Callable[[Any], Any], steps: int = 4
) -> None:
    """Step ``core`` and a deep copy whose episodes are ``perturb(episodes)`` with ``action``.

    Every observation of the two must be equal (the truth never reaches the observation), and
    the last step's ``pos_err_m`` must differ (the perturbation did reach the evaluation, so the
    check can fail).
    """
    twin, twin_rngs = copy.deepcopy((core, rngs))
    twin.episodes = perturb(twin.episodes)
    for _ in range(steps):
        o1, *_, i1 = core.step(action, rngs)
        o2, *_, i2 = twin.step(action, twin_rngs)
        np.testing.assert_array_equal(o1, o2)
    assert not np.allclose(i1["pos_err_m"], i2["pos_err_m"])  # the truth did change the evaluation
