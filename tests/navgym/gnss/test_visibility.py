import numpy as np
import pytest

from navgym import geo
from navgym.gnss import (
    almanac_orbit,
    count_visible,
    default_critical_window,
    dop,
    find_critical_window,
    select_satellites,
    visible,
)
from navgym.gnss.critical import CRITICAL_WINDOW_DEFAULT, visible_counts

PLACES_DEG = [(43.6, 1.44), (35.7, 139.7), (-33.9, 151.2), (0.0, -78.5), (64.1, -21.9)]


@pytest.mark.parametrize(("lat", "lon"), PLACES_DEG)
def test_visible_count_plausible(almanac, lat, lon):
    rx = geo.geodetic_to_ecef(np.deg2rad(lat), np.deg2rad(lon), 100.0)
    t = almanac.t_ref[0] + np.arange(0.0, 86400.0, 3 * 3600.0)
    pos = almanac_orbit(almanac, t).position  # (T, S, 3)
    el, _ = geo.elevation_azimuth(rx, pos)
    n = count_visible(el, 10.0)
    assert np.all((n >= 6) & (n <= 12)), n
    # The fast sine-of-elevation counter agrees with the angle-based one.
    np.testing.assert_array_equal(visible_counts(almanac, rx, t, 10.0)[0], n)


def test_select_satellites_order_and_mask():
    el = np.deg2rad(np.array([[5.0, 60.0, 20.0, 60.0, 80.0, -3.0]]))
    idx, mask = select_satellites(el, 10.0, m_max=5)
    assert idx.tolist() == [[4, 1, 3, 2, 0]]  # ties (60 deg) by index, then below-mask by index
    assert mask.tolist() == [[True, True, True, True, False]]
    idx, mask = select_satellites(el, 10.0, m_max=3, prn=np.array([9, 8, 7, 6, 5, 4]), sort_by_prn=True)
    assert idx.tolist() == [[4, 3, 1]] and mask.all()  # PRNs 5, 6, 8
    avail = np.array([True, True, True, False, True, True])
    idx, mask = select_satellites(el, 10.0, m_max=4, available=avail)
    assert idx.tolist() == [[4, 1, 2, 0]] and mask.tolist() == [[True, True, True, False]]


@pytest.mark.parametrize("bad", [-1.0, 90.0, 95.0, np.nan])
def test_impossible_mask_angle_names_parameter(bad):
    with pytest.raises(ValueError, match="mask_deg"):
        visible(np.zeros(3), bad)
    with pytest.raises(ValueError, match="mask_deg"):
        select_satellites(np.zeros((1, 3)), bad)


def test_dop_known_geometry():
    # Zenith plus three satellites at elevation e, azimuths 0/120/240: closed-form DOPs.
    lat, lon = 0.4, 0.2
    rx = geo.geodetic_to_ecef(lat, lon, 0.0)
    e = np.deg2rad(30.0)
    az = np.deg2rad([0.0, 120.0, 240.0])
    ned = np.stack([np.cos(e) * np.cos(az), np.cos(e) * np.sin(az), -np.sin(e) * np.ones(3)], -1)
    ned = np.vstack([[0.0, 0.0, -1.0], ned]) * 2e7
    sat = geo.ned_to_ecef(ned, lat, lon, 0.0)
    d = dop(rx, sat)
    g = np.column_stack([-ned / 2e7, np.ones(4)])
    q = np.linalg.inv(g.T @ g)
    assert d.gdop == pytest.approx(np.sqrt(np.trace(q)), rel=1e-9)
    assert d.hdop == pytest.approx(np.sqrt(q[0, 0] + q[1, 1]), rel=1e-9)
    assert d.hdop == pytest.approx(np.sqrt(4 / (3 * np.cos(e) ** 2)), rel=1e-9)
    # Batched with a mask: fewer than 4 rows -> inf (Carvalho et al. 1997, §V: GDOP undefined).
    sats = np.stack([sat, sat])
    mask = np.array([[True] * 4, [True, True, True, False]])
    db = dop(np.stack([rx, rx]), sats, mask)
    assert db.gdop[0] == pytest.approx(d.gdop) and np.isinf(db.gdop[1])


def test_cached_critical_window_goes_three_to_two(almanac):
    w = default_critical_window(almanac)
    assert w.counts.shape == (3601,)
    assert w.counts[0] == 3 and w.counts[-1] == 2
    assert set(np.unique(w.counts)) == {2, 3}
    assert np.all(np.diff(w.counts) <= 0)  # a single 3 -> 2 switch, 1 s resolution
    assert 900.0 <= w.switch_s <= 2700.0
    assert w.mask_deg == 50.0


def test_critical_search_reproduces_cache(almanac):
    w = find_critical_window(almanac, mask_deg=50.0, duration_s=3600.0)
    lat, lon, t0 = CRITICAL_WINDOW_DEFAULT
    assert np.rad2deg(w.lat) == pytest.approx(lat) and np.rad2deg(w.lon) == pytest.approx(lon)
    assert w.t0 == t0
    np.testing.assert_array_equal(w.counts, default_critical_window(almanac).counts)
    with pytest.raises(ValueError, match="mask_deg"):
        find_critical_window(almanac, mask_deg=90.0)


def test_fast_gdop_equals_dop_gdop():
    """navgym.gnss.gdop (per-step, element-wise Cholesky) == dop().gdop on random geometries,
    masks included; fewer than 4 usable satellites give inf in both."""
    from navgym.gnss import gdop

    rng = np.random.default_rng(3)
    B, m = 50, 10
    rx = geo.geodetic_to_ecef(rng.uniform(-1.2, 1.2, B), rng.uniform(-3, 3, B), rng.uniform(0, 500, B))
    sat = rng.normal(0, 1, (B, m, 3))
    sat *= 2.66e7 / np.linalg.norm(sat, axis=2, keepdims=True)
    mask = rng.random((B, m)) < 0.7
    mask[:3] = False
    mask[:3, :3] = True  # three usable satellites: undefined
    fast = gdop(rx, sat, mask)
    ref = dop(rx, sat, mask).gdop
    assert np.isinf(fast[:3]).all() and np.isinf(ref[:3]).all()
    np.testing.assert_allclose(fast[3:], ref[3:], rtol=1e-9)
