import numpy as np
import pytest

from navgym import geo
from navgym.gnss import (
    almanac_orbit,
    delta_range,
    geometric_range,
    goad_goodman_delay,
    klobuchar_delay,
    pseudorange,
    range_rate,
    saastamoinen_delay,
    sagnac_correction,
)
from navgym.gnss.troposphere import goad_goodman_delay_from_sine

from .tolerances import LIGHT_TIME_M, RANGE_RATE_MPS


def _rx():
    return geo.geodetic_to_ecef(np.deg2rad(45.0), np.deg2rad(5.0), 200.0)


def _exact_range(almanac, rx, t):
    """Iterated transmit time with the satellite rotated into the receive-time frame."""
    tau = np.full(almanac.prn.shape, 0.075)
    for _ in range(6):
        p = almanac_orbit(almanac, t - tau).position  # per satellite: broadcast below
        p = p[np.arange(p.shape[0]), np.arange(p.shape[0])] if p.ndim == 3 else p
        th = geo.OMEGA_E * tau
        x = np.cos(th) * p[:, 0] + np.sin(th) * p[:, 1]
        y = -np.sin(th) * p[:, 0] + np.cos(th) * p[:, 1]
        rho = np.sqrt((x - rx[0]) ** 2 + (y - rx[1]) ** 2 + (p[:, 2] - rx[2]) ** 2)
        tau = rho / geo.C_LIGHT
    return rho


def test_light_time_and_sagnac_match_exact(almanac):
    rx = _rx()
    t = almanac.t_ref[0] + 7000.0
    s = almanac_orbit(almanac, t)
    approx = geometric_range(rx, s.position, s.velocity)
    exact = _exact_range(almanac, rx, t)
    np.testing.assert_allclose(approx, exact, atol=LIGHT_TIME_M)
    plain = geometric_range(rx, s.position, earth_rotation=False)
    assert np.max(np.abs(plain - exact)) > 10.0  # the corrections matter
    sag = sagnac_correction(rx, s.position)
    assert np.max(np.abs(sag)) < 40.0


def test_range_rate_is_derivative_of_range(almanac):
    rx0 = _rx()
    v = np.array([12.0, -7.0, 3.0])
    t0 = almanac.t_ref[0] + 4000.0
    h = 0.5

    def rng(dt):
        s = almanac_orbit(almanac, t0 + dt)
        return geometric_range(rx0 + v * dt, s.position, s.velocity)

    fd = (rng(h) - rng(-h)) / (2 * h)
    s = almanac_orbit(almanac, t0)
    np.testing.assert_allclose(range_rate(rx0, v, s.position, s.velocity), fd, atol=RANGE_RATE_MPS)
    # Touil & Ghadi 2012, eq. 7 without Earth-rotation terms is the instantaneous projection.
    d = s.position - rx0
    eq7 = np.sum(d * (s.velocity - v), -1) / np.linalg.norm(d, axis=-1)
    np.testing.assert_allclose(range_rate(rx0, v, s.position, s.velocity, False), eq7)
    dr = delta_range(rx0, v, s.position, s.velocity, 3.5)
    np.testing.assert_allclose(dr - range_rate(rx0, v, s.position, s.velocity), 3.5)


def test_pseudorange_composition_and_batch(almanac):
    s = almanac_orbit(almanac, almanac.t_ref[0])
    rx = np.stack([_rx(), geo.geodetic_to_ecef(0.1, 2.0, 0.0)])  # (2, 3)
    sp = np.stack([s.position[:5], s.position[5:10]])
    sv = np.stack([s.velocity[:5], s.velocity[5:10]])
    bias = np.array([[100.0], [-3.0]])
    atm = np.arange(10.0).reshape(2, 5)
    pr = pseudorange(rx[:, None], sp, sv, bias, atm)
    assert pr.shape == (2, 5)
    for b in range(2):
        np.testing.assert_allclose(
            pr[b], geometric_range(rx[b], sp[b], sv[b]) + bias[b] + atm[b], rtol=0, atol=1e-6
        )
    with pytest.raises(ValueError, match="sat_vel"):
        geometric_range(rx[0], sp[0])
    with pytest.raises(ValueError, match="sat_pos"):
        geometric_range(rx[0], sp[0, :, :2], sv[0])


