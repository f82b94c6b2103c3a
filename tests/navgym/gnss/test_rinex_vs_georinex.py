"""navgym's RINEX 2 readers against georinex, an established reader, on the real GEONET files.

Every navigation record field and every observation value that both readers return must agree
exactly (both parse the same decimal text into float64), which checks the record layout, the
``D`` exponents, the epoch times and the satellite slots of :mod:`navgym.gnss.rinex`
independently of the SPP validation (``test_ephemeris_spp.py``). Satellite positions are not
compared: georinex's ``keplerian2ecef`` solves Kepler's equation with one fixed-point step
(errors of kilometres), so it is no reference for :func:`navgym.gnss.ephemeris_orbit`.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.navgym.gnss.conftest import NAV_FILE, OBS_FILE, _require

gr = pytest.importorskip("georinex")

# georinex 1.16 merges its per-satellite arrays with xarray's current default join
pytestmark = pytest.mark.filterwarnings("ignore:In a future version of xarray:FutureWarning")

#: navgym BroadcastEphemeris field -> georinex variable (RINEX 2 navigation record order).
NAV_FIELDS = {
    "af0": "SVclockBias",
    "af1": "SVclockDrift",
    "af2": "SVclockDriftRate",
    "iode": "IODE",
    "crs": "Crs",
    "delta_n": "DeltaN",
    "m0": "M0",
    "cuc": "Cuc",
    "e": "Eccentricity",
    "cus": "Cus",
    "sqrt_a": "sqrtA",
    "toe_sow": "Toe",
    "cic": "Cic",
    "omega0": "Omega0",
    "cis": "Cis",
    "i0": "Io",
    "crc": "Crc",
    "omega": "omega",
    "omega_dot": "OmegaDot",
    "idot": "IDOT",
    "week": "GPSWeek",
    "sv_accuracy": "SVacc",
    "health": "health",
    "tgd": "TGD",
    "iodc": "IODC",
}


def _gps_seconds(times: np.ndarray) -> np.ndarray:
    """datetime64 on the GPS time scale (as RINEX 2 GPS files give it) -> GPS seconds."""
    return (times - np.datetime64("1980-01-06T00:00:00")) / np.timedelta64(1, "ns") * 1e-9


def test_navigation_records_equal_georinex(nav):
    ref = gr.load(_require(NAV_FILE))
    eph = nav.ephemeris
    toc = _gps_seconds(ref["time"].values)
    sv = list(ref["sv"].values)
    n_ref = int(np.isfinite(ref["sqrtA"].values).sum())
    assert eph.prn.size == n_ref, (eph.prn.size, n_ref)
    for r in range(eph.prn.size):
        i = int(np.flatnonzero(np.abs(toc - eph.toc[r]) < 1e-3)[0])
        j = sv.index(f"G{int(eph.prn[r]):02d}")
        for ours, theirs in NAV_FIELDS.items():
            assert getattr(eph, ours)[r] == ref[theirs].values[i, j], (r, ours)
    np.testing.assert_array_equal(
        np.concatenate([nav.ion_alpha, nav.ion_beta]), ref.attrs["ionospheric_corr_GPS"]
    )


def test_observations_equal_georinex(obs):
    ref = gr.load(_require(OBS_FILE))
    t_ref = _gps_seconds(ref["time"].values)
    # Epochs agree to float rounding, except that georinex truncates some millisecond seconds
    # fields to the millisecond below: line 399 of the file, "0 21 30.0020000", is
    # 00:21:30.001 there and 00:21:30.002 here (15 of the 120 epochs, all with a fractional
    # second in the file).
    late = obs.time - t_ref
    off = np.abs(late) > 1e-6
    assert off.sum() == 15
    np.testing.assert_allclose(late[off], 1e-3, rtol=0, atol=1e-6)
    assert (obs.time[off] % 1.0 > 1.5e-3).all()
    np.testing.assert_array_equal(obs.approx_position, ref.attrs["position"])
    sv = {s: k for k, s in enumerate(ref["sv"].values)}
    compared = 0
    for name in obs.obs_types:
        ours = obs.observable(name)
        theirs = ref[name].values  # (E, S_ref)
        for e in range(obs.time.size):
            for s in np.flatnonzero(obs.prn[e] > 0):
                k = sv[f"G{int(obs.prn[e, s]):02d}"]
                a, b = ours[e, s], theirs[e, k]
                assert a == b or (np.isnan(a) and np.isnan(b)), (name, e, int(obs.prn[e, s]), a, b)
                compared += np.isfinite(a)
        # and no GPS value of georinex is missing from ours
        seen = np.zeros(theirs.shape, dtype=bool)
        for e in range(obs.time.size):
            for s in np.flatnonzero(obs.prn[e] > 0):
                seen[e, sv[f"G{int(obs.prn[e, s]):02d}"]] = True
        gps = np.array([s.startswith("G") for s in ref["sv"].values])
        assert not (np.isfinite(theirs) & ~seen)[:, gps].any(), name
    assert compared > 1000
