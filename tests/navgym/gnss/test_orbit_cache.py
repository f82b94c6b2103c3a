"""The tabulated orbit cache equals the Kepler model to sub-millimetre accuracy."""

import numpy as np

from navgym.gnss import almanac_orbit, load_default_almanac
from navgym.gnss.orbit_cache import OrbitCache


def test_hermite_interpolation_matches_kepler_orbits():
    alm = load_default_almanac()
    cache = OrbitCache(alm, step=30.0, span=86400.0)
    t = alm.t_ref[0] + np.random.default_rng(0).uniform(-80000.0, 80000.0, 500)
    exact, approx = almanac_orbit(alm, t), cache(t)
    assert np.abs(exact.position - approx.position).max() < 1e-3  # metres
    assert np.abs(exact.velocity - approx.velocity).max() < 1e-5  # m/s


def test_times_outside_the_table_fall_back_to_the_exact_model():
    alm = load_default_almanac()
    cache = OrbitCache(alm, step=30.0, span=3600.0)
    t = np.array([alm.t_ref[0] + 10 * 86400.0])
    np.testing.assert_array_equal(cache(t).position, almanac_orbit(alm, t).position)
