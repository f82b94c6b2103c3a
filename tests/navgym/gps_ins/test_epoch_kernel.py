"""The compiled GpsIns epoch (navgym.gps_ins.epoch_kernel) equals the NumPy reference path."""

import copy
from dataclasses import replace

import numpy as np
import pytest

import navgym  # noqa: F401
from navgym.gnss.orbit_cache import default_orbit_cache
from navgym.gnss.troposphere import TROPO_NOISE_FRACTION, goad_goodman_coefficients
from navgym.gps_ins.env import GPS_INS
from navgym.gps_ins.epoch_kernel import pseudorange_epoch

_core = GPS_INS.core

CONFIGS = {
    # outages, jamming (wider noise, losses), the fading task's defaults
    "fading": ("fading", {}),
    # impulsive mixture noise, outlier satellites with gross errors, partial outages
    "faults": (
        "mixture",
        {"outlier_probability": 1.0, "partial_probability": 0.5, "impulsive_probability": 1.0},
    ),
    # Carvalho et al. 1997's critical scenario: 50 deg mask, 3 -> 2 satellites
    "critical": ("fading", {"critical": True}),
}


def _pair(task, kw, B=24, seed=7):
    core = _core(task, B, dict(kw))
    rngs = [np.random.default_rng(seed + i) for i in range(B)]
    core.reset(np.arange(B), rngs, [None] * B)
    return core.platform, core.episodes


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_compiled_epoch_equals_the_numpy_reference(name):
    task, kw = CONFIGS[name]
    platform, ep = _pair(task, kw)
    ep_c, ep_r = copy.deepcopy(ep), copy.deepcopy(ep)
    reference = replace(platform, compiled=False)
    B, T = ep.gps_t0.shape[0], ep.heading.shape[1] - 1
    start = 1900 if name == "critical" else 0  # the drop to 2 satellites is at 1983 s
    seen = {"masked": 0, "used": 0, "outlier": 0}
    for step in range(start, min(start + 150, T)):
        t = np.full(B, step)
        t[::3] = np.minimum(step + 5, T - 1)  # episodes at different steps, as after autoresets
        mc, mr = platform.step_models(ep_c, t), reference.step_models(ep_r, t)
        np.testing.assert_array_equal(mc.mask, mr.mask)
        np.testing.assert_array_equal(np.isnan(mc.z), ~mc.mask)
        np.testing.assert_allclose(mc.z[mc.mask], mr.z[mr.mask], rtol=0, atol=1e-6)
        oc, orf = mc.observation, mr.observation
        # rounding of terms of 2e7 m (satellite positions): |d0|^2 relative, E.d0 and N.d0 to
        # 1e-6 m, the Sagnac rows and the constant term far below the 5 m pseudo-range noise
        tol = {"rho0_sq": (1e-13, 0.0), "A": (0.0, 1e-6), "W": (0.0, 1e-15), "c0": (0.0, 1e-9)}
        for f, (rtol, atol) in tol.items():
            np.testing.assert_allclose(getattr(oc, f), getattr(orf, f), rtol=rtol, atol=atol, err_msg=f)
        np.testing.assert_array_equal(oc.R, orf.R)
        for a, b in zip(mc.context, mr.context, strict=True):
            if a is None:  # the v3 context's reported C/N0 (None without the context)
                assert b is None
                continue
            np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-6)
        np.testing.assert_array_equal(mc.transition.transition_matrix, mr.transition.transition_matrix)
        np.testing.assert_array_equal(mc.transition.Q, mr.transition.Q)
        np.testing.assert_array_equal(ep_c.noise_ptr, ep_r.noise_ptr)
        seen["masked"] += int((~mc.mask).sum())
        seen["used"] += int(mc.mask.sum())
        reg = ep.regime[np.arange(B), t + 1]
        seen["outlier"] += int((reg[:, 4] > 0).sum())
    # the windows exercise what they claim: used and masked rows, outlier periods where asked
    assert seen["used"] > 0 and seen["masked"] > 0, seen
    if name == "faults":
        assert seen["outlier"] > 0, seen
    # the compared windows crossed a noise-buffer refill (64 steps)
    assert ep_c.noise_ptr.max() < 64 and not np.array_equal(ep_c.noise_n, ep.noise_n)


def test_measurements_are_the_simulated_ones():
    """The compiled pseudo-ranges minus the clock and troposphere are ranges of real satellites."""
    platform, ep = _pair("fading", {"outage_probability": 0.0, "jamming_probability": 0.0}, B=4)
    t = np.zeros(4, dtype=np.int64)
    m = platform.step_models(copy.deepcopy(ep), t)
    used = m.mask
    assert used.sum(axis=1).min() >= 4
    rho = np.sqrt(m.observation.rho0_sq)  # range from the INS point: within a few km of z
    resid = m.z - rho - 299792458.0 * ep.clock[np.arange(4), 1, 0][:, None]
    assert np.nanmax(np.abs(np.where(used, resid, np.nan))) < 200.0


def test_outside_the_orbit_table_the_reference_path_is_used():
    cache = default_orbit_cache()
    assert cache.interval_coefficients(np.array([cache.almanac.t_ref[0] + 30 * 86400.0])) is None
    found = cache.interval_coefficients(np.array([float(cache.almanac.t_ref[0])]))
    assert found is not None and found[0].shape[1:] == (cache.almanac.prn.shape[0], 3, 4)
    platform, ep = _pair("fading", {}, B=3)
    far = ep._replace(gps_t0=ep.gps_t0 + 30 * 86400.0)
    t = np.zeros(3, dtype=np.int64)
    m1 = platform.step_models(copy.deepcopy(far), t)
    m2 = replace(platform, compiled=False).step_models(copy.deepcopy(far), t)
    np.testing.assert_array_equal(m1.z, m2.z)


def test_bad_row_count_is_rejected():
    platform, ep = _pair("fading", {}, B=2)
    cache = default_orbit_cache()
    coef, s = cache.interval_coefficients(ep.gps_t0 + 1.0)
    args = (coef, s, cache.step, np.ones(2, dtype=np.int64), ep, cache.almanac.prn, 5.0)
    with pytest.raises(ValueError, match="m must lie"):
        pseudorange_epoch(*args, 0, goad_goodman_coefficients(), TROPO_NOISE_FRACTION)
    with pytest.raises(ValueError, match="m must lie"):
        pseudorange_epoch(*args, 40, goad_goodman_coefficients(), TROPO_NOISE_FRACTION)