def test_goad_goodman_seed_constants():
    # Zenith: 1e-6 (N_d0 h_d + N_w0 h_w) with Carvalho et al. 1997's P, T, e.
    t, p, e = 298.0, 1013.0, 34.0
    n_d = 77.64 * p / t
    n_w = -12.96 * e / t + 3.718e5 * e / t**2
    h_d = 40136.0 + 148.72 * (t - 273.16)
    zenith = 1e-6 * (n_d * h_d + n_w * 11000.0)
    assert goad_goodman_delay(np.pi / 2) == pytest.approx(zenith, rel=1e-9)
    assert zenith == pytest.approx(13.12, abs=0.02)
    el = np.deg2rad([5.0, 10.0, 30.0, 60.0, 90.0])
    d = goad_goodman_delay(el)
    assert np.all(np.diff(d) < 0) and d[0] > 5 * d[-1]
    np.testing.assert_allclose(goad_goodman_delay(el, quartic_profile=True), d / 5)
    np.testing.assert_allclose(goad_goodman_delay_from_sine(np.sin(el)), d)


def test_saastamoinen_and_klobuchar_magnitudes():
    z = saastamoinen_delay(np.pi / 2, 0.8, 0.0)
    assert 2.3 < z < 2.6  # standard atmosphere zenith delay at sea level
    assert saastamoinen_delay(np.deg2rad(10.0), 0.8, 0.0) > 5 * z
    alpha = np.array([1.118e-8, 1.49e-8, -5.96e-8, -5.96e-8])
    beta = np.array([8.806e4, 1.638e4, -1.966e5, -1.311e5])
    lat, lon = np.deg2rad(35.0), np.deg2rad(139.0)
    # Night (local ~ 2 h): the constant 5 ns term times the obliquity F.
    night = klobuchar_delay(alpha, beta, lat, lon, np.pi / 2, 0.0, (2 - 139 / 15) % 24 * 3600)
    assert night == pytest.approx(geo.C_LIGHT * 5e-9 * (1 + 16 * (0.53 - 0.5) ** 3), rel=1e-9)
    # Local 14 h: peak of the cosine, several metres, larger at low elevation.
    tow = (14 - 139 / 15) % 24 * 3600
    day = klobuchar_delay(alpha, beta, lat, lon, np.deg2rad([90.0, 15.0]), 0.0, tow)
    assert 2.0 < day[0] < 15.0 and day[1] > 2 * day[0]
    with pytest.raises(ValueError, match="alpha"):
        klobuchar_delay(alpha[:3], beta, lat, lon, 1.0, 0.0, 0.0)


def test_fused_range_and_rate_equals_separate(almanac):
    from navgym.gnss.measurements import range_and_rate

    s = almanac_orbit(almanac, almanac.t_ref[0] + 100.0)
    rx, v = _rx(), np.array([1.0, 2.0, -3.0])
    rho, rate = range_and_rate(rx, v, s.position, s.velocity)
    np.testing.assert_allclose(rho, geometric_range(rx, s.position, s.velocity), rtol=0, atol=1e-7)
    np.testing.assert_allclose(rate, range_rate(rx, v, s.position, s.velocity), rtol=0, atol=1e-9)


def test_ecef_acceleration_is_derivative_of_velocity(almanac):
    from navgym.gnss.orbit import ecef_acceleration

    t, h = almanac.t_ref[0] + 500.0, 1.0
    s = almanac_orbit(almanac, t)
    fd = (almanac_orbit(almanac, t + h).velocity - almanac_orbit(almanac, t - h).velocity) / (2 * h)
    acc = ecef_acceleration(s.position, s.velocity)
    # Two-body; the almanac nodal precession adds about 2 Omega_dot v = 6e-5 m/s^2.
    np.testing.assert_allclose(acc, fd, atol=1e-4)
