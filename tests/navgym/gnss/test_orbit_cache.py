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


def test_lookup_selects_the_same_states_as_the_full_interpolation():
    alm = load_default_almanac()
    cache = OrbitCache(alm, step=30.0, span=86400.0)
    rng = np.random.default_rng(1)
    t = alm.t_ref[0] + rng.uniform(-80000.0, 80000.0, 64)
    full, lazy = cache(t), cache.lookup(t)
    np.testing.assert_array_equal(lazy.position, full.position)
    idx = np.argsort(rng.random((64, alm.prn.shape[0])), axis=1)[:, :12]
    pos, vel = lazy.select(idx)
    np.testing.assert_array_equal(pos, np.take_along_axis(full.position, idx[..., None], axis=1))
    np.testing.assert_allclose(
        vel, np.take_along_axis(full.velocity, idx[..., None], axis=1), rtol=0, atol=1e-9
    )
    exact = almanac_orbit(alm, t)
    assert np.abs(np.take_along_axis(exact.velocity, idx[..., None], axis=1) - vel).max() < 1e-5


def test_simulated_step_is_the_same_with_the_lazy_lookup():
    from navgym.gnss import ClockState, make_regime, simulate_gnss_step

    alm = load_default_almanac()
    cache = OrbitCache(alm, step=30.0, span=86400.0)
    rng = np.random.default_rng(2)
    B = 32
    t = alm.t_ref[0] + rng.uniform(-8000.0, 8000.0, B)
    lat, lon = np.deg2rad(rng.uniform(-60, 60, B)), np.deg2rad(rng.uniform(-180, 180, B))
    R = 6.378e6
    rx = R * np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)
    args = (rx, rng.normal(0, 10, (B, 3)), ClockState(np.zeros(B), np.zeros(B)), make_regime(B))
    normals, uniforms = rng.standard_normal((B, 36)), rng.random((B, 36))
    a = simulate_gnss_step(alm, t, *args, normals, uniforms, orbit=cache(t))
    b = simulate_gnss_step(alm, t, *args, normals, uniforms, orbit=cache.lookup(t))
    np.testing.assert_array_equal(a.sat_index, b.sat_index)
    np.testing.assert_array_equal(a.pseudorange, b.pseudorange)
    np.testing.assert_allclose(a.delta_range, b.delta_range, rtol=0, atol=1e-9)


def test_a_buffered_lookup_is_bit_identical_through_interval_changes_and_replaced_rows():
    alm = load_default_almanac()
    cache = OrbitCache(alm, step=30.0, span=86400.0)
    rng = np.random.default_rng(3)
    B = 16
    t0 = alm.t_ref[0] + rng.uniform(-80000.0, 80000.0, B)
    buf = cache.new_buffer(B)
    assert (buf.interval == -1).all()
    idx = np.argsort(rng.random((B, alm.prn.shape[0])), axis=1)[:, :12]
    for k in range(75):  # 1 s steps: every row crosses two or three 30 s intervals
        if k == 40:  # a reset episode: another time, its row keeps the old coefficients
            t0[[2, 9]] = alm.t_ref[0] + rng.uniform(-80000.0, 80000.0, 2)
        t = t0 + k
        plain, buffered = cache.lookup(t), cache.lookup(t, buf)
        np.testing.assert_array_equal(buffered.position, plain.position)
        np.testing.assert_array_equal(buffered.coef, plain.coef)
        for a, b in zip(buffered.select(idx), plain.select(idx), strict=True):
            np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(buf.interval, np.floor((t - cache._t0) / cache.step).astype(np.int64))


def test_a_buffer_of_the_wrong_size_is_refused():
    import pytest

    alm = load_default_almanac()
    cache = OrbitCache(alm, step=30.0, span=86400.0)
    t = alm.t_ref[0] + np.zeros(4)
    with pytest.raises(ValueError, match="buffer holds 3 rows"):
        cache.lookup(t, cache.new_buffer(3))
