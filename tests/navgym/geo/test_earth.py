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


def test_precomputed_sine_gives_the_same_radii_and_gravity():
    lat = np.linspace(-1.5, 1.5, 101)
    h = np.linspace(-100.0, 9000.0, 101)
    s = np.sin(lat)
    np.testing.assert_array_equal(geo.meridian_radius(lat, s), geo.meridian_radius(lat))
    np.testing.assert_array_equal(geo.normal_radius(lat, s), geo.normal_radius(lat))
    np.testing.assert_array_equal(geo.gravity(lat, h, s), geo.gravity(lat, h))
