import numpy as np
import pytest

from navgym import geo
from navgym.gnss import (
    Almanac,
    almanac_orbit,
    ephemeris_clock,
    ephemeris_orbit,
    select_ephemeris,
    solve_spp,
    spp_from_rinex,
    take_ephemeris,
)

from .tolerances import (
    ALMANAC_VS_BROADCAST_M,
    ORBIT_VELOCITY_MPS,
    SPP_MEDIAN_NO_CORRECTIONS_M,
    SPP_MEDIAN_WITH_ATMOSPHERE_M,
)


def _first_record_per_prn(eph):
    _, first = np.unique(eph.prn, return_index=True)
    return take_ephemeris(eph, first)


def test_almanac_model_matches_broadcast_over_an_hour(nav):
    eph = _first_record_per_prn(nav.ephemeris)
    alm = Almanac(
        prn=eph.prn,
        health=np.zeros_like(eph.prn),
        e=eph.e,
        toa=eph.toe_sow,
        i0=eph.i0,
        omega_dot=eph.omega_dot,
        sqrt_a=eph.sqrt_a,
        omega0=eph.omega0,
        omega=eph.omega,
        m0=eph.m0,
        af0=eph.af0,
        af1=eph.af1,
        week=eph.week,
    )
    t = eph.toe + np.arange(0.0, 3601.0, 60.0)[:, None]  # (T, S)
    full = ephemeris_orbit(eph, t).position
    kepler = almanac_orbit(Almanac(*(np.broadcast_to(f, t.shape) for f in alm)), t).position
    err = np.linalg.norm(full - kepler, axis=-1)
    assert err.max() < ALMANAC_VS_BROADCAST_M
    assert err[0].max() < 1000.0  # at t_oe only the harmonic corrections differ


def test_broadcast_velocity_is_derivative(nav):
    eph = _first_record_per_prn(nav.ephemeris)
    t = eph.toe + 1000.0
    h = 0.5
    v = ephemeris_orbit(eph, t).velocity
    fd = (ephemeris_orbit(eph, t + h).position - ephemeris_orbit(eph, t - h).position) / (2 * h)
    np.testing.assert_allclose(v, fd, atol=ORBIT_VELOCITY_MPS)


def test_select_ephemeris(nav):
    eph = nav.ephemeris
    prn = np.array([[1, 3, 33, 0]])
    t = eph.toe[eph.prn == 3][0] + 100.0
    idx = select_ephemeris(eph, prn, t)
    assert idx[0, 2] == -1 and idx[0, 3] == -1
    assert eph.prn[idx[0, 1]] == 3 and abs(eph.toe[idx[0, 1]] - t) <= 7200
    cands = np.flatnonzero(eph.prn == 3)
    assert abs(eph.toe[idx[0, 1]] - t) == np.min(np.abs(eph.toe[cands] - t))


def test_satellite_clock_terms(nav):
    eph = take_ephemeris(nav.ephemeris, np.array([0]))
    t = eph.toc + 600.0
    with_tgd = ephemeris_clock(eph, t)
    without = ephemeris_clock(eph, t, l1_group_delay=False)
    np.testing.assert_allclose(without - with_tgd, eph.tgd)
    poly = eph.af0 + eph.af1 * 600.0 + eph.af2 * 600.0**2
    rel = without - poly  # relativistic term F e sqrt(A) sin E: |.| <= 4.4e-10 * 0.006 * 5154
    assert np.all(np.abs(rel) <= 4.443e-10 * eph.e * eph.sqrt_a + 1e-18)


@pytest.mark.parametrize(
    ("ionosphere", "troposphere", "bound"),
    [
        (False, False, SPP_MEDIAN_NO_CORRECTIONS_M),
        (True, True, SPP_MEDIAN_WITH_ATMOSPHERE_M),
    ],
)
def test_spp_on_geonet_0759(obs, nav, ionosphere, troposphere, bound):
    sol = spp_from_rinex(obs, nav, mask_deg=10.0, ionosphere=ionosphere, troposphere=troposphere)
    assert sol.valid.all() and sol.position.shape == (120, 3)
    err = np.linalg.norm(sol.position - obs.approx_position, axis=1)
    assert np.median(err) < bound
    assert np.all(sol.used.sum(axis=1) >= 6)
    assert np.abs(sol.residuals).max() < 10.0


def test_spp_atmosphere_helps(obs, nav):
    plain = spp_from_rinex(obs, nav)
    full = spp_from_rinex(obs, nav, ionosphere=True, troposphere=True)
    e_plain = np.linalg.norm(plain.position - obs.approx_position, axis=1)
    e_full = np.linalg.norm(full.position - obs.approx_position, axis=1)
    assert np.median(e_full) < 0.3 * np.median(e_plain)


def test_solve_spp_synthetic_exact_and_underdetermined():
    rng = np.random.default_rng(3)
    truth = geo.geodetic_to_ecef(np.array([0.7, -0.3]), np.array([0.1, 2.0]), 50.0)
    up = geo.up_vector(truth)
    dirs = rng.normal(size=(2, 6, 3)) + 2.5 * up[:, None, :]
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    sat = truth[:, None, :] + 2.2e7 * dirs
    bias = np.array([1234.5, -50.0])
    rho = np.linalg.norm(sat - truth[:, None], axis=-1)
    rho += geo.OMEGA_E / geo.C_LIGHT * (sat[..., 0] * truth[:, None, 1] - sat[..., 1] * truth[:, None, 0])
    rho += bias[:, None]
    mask = np.ones((2, 6), bool)
    mask[1, 3:] = False  # episode 1 has only 3 satellites: no fix
    sol = solve_spp(rho, sat, mask, mask_deg=0.0)
    np.testing.assert_allclose(sol.position[0], truth[0], atol=1e-4)
    assert sol.clock_bias_m[0] == pytest.approx(bias[0], abs=1e-4)
    assert sol.valid.tolist() == [True, False] and np.all(np.isnan(sol.position[1]))


def test_spp_bad_input():
    with pytest.raises(ValueError, match="mask_deg"):
        solve_spp(np.zeros((1, 4)), np.zeros((1, 4, 3)), np.ones((1, 4), bool), mask_deg=90.0)
    with pytest.raises(ValueError, match="sat_pos"):
        solve_spp(np.zeros((1, 4)), np.zeros((1, 3, 3)), np.ones((1, 4), bool))
