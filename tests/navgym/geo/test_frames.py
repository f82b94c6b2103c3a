import numpy as np
import pytest

from navgym import geo

from .tolerances import ANGLE_ATOL_RAD, ORTHO_ATOL, POS_ATOL_M


def _grid(seed: int = 0, n: int = 2000):
    rng = np.random.default_rng(seed)
    lat = rng.uniform(-np.pi / 2, np.pi / 2, n)
    lon = rng.uniform(-np.pi, np.pi, n)
    h = rng.uniform(-500.0, 2.5e7, n)
    return lat, lon, h


def test_constants_match_carvalho_1997():
    assert geo.A == 6378137.0
    assert geo.B == pytest.approx(6356752.314, abs=1e-3)
    assert geo.GM == 3.986005e14
    assert geo.OMEGA_E == pytest.approx(7.2921151467e-5, rel=1e-12)
    assert geo.E2 == pytest.approx(6.69437999014e-3, rel=1e-11)


def test_known_point_equator_and_pole():
    np.testing.assert_allclose(geo.geodetic_to_ecef(0.0, 0.0, 0.0), [geo.A, 0, 0], atol=1e-9)
    np.testing.assert_allclose(geo.geodetic_to_ecef(np.pi / 2, 0.3, 100.0), [0, 0, geo.B + 100.0], atol=1e-6)
    lat, lon, h = geo.ecef_to_geodetic([0.0, 0.0, -geo.B - 10.0])
    assert lat == pytest.approx(-np.pi / 2, abs=ANGLE_ATOL_RAD)
    assert h == pytest.approx(10.0, abs=POS_ATOL_M)


@pytest.mark.parametrize("seed", [0, 1])
def test_roundtrip_geodetic_ecef(seed):
    lat, lon, h = _grid(seed)
    xyz = geo.geodetic_to_ecef(lat, lon, h)
    lat2, lon2, h2 = geo.ecef_to_geodetic(xyz)
    np.testing.assert_allclose(h2, h, atol=POS_ATOL_M)
    np.testing.assert_allclose(lat2, lat, atol=ANGLE_ATOL_RAD)
    dlon = np.angle(np.exp(1j * (lon2 - lon)))
    assert np.all(np.abs(dlon * np.cos(lat)) < ANGLE_ATOL_RAD)


def test_against_pymap3d():
    pm = pytest.importorskip("pymap3d")
    lat, lon, h = _grid(3, 50)
    xyz = geo.geodetic_to_ecef(lat, lon, h)
    ref = np.array(pm.geodetic2ecef(lat, lon, h, deg=False)).T
    np.testing.assert_allclose(xyz, ref, atol=POS_ATOL_M)
    # pymap3d's inverse loses accuracy far above the surface (1e-6 rad at 2e6 m): compare low.
    low = geo.geodetic_to_ecef(lat, lon, np.clip(h, -500.0, 1e5))
    lat2, lon2, h2 = pm.ecef2geodetic(*low.T, deg=False)
    la, lo, hh = geo.ecef_to_geodetic(low)
    np.testing.assert_allclose(la, lat2, atol=1e-9)
    np.testing.assert_allclose(hh, h2, atol=POS_ATOL_M)
    ref_lat, ref_lon, ref_h = 0.6, -1.2, 300.0
    ned = geo.ecef_to_ned(xyz, ref_lat, ref_lon, ref_h)
    ref_ned = np.array(pm.ecef2ned(*xyz.T, ref_lat, ref_lon, ref_h, deg=False)).T
    np.testing.assert_allclose(ned, ref_ned, atol=POS_ATOL_M)
    sat = xyz[:10]
    rx = geo.geodetic_to_ecef(ref_lat, ref_lon, ref_h)
    el, az = geo.elevation_azimuth(rx, sat)
    az_ref, el_ref, _ = pm.ecef2aer(*sat.T, ref_lat, ref_lon, ref_h, deg=False)
    np.testing.assert_allclose(el, el_ref, atol=1e-9)
    np.testing.assert_allclose(np.cos(az - az_ref), 1.0, atol=1e-12)


