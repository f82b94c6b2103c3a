"""The PF benchmark's model: reduced pseudo-ranges are right in both precisions and layouts."""

import numpy as np
import pytest

from benchmarks.particles import PseudorangePF


@pytest.mark.parametrize("layout", ["soa", "aos"])
def test_reduced_pseudoranges_match_the_direct_formula(layout):
    rng = np.random.default_rng(0)
    B, N = 3, 7
    x = rng.normal(0, 1, (B, N, 8)) * np.array([800.0] * 3 + [10.0] * 3 + [300.0, 1.0])
    ref = PseudorangePF(layout=layout)
    direct = np.linalg.norm(x[..., None, 0:3] - ref.sats, axis=-1) - ref.sat_range + x[..., 6:7]
    for dtype, atol in (("float64", 1e-7), ("float32", 2e-3)):
        model = PseudorangePF(layout=layout, dtype=dtype)
        xs = x.astype(dtype)
        if layout == "soa":
            xs = np.ascontiguousarray(xs.transpose(0, 2, 1)).transpose(0, 2, 1)
        out = model.h(xs)
        assert out.dtype == np.dtype(dtype) and out.shape == (B, N, 8)
        np.testing.assert_allclose(out, direct, rtol=0, atol=atol)


def test_float32_and_float64_filters_reach_the_same_accuracy():
    """Same scenario, same generator seeds: the float32 PF's position RMSE equals float64's to cm."""
    from benchmarks.particles import _position_rmse, run_steps

    rmse = {}
    for dtype in ("float64", "float32"):
        model = PseudorangePF(dtype=dtype)
        rng = np.random.Generator(np.random.PCG64(3))
        state, zs, truth = model.scenario(16, 500, 8, rng)
        rmse[dtype] = _position_rmse(run_steps(state, zs, model, rng, "systematic"), truth[-1])
    assert rmse["float64"] < 10.0  # the filter tracks (prior 10 m per axis, 3 m pseudo-ranges)
    assert abs(rmse["float32"] - rmse["float64"]) < 0.05 * rmse["float64"]
