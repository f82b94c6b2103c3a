"""The Iridium constellation of Benzerrouk 2014, §2.7d: geometry, period, visibility (known answers)."""

import numpy as np
import pytest

from navgym.geo.frames import ecef_to_geodetic, geodetic_to_ecef
from navgym.geo.wgs84 import OMEGA_E, A
from navgym.iridium.constellation import (
    ALTITUDE_M,
    INCLINATION_DEG,
    IRIDIUM_MASK_DEG,
    PERIOD_S,
    elevations,
    satellite_ecef,
    serving_satellite,
)


def test_66_satellites_on_circles_of_the_source_altitude():
    r = satellite_ecef(np.array([0.0, 1234.5]), 0.3, 1.1)
    assert r.shape == (2, 66, 3)
    np.testing.assert_allclose(np.linalg.norm(r, axis=-1), A + ALTITUDE_M, rtol=1e-12)


def test_the_period_is_100_min_28_s_in_inertial_space():
    """After one period each satellite is back where it was, up to the Earth's turn about z."""
    r0 = satellite_ecef(0.0)
    r1 = satellite_ecef(PERIOD_S)
    a = OMEGA_E * PERIOD_S  # the ECEF frame has turned by this
    c, s = np.cos(a), np.sin(a)
    back = np.stack([c * r1[:, 0] - s * r1[:, 1], s * r1[:, 0] + c * r1[:, 1], r1[:, 2]], axis=-1)
    np.testing.assert_allclose(back, r0, atol=1e-6)
    assert PERIOD_S == 6028.0


def test_inclination_and_plane_spacing():
    """The highest geocentric latitude is the inclination; the 6 planes' normals are 31.6 deg apart."""
    t = np.linspace(0.0, PERIOD_S, 2001)
    r = satellite_ecef(t)  # (T, 66, 3)
    lat = np.degrees(np.arcsin(r[..., 2] / np.linalg.norm(r, axis=-1)))
    assert lat.max() == pytest.approx(INCLINATION_DEG, abs=0.05)
    # inertial orbit normals of satellite 0 of each plane (cross product of two positions at t = 0, dt)
    r0, r1 = satellite_ecef(0.0), satellite_ecef(1.0)
    c, s = np.cos(OMEGA_E), np.sin(OMEGA_E)
    r1 = np.stack([c * r1[:, 0] - s * r1[:, 1], s * r1[:, 0] + c * r1[:, 1], r1[:, 2]], axis=-1)
    n = np.cross(r0, r1)[::11]
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    node = np.degrees(np.arctan2(n[:, 0], -n[:, 1]))  # right ascension of the ascending node
    np.testing.assert_allclose(np.diff(node), 31.6, atol=1e-9)
    assert 180.0 - (node[-1] - node[0]) == pytest.approx(22.0)  # the seam


def test_elevation_is_90_deg_under_a_satellite_and_negative_opposite():
    r = satellite_ecef(0.0)[5]
    lat, lon, _ = ecef_to_geodetic(r)
    # the geodetic point below the satellite sees it close to the zenith (geodetic vs geocentric vertical)
    el = elevations(lat, lon, 0.0)
    assert np.degrees(el[5]) > 89.5
    el_far = elevations(-lat, lon + np.pi, 0.0)
    assert el_far[5] < 0.0
    assert geodetic_to_ecef(lat, lon, 0.0).shape == (3,)


def test_continuous_coverage_at_the_iridium_mask_and_gaps_above_it():
    """Laid out for 8.2 deg: a satellite always in view (Belgium-Spain latitudes); at 30 deg, often none."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 3600.0, 30.0)
    none_low, none_high = [], []
    for lat in (41.0, 46.0, 51.0):
        phase = rng.uniform(0, 2 * np.pi, 2)
        el = elevations(np.radians(lat), np.radians(2.0), t, phase[0], phase[1])
        count, best = serving_satellite(el, IRIDIUM_MASK_DEG)
        none_low.append((count == 0).mean())
        none_high.append((serving_satellite(el, 30.0)[0] == 0).mean())
        seen = best[count > 0]
        assert np.all(np.isfinite(seen)) and np.all(np.degrees(seen) >= IRIDIUM_MASK_DEG)
    assert max(none_low) == 0.0
    assert min(none_high) > 0.2


def test_serving_satellite_counts_and_picks_the_highest():
    el = np.radians(np.array([[5.0, 10.0, 40.0, -3.0], [1.0, 2.0, 3.0, 4.0]]))
    count, best = serving_satellite(el, 8.2)
    np.testing.assert_array_equal(count, [2, 0])
    assert np.degrees(best[0]) == pytest.approx(40.0) and np.isnan(best[1])
