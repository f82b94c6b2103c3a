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


# --- Fortran numbers without the exponent letter -------------------------------------------------
#
# Fortran's Dw.d output drops the exponent letter when the exponent needs three digits, so a real
# IGS file (brdc3050.12n, line 320) carries ``0.499063314480-269`` in a spare field; georinex
# reads all of its 423 records. The file is not available offline: these tests put the same text
# into the spare fields of valid records and require every returned field to equal georinex's.

#: The spare-field text of brdc3050.12n, line 320 (D19.12 with a three-digit exponent).
FORTRAN_SPARE = " 0.499063314480-269"


def _d19(x: float) -> str:
    """One D19.12 field as RINEX 2 writers format it."""
    return f"{x:19.12E}".replace("E", "D")


def _assert_nav_equals_georinex(nav, ref) -> None:
    eph = nav.ephemeris
    toc = _gps_seconds(ref["time"].values)
    sv = list(ref["sv"].values)
    assert eph.prn.size == int(np.isfinite(ref["sqrtA"].values).sum())
    for r in range(eph.prn.size):
        i = int(np.flatnonzero(np.abs(toc - eph.toc[r]) < 1e-3)[0])
        j = sv.index(f"G{int(eph.prn[r]):02d}")
        for ours, theirs in NAV_FIELDS.items():
            assert getattr(eph, ours)[r] == ref[theirs].values[i, j], (r, ours)


def test_spare_field_without_exponent_letter_hand_written_record_equals_georinex(tmp_path):
    """A RINEX 2.11 navigation file written by hand (Table A4 layout), spares as in brdc3050.12n."""
    from navgym.gnss import read_rinex_nav

    def hdr(label, body=""):
        return f"{body:<60}{label}\n"

    text = hdr("RINEX VERSION / TYPE", "     2.11           N: GPS NAV DATA")
    text += hdr("ION ALPHA", "    0.1118D-07  0.1490D-07 -0.5960D-07 -0.5960D-07")
    text += hdr("ION BETA", "    0.8806D+05  0.1638D+05 -0.1966D+06 -0.1311D+06")
    text += hdr("END OF HEADER")
    for prn, hour, sqrt_a in ((5, 2, 5153.63647842), (17, 4, 5153.71234567)):
        text += (
            f"{prn:2d} 12 10 31 {hour:2d}  0  0.0"
            + "".join(_d19(v) for v in (-1.23456789012e-4, 3.41060513165e-13, 0.0))
            + "\n"
        )
        orbit = [
            (17.0, -52.1875, 4.02659638965e-9, 2.87153499034),
            (-2.67662107944e-6, 5.95761800651e-3, 4.17418777943e-6, sqrt_a),
            (hour * 3600.0 + 345600.0, 1.06170773506e-7, -2.49318481774, -9.31322574615e-8),
            (0.983391914449, 309.375, -1.65049681327, -7.88997134293e-9),
            (-8.5717856424e-12, 1.0, 1712.0, 0.0),
            (2.0, 0.0, -1.11758708954e-8, 17.0),
        ]
        text += "".join("   " + "".join(_d19(v) for v in line) + "\n" for line in orbit)
        text += "   " + _d19(hour * 3600.0 + 338400.0) + _d19(4.0) + FORTRAN_SPARE + FORTRAN_SPARE + "\n"
    f = tmp_path / "brdc3050.12n"
    f.write_text(text)
    nav = read_rinex_nav(f)
    assert nav.ephemeris.prn.tolist() == [5, 17]
    _assert_nav_equals_georinex(nav, gr.load(f))
    np.testing.assert_array_equal(
        np.concatenate([nav.ion_alpha, nav.ion_beta]), gr.load(f).attrs["ionospheric_corr_GPS"]
    )


def test_spare_field_without_exponent_letter_in_real_records_equals_georinex(tmp_path):
    """The first three records of the real GEONET file, spares of record 2 as in brdc3050.12n."""
    from navgym.gnss import read_rinex_nav

    lines = _require(NAV_FILE).read_text().splitlines(keepends=True)[: 12 + 3 * 8]
    clean = tmp_path / "clean.05n"
    clean.write_text("".join(lines))
    orbit7 = 12 + 8 + 7  # index of record 2's BROADCAST ORBIT - 7 line (transmission time only)
    ttm = lines[orbit7].rstrip("\n")[:22]
    lines[orbit7] = ttm + _d19(0.0) + FORTRAN_SPARE + FORTRAN_SPARE + "\n"
    f = tmp_path / "spare.05n"
    f.write_text("".join(lines))
    nav = read_rinex_nav(f)
    _assert_nav_equals_georinex(nav, gr.load(f))
    for a, b in zip(nav.ephemeris, read_rinex_nav(clean).ephemeris, strict=True):
        np.testing.assert_array_equal(a, b)
