import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from navgym.gnss import signal_quality as sq


def test_chip_length_is_c_over_chip_rate():
    assert sq.CA_CHIP_LENGTH_M == pytest.approx(293.052, abs=1e-3)


def test_nominal_cn0_spans_horizon_to_zenith_and_rises_with_elevation():
    el = np.radians([-5.0, 0.0, 15.0, 45.0, 90.0])
    c = sq.nominal_cn0_dbhz(el, zenith_dbhz=48.0, horizon_dbhz=32.0)
    assert c[0] == c[1] == 32.0 and c[-1] == 48.0
    assert np.all(np.diff(c[1:]) > 0)
    assert c[3] == pytest.approx(32.0 + 16.0 * np.sin(np.radians(45.0)))
    with pytest.raises(ValueError, match="horizon_dbhz"):
        sq.nominal_cn0_dbhz(el, zenith_dbhz=30.0, horizon_dbhz=40.0)


def test_effective_cn0_formula_and_limits():
    # no jammer: unchanged; J/S = Q Rc / (C/N0) halves the density ratio (3 dB down)
    assert sq.effective_cn0_dbhz(45.0, -np.inf) == pytest.approx(45.0)
    cn0 = 10**4.5
    js_db = 10 * np.log10(2.0 * sq.CA_CHIP_RATE_HZ / cn0)
    assert sq.effective_cn0_dbhz(45.0, js_db, q=2.0) == pytest.approx(45.0 - 10 * np.log10(2.0))
    # a strong jammer: (C/N0)_eff -> 10 log10(Q Rc) - J/S, whatever the signal (about 63 dB-Hz - J/S for C/A)
    assert sq.effective_cn0_dbhz(48.0, 50.0) == pytest.approx(10 * np.log10(2 * 1.023e6) - 50.0, abs=0.01)
    # every row of a receiver drops together and the order of the rows is kept
    rows = np.array([35.0, 42.0, 48.0])
    jammed = sq.effective_cn0_dbhz(rows, 30.0)
    assert np.all(jammed < rows) and np.all(np.diff(jammed) > 0)
    with pytest.raises(ValueError, match="q"):
        sq.effective_cn0_dbhz(45.0, 10.0, q=0.0)


def test_dll_jitter_known_values():
    # B_L = 1 Hz, d = 1 chip, T = 20 ms: 45 dB-Hz -> 0.00398 chips (1.17 m); 30 dB-Hz -> 0.0235 chips (6.9 m)
    j = sq.dll_jitter_m([45.0, 30.0])
    expected = [
        293.052 * np.sqrt(1 / (2 * 10**4.5) * (1 + 2 / (0.02 * 10**4.5))),
        293.052 * np.sqrt(1 / (2 * 10**3.0) * (1 + 2 / (0.02 * 10**3.0))),
    ]
    np.testing.assert_allclose(j, expected, rtol=1e-5)
    assert 1.1 < j[0] < 1.2 and 6.8 < j[1] < 7.0
    # narrower correlators and loops reduce the jitter
    assert sq.dll_jitter_m(40.0, spacing_chips=0.1) < sq.dll_jitter_m(40.0)
    assert sq.dll_jitter_m(40.0, loop_bandwidth_hz=0.5) < sq.dll_jitter_m(40.0)
    with pytest.raises(ValueError, match="spacing_chips"):
        sq.dll_jitter_m(40.0, spacing_chips=1.5)


@given(st.floats(35.0, 60.0))
def test_sigma_epsilon_is_the_dll_high_cn0_limit(cn0):
    c_i = sq.sigma_epsilon_constant()
    ratio = sq.dll_jitter_m(cn0) ** 2 / sq.sigma_epsilon_variance(cn0, c_i)
    # the squaring-loss term 2 / ((2 - d) T c/n0) is all that separates them
    assert ratio == pytest.approx(1 + 2 / (0.02 * 10 ** (cn0 / 10)), rel=1e-9)
    assert 1.0 <= ratio < 1.04


def test_elevation_variance_rtklib_form():
    v = sq.elevation_variance(np.radians([90.0, 30.0, 1.0]), a_m=0.3, b_m=0.3)
    assert v[0] == pytest.approx(0.18)
    assert v[1] == pytest.approx(0.09 + 0.09 / 0.25)
    assert v[2] == pytest.approx(0.09 + 0.09 / np.sin(0.0873) ** 2)  # held at 5 deg
    with pytest.raises(ValueError, match="a_m"):
        sq.elevation_variance(0.5, a_m=-1.0, b_m=0.3)


def test_reported_cn0_noise_and_resolution():
    rng = np.random.default_rng(3)
    true = np.full(20000, 40.3)
    rep = sq.reported_cn0_dbhz(true, rng.standard_normal(true.shape), sigma_db=1.0, resolution_db=1.0)
    assert np.all(rep == np.round(rep))
    assert abs(rep.mean() - 40.3) < 0.05 and 0.9 < rep.std() < 1.2
    exact = sq.reported_cn0_dbhz(true, np.zeros_like(true), sigma_db=1.0, resolution_db=0.0)
    np.testing.assert_array_equal(exact, true)


def test_tracking_threshold():
    np.testing.assert_array_equal(sq.tracked([20.0, 25.0, 40.0]), [False, True, True])
