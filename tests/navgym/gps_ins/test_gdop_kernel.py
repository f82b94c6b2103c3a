"""The compiled GDOP (navgym.gps_ins.gdop_kernel) equals navgym.gnss.visibility.gdop bit for bit."""

import numpy as np
import pytest

from navgym.gnss.visibility import gdop as reference
from navgym.gps_ins.gdop_kernel import gdop


@pytest.mark.parametrize("B", [1, 7, 300])
@pytest.mark.parametrize("m", [4, 8, 12])
def test_equals_the_numpy_gdop(B, m):
    r = np.random.default_rng(B * 100 + m)
    rx = r.normal(0.0, 1.0, (B, 3)) * 6.4e6
    sat = r.normal(0.0, 1.0, (B, m, 3)) * 2.6e7
    mask = r.random((B, m)) < 0.7
    if B > 5:
        mask[:3] = False  # no satellite, then fewer than 4
        mask[3, :2] = True
        sat[5, 1] = sat[5, 0] * (1.0 + 1e-7)  # nearly the same line of sight
    if B > 11:
        sat[10, :] = sat[10, 0]  # degenerate geometry
        mask[10] = True
        rx[11] = np.nan  # non-finite estimate
    with np.errstate(all="ignore"):
        want = reference(rx, sat, mask)
        got = gdop(rx, sat, mask)
    np.testing.assert_array_equal(got, want)
    assert got.dtype == np.float64 and got.shape == (B,)


def test_equals_the_numpy_gdop_along_an_episode():
    """Real geometries: the GpsIns env's satellites and estimates over steps."""
    import gymnasium as gym

    import navgym  # noqa: F401

    env = gym.make_vec("navgym/GpsInsFading-v2", num_envs=8, vectorization_mode="vector_entry_point")
    env.reset(seed=3)
    core = env.unwrapped.core
    for t in range(20):
        models = core.platform.step_models(core.episodes, core.t)
        p_ins, east, north, sat = models.context[:4]
        p_est = models.observation.position(core.state.m, p_ins, east, north)
        np.testing.assert_array_equal(gdop(p_est, sat, models.mask), reference(p_est, sat, models.mask))
        env.step(np.full((8, 1), 0.1 * (t % 5), np.float32))
    env.close()
