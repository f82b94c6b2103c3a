"""A check shared by the platforms' tests: an ElementwiseModel's sigma-point moments are the
copy path's, bit for bit (filters.core.models.ElementwiseModel)."""

from __future__ import annotations

import numpy as np

from filters import sigma_point
from filters.core.models import ElementwiseModel, innovation
from filters.core.quadrature import Cubature, Unscented
from filters.core.types import GaussianState


class _Plain:
    """The same observation model without the marker (its points come as a batch-first copy)."""

    def __init__(self, model):
        self.model, self.R = model, model.R

    def h(self, x):
        return self.model.h(x)

    def residual(self, z, z_hat):
        return innovation(self.model, z, z_hat)  # the model's own residual, where it has one


def assert_view_equals_copy(model, n: int, seed: int = 0) -> None:
    """Compiled CKF and UKF measurement moments of ``model`` on random beliefs of ``n`` states:
    the state-major view (the model is an ElementwiseModel) = the batch-first copy, bit for bit."""
    assert isinstance(model, ElementwiseModel)
    rng = np.random.default_rng(seed)
    B = 33
    A = rng.standard_normal((B, n, n))
    state = GaussianState(rng.standard_normal((B, n)) * 10, A @ np.swapaxes(A, 1, 2) + np.eye(n))
    m = np.asarray(model.R).shape[-1]
    z = rng.standard_normal((B, m)) * 10
    seen = []

    class Recording(type(model)):  # the same model, recording the layout of its points
        def h(self, x):
            seen.append(x.flags.c_contiguous)
            return super().h(x)

    recording = Recording(*model)
    for rule in (Cubature(), Unscented()):
        a = sigma_point.measurement_moments(state, z, recording, rule=rule)
        b = sigma_point.measurement_moments(state, z, _Plain(model), rule=rule)
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
    assert seen == [False, False]  # the state-major view, not a batch-first copy
