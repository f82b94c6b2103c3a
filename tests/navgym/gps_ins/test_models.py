"""The pseudo-range model's prediction of a subset of its rows (filters.core.models.RowMaskable)."""

from __future__ import annotations

import numpy as np
import pytest

from filters.core.models import RowMaskable
from navgym.gps_ins.models import PseudorangeModel


def _model(B=6, m=12, seed=0):
    rng = np.random.default_rng(seed)
    p_ins = rng.normal(size=(B, 3)) * 6.4e6
    east = rng.normal(size=(B, 3))
    east /= np.linalg.norm(east, axis=1, keepdims=True)
    north = np.cross(p_ins / np.linalg.norm(p_ins, axis=1, keepdims=True), east)
    north /= np.linalg.norm(north, axis=1, keepdims=True)
    sat = rng.normal(size=(B, m, 3)) * 2.6e7
    return PseudorangeModel.build(p_ins, east, north, sat, rng.uniform(2, 10, (B, m)), 25.0 * np.eye(m)), rng


@pytest.mark.parametrize("rows", [[0], [5], [11], [3, 7]])
def test_only_rows_predicts_those_rows_bit_for_bit_and_zero_elsewhere(rows):
    model, rng = _model()
    assert isinstance(model, RowMaskable)
    part = model.only_rows(np.array(rows))
    others = [i for i in range(12) if i not in rows]
    for x in (rng.normal(size=(6, 17, 8)) * 50, rng.normal(size=(6, 8)) * 50):  # sigma points, means
        whole, h = model.h(x), part.h(x)
        assert h.shape == whole.shape and h.flags.c_contiguous
        np.testing.assert_array_equal(h[..., rows], whole[..., rows])
        assert not h[..., others].any()
    x = rng.normal(size=(6, 8))
    np.testing.assert_array_equal(part.H(x), model.H(x))
    assert part.R is model.R
