"""Gaussian filters by name: ``get("ckf").predict(...)`` / ``.update(...)``.

Environments take ``filter="ekf" | "iekf" | "ukf" | "ckf" | "ghkf" | "dd1" | "dd2"`` and look the
step functions up here; every entry has the signatures of :func:`filters.kalman.predict` and
:func:`filters.kalman.update` (``predict(state, model, u, dt, fading=None, Q=None)``,
``update(state, z, model, mask=None, R=None)``).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any, NamedTuple

import numpy as np

from filters import divided_difference, kalman, sigma_point
from filters.core.conditioning import condition_bank
from filters.core.quadrature import MAX_GAUSS_HERMITE_POINTS, Cubature, GaussHermite, Unscented
from filters.core.types import GaussianState, UpdateInfo
from filters.core.validation import check_measurement


class GaussianFilter(NamedTuple):
    """A pair of pure step functions on :class:`~filters.core.types.GaussianState`.

    ``moments``, where the filter has one, is its measurement prediction without the noise
    (``moments(state, z, model, mask) ->`` :class:`~filters.core.types.MeasurementMoments`,
    ``S = C + R``; the KF/EKF's is :func:`filters.kalman.measurement_moments`), shared by the
    updates of one prior under several noise covariances.
    ``update_bank(state, z, model, mask, R_components (B, K, m, m))`` computes those K updates,
    a ``(B*K)`` result, filter-major (:func:`filters.kalman.update_bank` for the KF and EKF,
    :func:`~filters.core.conditioning.condition_bank` on ``moments`` for the others); None
    where a filter has no shortcut (the iterated EKF relinearizes per component).
    """

    name: str
    predict: Callable
    update: Callable
    needs_jacobians: bool
    moments: Callable | None = None
    update_bank: Callable | None = None


def _moments_bank(
    state: GaussianState,
    z: np.ndarray,
    model: Any,
    mask: np.ndarray | None,
    R_components: np.ndarray,
    *,
    moments: Callable,
) -> tuple[GaussianState, UpdateInfo]:
    """The ``update_bank`` of a moment-based filter: its points and ``h`` once per prior."""
    z, mask = check_measurement(z, mask, state.m.shape[0])
    return condition_bank(state.m, state.P, moments(state, z, model, mask), R_components, mask)


def _with_moments(name: str, predict: Callable, update: Callable, moments: Callable) -> GaussianFilter:
    return GaussianFilter(name, predict, update, False, moments, partial(_moments_bank, moments=moments))


def _sp(name: str, rule) -> GaussianFilter:
    return _with_moments(
        name,
        partial(sigma_point.predict, rule=rule),
        partial(sigma_point.update, rule=rule),
        partial(sigma_point.measurement_moments, rule=rule),
    )


def _dd(name: str, order: int) -> GaussianFilter:
    return _with_moments(
        name,
        partial(divided_difference.predict, order=order),
        partial(divided_difference.update, order=order),
        partial(divided_difference.measurement_moments, order=order),
    )


def _linearized(name: str) -> GaussianFilter:
    """The KF / EKF: the Jacobians' measurement prediction and the bank of :mod:`filters.kalman`."""
    return GaussianFilter(
        name, kalman.predict, kalman.update, True, kalman.measurement_moments, kalman.update_bank
    )


#: The filters whose points grow as ``p**n`` with the state size ``n`` (tensor-product rules).
_TENSOR_RULES = {"ghkf": GaussHermite(3), "ghkf5": GaussHermite(5)}

FILTERS: dict[str, GaussianFilter] = {
    "kf": _linearized("kf"),
    "ekf": _linearized("ekf"),
    "iekf": GaussianFilter("iekf", kalman.predict, kalman.iterated_update, True),
    "ukf": _sp("ukf", Unscented()),
    "ckf": _sp("ckf", Cubature()),
    "ghkf": _sp("ghkf", _TENSOR_RULES["ghkf"]),
    "ghkf5": _sp("ghkf5", _TENSOR_RULES["ghkf5"]),
    "dd1": _dd("dd1", 1),
    "dd2": _dd("dd2", 2),
}


def get(name: str) -> GaussianFilter:
    """The filter registered as ``name`` (ValueError listing the choices otherwise)."""
    try:
        return FILTERS[name]
    except KeyError:
        raise ValueError(f"filter must be one of {sorted(FILTERS)}; got {name!r}") from None


def state_dim_error(name: str, n: int) -> str | None:
    """Why the filter ``name`` cannot run on an ``n``-state problem, or None when it can.

    Every filter runs on every state size except the tensor-product Gauss-Hermite ones
    (``"ghkf"``: ``3**n`` points, ``"ghkf5"``: ``5**n``), which are refused beyond
    :data:`~filters.core.quadrature.MAX_GAUSS_HERMITE_POINTS` points.
    """
    rule = _TENSOR_RULES.get(name)
    if rule is None or rule.n_points(n) <= MAX_GAUSS_HERMITE_POINTS:
        return None
    return (
        f"filter={name!r} on a {n}-state problem needs {rule.p}**{n} = {rule.n_points(n)} sigma points, "
        f"more than the {MAX_GAUSS_HERMITE_POINTS} a Gauss-Hermite rule may take"
    )
