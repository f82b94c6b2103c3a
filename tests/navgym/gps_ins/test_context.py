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