def test_north_east_axes_are_the_first_rows_of_the_ned_matrix():
    lat, lon, _ = _grid(4, 100)
    north, east = geo.north_east_axes(lat.reshape(10, 10), lon.reshape(10, 10))
    c = geo.ecef_to_ned_matrix(lat, lon).reshape(10, 10, 3, 3)
    np.testing.assert_array_equal(north, c[..., 0, :])
    np.testing.assert_array_equal(east, c[..., 1, :])
    np.testing.assert_allclose(np.cross(north, east), c[..., 2, :], atol=ORTHO_ATOL)  # N x E = D


def test_ned_matrix_orthonormal_and_roundtrip():
    lat, lon, h = _grid(4, 100)
    c = geo.ecef_to_ned_matrix(lat, lon)
    assert c.shape == (100, 3, 3)
    np.testing.assert_allclose(
        c @ np.swapaxes(c, -1, -2), np.broadcast_to(np.eye(3), c.shape), atol=ORTHO_ATOL
    )
    np.testing.assert_allclose(np.linalg.det(c), 1.0, atol=ORTHO_ATOL)
    ned = np.random.default_rng(1).normal(0, 1e4, (100, 3))
    back = geo.ecef_to_ned(geo.ned_to_ecef(ned, lat, lon, h), lat, lon, h)
    np.testing.assert_allclose(back, ned, atol=POS_ATOL_M)


def test_ned_down_is_along_ellipsoid_normal():
    lat, lon = 0.7, 0.2
    up = geo.geodetic_to_ecef(lat, lon, 1000.0) - geo.geodetic_to_ecef(lat, lon, 0.0)
    ned = geo.ecef_to_ned_matrix(lat, lon) @ up
    np.testing.assert_allclose(ned, [0, 0, -1000.0], atol=1e-6)


def test_elevation_azimuth_broadcast_batch():
    rx = geo.geodetic_to_ecef(np.array([0.1, 0.5]), np.array([0.0, 1.0]), 0.0)  # (2, 3)
    sat = geo.geodetic_to_ecef(np.full((2, 4), 0.3), np.linspace(-1, 1, 8).reshape(2, 4), 2e7)
    el, az = geo.elevation_azimuth(rx[:, None, :], sat)
    assert el.shape == az.shape == (2, 4)
    for b in range(2):
        for j in range(4):
            e1, a1 = geo.elevation_azimuth(rx[b], sat[b, j])
            assert el[b, j] == pytest.approx(e1, abs=1e-14)
            assert az[b, j] == pytest.approx(a1, abs=1e-14)
    zenith = geo.geodetic_to_ecef(0.1, 0.0, 2e7)
    assert geo.elevation_azimuth(rx[0], zenith)[0] == pytest.approx(np.pi / 2, abs=1e-12)


def test_bad_shape_names_argument():
    with pytest.raises(ValueError, match="xyz"):
        geo.ecef_to_geodetic(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="sat_ecef"):
        geo.elevation_azimuth(np.ones(3), np.ones(2))


def test_up_vector_matches_ned_down_axis():
    lat, lon, h = _grid(5, 200)
    xyz = geo.geodetic_to_ecef(lat, lon, h)
    up = geo.up_vector(xyz)
    down = geo.ecef_to_ned_matrix(lat, lon)[..., 2, :]
    np.testing.assert_allclose(up, -down, atol=1e-12)
    np.testing.assert_allclose(geo.up_vector([0.0, 0.0, 7e6]), [0, 0, 1], atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1])
def test_geodetic_sincos_equals_trigonometry_of_the_angles(seed):
    lat, lon, h = _grid(seed)
    lat = np.clip(lat, -1.5, 1.5)  # off the polar axis, where sin/cos of lon are undefined
    xyz = geo.geodetic_to_ecef(lat, lon, h)
    got = geo.ecef_to_geodetic_sincos(xyz)
    ref = geo.ecef_to_geodetic(xyz)
    for a, b in zip(got[:3], ref, strict=True):
        np.testing.assert_array_equal(a, b)
    la, lo = ref[0], ref[1]
    for a, b in zip(got[3:], (np.sin(la), np.cos(la), np.sin(lo), np.cos(lo)), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)
