import numpy as np
import pytest

from navgym import geo
from navgym.gnss import (
    NORMALS_PER_ROW,
    UNIFORMS_PER_ROW,
    ClockState,
    constellation,
    count_visible,
    delta_range,
    goad_goodman_delay,
    make_regime,
    pseudorange,
    simulate_gnss_step,
)

M = 12


def _setup(b=3, seed=0):
    rng = np.random.default_rng(seed)
    rx = geo.geodetic_to_ecef(rng.uniform(-1, 1, b), rng.uniform(-3, 3, b), 100.0)
    vel = rng.normal(0, 20, (b, 3))
    clock = ClockState(rng.normal(0, 1e-6, b), rng.normal(0, 1e-9, b))
    z = rng.standard_normal((b, NORMALS_PER_ROW * M))
    u = rng.random((b, UNIFORMS_PER_ROW * M))
    return rx, vel, clock, z, u


def test_step_composes_the_models(almanac):
    rx, vel, clock, z, u = _setup()
    t = almanac.t_ref[0] + 1000.0
    reg = make_regime(3, sigma=1e-9, sigma_dr=1e-9)
    g = simulate_gnss_step(almanac, t, rx, vel, clock, reg, z, u, mask_deg=10.0)
    orbit = constellation(almanac, t)
    el_all, _ = geo.elevation_azimuth(rx[:, None], orbit.position)
    np.testing.assert_array_equal(g.mask.sum(1), np.minimum(count_visible(el_all, 10.0), M))
    np.testing.assert_allclose(g.elevation, np.take_along_axis(el_all, g.sat_index, 1), atol=1e-9)
    vis_el = np.where(g.mask, g.elevation, -10.0)
    assert np.all(np.diff(vis_el, axis=1) <= 0)  # highest first
    assert np.all(g.elevation[g.mask] > np.deg2rad(10.0))
    assert np.all(g.prn == almanac.prn[g.sat_index])
    tropo = goad_goodman_delay(g.elevation)
    np.testing.assert_allclose(g.troposphere, tropo, rtol=1e-9)
    zt = z[:, 2 * M :]  # block layout: [pseudo-range | delta-range | troposphere]
    expected = pseudorange(rx[:, None], g.sat_pos, g.sat_vel, clock.bias_m[:, None], tropo * (1 + 0.05 * zt))
    np.testing.assert_allclose(g.pseudorange, expected, rtol=0, atol=1e-6)
    dr = delta_range(rx[:, None], vel[:, None], g.sat_pos, g.sat_vel, clock.drift_mps[:, None])
    np.testing.assert_allclose(g.delta_range, dr, rtol=0, atol=1e-6)


def test_noise_std_in_step(almanac):
    b = 400
    rx, vel, clock, z, u = _setup(b, seed=1)
    reg = make_regime(b, sigma=7.0)
    t = almanac.t_ref[0]
    g = simulate_gnss_step(almanac, t, rx, vel, clock, reg, z, u, troposphere=False)
    clean = pseudorange(rx[:, None], g.sat_pos, g.sat_vel, clock.bias_m[:, None])
    err = (g.pseudorange - clean)[g.mask]
    assert err.size > 2500
    assert np.std(err) == pytest.approx(7.0, rel=0.05)


def test_per_episode_time_and_mask(almanac):
    rx, vel, clock, z, u = _setup()
    reg = make_regime(3)
    t = almanac.t_ref[0] + 500.0
    shared = simulate_gnss_step(almanac, t, rx, vel, clock, reg, z, u, mask_deg=[5.0, 10.0, 40.0])
    per_ep = simulate_gnss_step(
        almanac, np.full(3, t), rx, vel, clock, reg, z, u, mask_deg=np.array([5.0, 10.0, 40.0])
    )
    np.testing.assert_allclose(shared.pseudorange, per_ep.pseudorange, atol=1e-6)
    np.testing.assert_array_equal(shared.mask, per_ep.mask)
    assert np.all(shared.elevation[2][shared.mask[2]] > np.deg2rad(40.0))


def test_available_satellites_and_loss(almanac):
    rx, vel, clock, z, u = _setup()
    avail = np.ones(almanac.prn.shape, bool)
    avail[::2] = False
    reg = make_regime(3, loss_prob=[0.0, 1.0, 0.0])
    g = simulate_gnss_step(almanac, almanac.t_ref[0], rx, vel, clock, reg, z, u, available=avail)
    assert np.all(g.sat_index[g.visible] % 2 == 1)
    assert not g.mask[1].any() and g.mask[0].any()


def test_pseudo_ranges_and_draws_are_the_same_without_delta_ranges(almanac):
    from navgym.gnss.orbit_cache import OrbitCache

    B = 32
    rx, vel, clock, z, u = _setup(B, seed=4)
    t = almanac.t_ref[0] + np.random.default_rng(5).uniform(-8000.0, 8000.0, B)
    regime = make_regime(B, eps=np.full(B, 0.3), var_ratio=np.full(B, 100.0), loss_prob=np.full(B, 0.2))
    cache = OrbitCache(almanac, step=30.0, span=86400.0)
    for earth_rotation in (True, False):
        kw = {"orbit": cache.lookup(t), "earth_rotation": earth_rotation}
        full = simulate_gnss_step(almanac, t, rx, vel, clock, regime, z, u, **kw)
        pr_only = simulate_gnss_step(almanac, t, rx, vel, clock, regime, z, u, delta_range=False, **kw)
        assert pr_only.delta_range is None and full.delta_range is not None
        for name in ("pseudorange", "mask", "sat_index", "sat_pos", "sat_vel", "troposphere"):
            np.testing.assert_array_equal(getattr(pr_only, name), getattr(full, name), err_msg=name)
        np.testing.assert_array_equal(pr_only.noise.pseudorange, full.noise.pseudorange)
        assert full.mask.any() and not full.mask.all()  # some rows used, some lost or below the mask


def test_bad_input(almanac):
    rx, vel, clock, z, u = _setup()
    reg = make_regime(3)
    t = almanac.t_ref[0]
    with pytest.raises(ValueError, match="normals"):
        simulate_gnss_step(almanac, t, rx, vel, clock, reg, z[:, :5], u)
    with pytest.raises(ValueError, match="mask_deg"):
        simulate_gnss_step(almanac, t, rx, vel, clock, reg, z, u, mask_deg=-5.0)
    with pytest.raises(ValueError, match="rx_ecef"):
        simulate_gnss_step(almanac, t, rx[:, :2], vel, clock, reg, z, u)
    with pytest.raises(ValueError, match="rx_vel"):
        simulate_gnss_step(almanac, t, rx, vel[:2], clock, reg, z, u)
    with pytest.raises(ValueError, match="regime"):
        simulate_gnss_step(almanac, t, rx, vel, clock, make_regime(2), z, u)
    with pytest.raises(ValueError, match="m_max"):
        simulate_gnss_step(almanac, t, rx, vel, clock, reg, z, u, m_max=0)
