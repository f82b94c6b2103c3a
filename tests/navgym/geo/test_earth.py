import numpy as np
import pytest

from navgym import geo


def test_radii_known_values():
    # Equator: R_M = a (1 - e^2), R_N = a; pole: both a^2 / b.
    assert geo.meridian_radius(0.0) == pytest.approx(geo.A * (1 - geo.E2), abs=1e-6)
    assert geo.normal_radius(0.0) == pytest.approx(geo.A, abs=1e-9)
    pole = geo.A**2 / geo.B
    assert geo.meridian_radius(np.pi / 2) == pytest.approx(pole, abs=1e-6)
    assert geo.normal_radius(np.pi / 2) == pytest.approx(pole, abs=1e-6)


def test_radii_match_finite_difference_of_geodetic_to_ecef():
    lat, lon, d = 0.8, 0.3, 1e-7
    north = geo.geodetic_to_ecef(lat + d, lon, 0.0) - geo.geodetic_to_ecef(lat - d, lon, 0.0)
    east = geo.geodetic_to_ecef(lat, lon + d, 0.0) - geo.geodetic_to_ecef(lat, lon - d, 0.0)
    assert np.linalg.norm(north) / (2 * d) == pytest.approx(geo.meridian_radius(lat), rel=1e-8)
    assert np.linalg.norm(east) / (2 * d * np.cos(lat)) == pytest.approx(geo.normal_radius(lat), rel=1e-8)


def test_somigliana_gravity_known_values():
    # TR8350.2: gamma_e = 9.7803253359, gamma_p = 9.8321849378 m/s^2.
    assert geo.gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-9)
    assert geo.gravity(np.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-8)
    g = geo.gravity(np.deg2rad([45.0, 45.0]), np.array([0.0, 1000.0]))
    assert g.shape == (2,)
    assert g[0] - g[1] == pytest.approx(3.086e-3, rel=5e-3)  # free-air gradient
