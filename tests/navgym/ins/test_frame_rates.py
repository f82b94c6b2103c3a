import numpy as np

from navgym.geo import gravity
from navgym.ins import earth_rate_ned, gravity_ned, home_frame


def test_home_frame_gravity_gradient_and_earth_rate():
    lat, h = np.deg2rad(np.array([10.0, 45.0, 60.0])), np.array([0.0, 120.0, 2000.0])
    f = home_frame(lat, h)
    np.testing.assert_array_equal(f.gravity, gravity_ned(lat, h))
    np.testing.assert_array_equal(f.earth_rate, earth_rate_ned(lat))
    # horizontal: the vertical turns by 1 / R per metre (~1.5e-6 /s^2 per metre); vertical: the
    # free-air gradient: gravity grows by about 3.086e-6 /s^2 per metre down
    assert np.all((f.gradient[:, :2] < -1.5e-6) & (f.gradient[:, :2] > -1.6e-6))
    np.testing.assert_allclose(f.gradient[:, 2], 3.086e-6, rtol=5e-3)
    np.testing.assert_allclose(-f.gradient[:, 2], (gravity(lat, h + 1.0) - gravity(lat, h - 1.0)) / 2.0)
    single = home_frame(lat[1], h[1])
    assert single.gravity.shape == (3,)
    np.testing.assert_allclose(single.gradient, f.gradient[1], rtol=1e-15)  # 0-d ufunc loops may round apart
