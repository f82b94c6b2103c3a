"""GpsIns v3 context physics (navgym.gps_ins.context): the C/N0 -> sigma chain and the J/S map."""

from __future__ import annotations

import numpy as np

from navgym.gnss import signal_quality as sq
from navgym.gps_ins import context
from navgym.gps_ins.platform import GpsInsPlatform


def test_sigma_matches_v2_nominal_at_reference_elevation():
    cn0 = sq.nominal_cn0_dbhz(context.REFERENCE_ELEVATION_RAD)
    np.testing.assert_allclose(context.pseudorange_sigma_m(cn0, 5.0), 5.0, rtol=1e-12)


def test_sigma_falls_with_cn0_like_sigma_epsilon():
    cn0 = np.array([35.0, 45.0])
    s = context.pseudorange_sigma_m(cn0, 5.0)
    assert s[0] > s[1]
    # 10 dB less C/N0: ~10x the variance (SIGMA-epsilon), a little more from the squaring loss
    ratio = (s[0] / s[1]) ** 2
    assert 10.0 <= ratio < 11.0


def test_jammer_reproduces_v2_jamming_variance():
    sigma_pr, jam = 5.0, np.array([0.0, 5.0, 20.0])
    js = context.jammer_to_signal_db(jam, sigma_pr)
    assert js[0] == -np.inf
    cn0 = sq.effective_cn0_dbhz(sq.nominal_cn0_dbhz(context.REFERENCE_ELEVATION_RAD), js, q=context.JAMMER_Q)
    var = context.pseudorange_sigma_m(cn0, sigma_pr) ** 2
    np.testing.assert_allclose(var, sigma_pr**2 + jam**2, rtol=1e-9)


def test_process_noise_states_are_the_velocity_errors():
    assert GpsInsPlatform().process_noise_states == (2, 3)


def test_row_cn0_falls_with_elevation_attenuation_and_jamming():
    el = np.deg2rad([[10.0, 45.0, 80.0]])
    open_sky = context.row_cn0_dbhz(el, 0.0, -np.inf)
    assert np.all(np.diff(open_sky) > 0)
    nlos = context.row_cn0_dbhz(el, np.array([[0.0, 10.0, 0.0]]), -np.inf)
    np.testing.assert_allclose(nlos[0, [0, 2]], open_sky[0, [0, 2]])
    np.testing.assert_allclose(nlos[0, 1], open_sky[0, 1] - 10.0)
    js = context.jammer_to_signal_db(np.array([[20.0]]), 5.0)
    jammed = context.row_cn0_dbhz(el, 0.0, js)
    assert np.all(jammed < open_sky - 1.0)


def test_window_stats_shorten_at_start():
    x = np.arange(10.0)[None, :]
    m, s = context.window_stats(x, 0, 3)
    assert m[0] == 0.0 and s[0] == 0.0
    m, s = context.window_stats(x, 5, 3)
    assert m[0] == 4.0
    np.testing.assert_allclose(s[0], np.std([3.0, 4.0, 5.0]))
