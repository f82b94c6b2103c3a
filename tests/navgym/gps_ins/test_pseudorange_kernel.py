"""The compiled reduced pseudo-ranges (navgym.gps_ins.pseudorange_kernel) equal the NumPy form."""

import numpy as np
import pytest

import navgym  # noqa: F401
from filters.particle import bootstrap
from navgym.gps_ins.env import GPS_INS
from navgym.gps_ins.pseudorange_kernel import reduced_pseudoranges

_core = GPS_INS.core


def _reduced_model(B=6, seed=3, steps=5):
    """A Resample env's observation model after a few steps, and its reduced form."""
    core = _core("resample", B, {})
    core.reset(np.arange(B), [np.random.default_rng(seed + i) for i in range(B)], [None] * B)
    models = core.platform.step_models(core.episodes, np.full(B, steps))
    red, _ = models.observation.reduced(models.z)
    return models.observation, red, models.mask


def _cloud(B, N, dtype, layout="soa", spread=300.0, seed=0):
    m = np.zeros((B, 8))
    P = np.diag([spread**2] * 2 + [1.0] * 4 + [spread**2, 1.0])
    st = bootstrap.from_gaussian(m, P, N, np.random.default_rng(seed), layout=layout)
    return st.x.astype(dtype)  # astype keeps the (B, n, N) buffer layout


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_compiled_equals_numpy_reference(dtype):
    base, red, mask = _reduced_model()
    x = _cloud(base.A.shape[0], 257, dtype)  # N not a multiple of the vector width
    assert x.transpose(0, 2, 1).flags.c_contiguous
    got, ref = red.h(x), red.h_reference(x)
    assert got.dtype == ref.dtype == dtype and got.shape == ref.shape == (6, 257, base.A.shape[-1])
    eps = np.finfo(dtype).eps
    # a few units in the last place of the output (the loop may contract to FMA)
    np.testing.assert_allclose(got, ref, rtol=0, atol=8 * eps * np.abs(ref).max())
    # and both are the full model minus rho0, evaluated in float64 on the same particles (that
    # form subtracts 2e7 m ranges: its own rounding is a few 1e-9 m)
    exact = base.h(np.ascontiguousarray(x, dtype=np.float64)) - red.rho0[:, None, :]
    np.testing.assert_allclose(got, exact, rtol=0, atol=8 * eps * np.abs(exact).max() + 4e-8)
    assert mask.any()


def test_other_layouts_use_the_numpy_form():
    _, red, _ = _reduced_model()
    x = _cloud(6, 50, np.float32, layout="aos")
    np.testing.assert_array_equal(red.h(x), red.h_reference(x))


def test_bad_input_raises():
    base, red, _ = _reduced_model()
    x = _cloud(6, 40, np.float32).transpose(0, 2, 1)  # (B, n, N) buffer
    args = (base.A, base.W, base.rho0_sq, red.rho0, base.c0)
    with pytest.raises(ValueError, match="C-contiguous"):
        reduced_pseudoranges(x[:, :, ::2], *args)
    with pytest.raises(ValueError, match="C-contiguous"):
        reduced_pseudoranges(x[:, :5], *args)
    with pytest.raises(ValueError, match="float32 or float64"):
        reduced_pseudoranges(x.astype(np.float16), *args)
    with pytest.raises(ValueError, match="A and W"):
        reduced_pseudoranges(x, base.A[:, :1], *args[1:])


def test_non_finite_particles_give_non_finite_predictions_as_in_numpy():
    _, red, _ = _reduced_model()
    x = _cloud(6, 64, np.float32)
    x[2, 5, 0] = np.nan  # a NaN east error
    x[3, 7, 6] = np.inf  # an infinite clock bias
    got, ref = red.h(x), red.h_reference(x)
    np.testing.assert_array_equal(np.isfinite(got), np.isfinite(ref))
    assert not np.isfinite(got[2, 5]).any() and not np.isfinite(got[3, 7]).any()
    assert np.isfinite(np.delete(got.reshape(-1, got.shape[-1]), [2 * 64 + 5, 3 * 64 + 7], axis=0)).all()
