import numpy as np
import pytest

from navgym.gnss import read_rinex_nav, read_rinex_obs
from navgym.gnss.gpstime import gps_seconds_from_datetime

from .conftest import NAV_FILE, OBS_FILE


def test_nav_header_and_records(nav):
    eph = nav.ephemeris
    assert eph.prn.shape == (162,)
    np.testing.assert_allclose(nav.ion_alpha, [1.118e-8, 1.49e-8, -5.96e-8, -5.96e-8])
    np.testing.assert_allclose(nav.ion_beta, [8.806e4, 1.638e4, -1.966e5, -1.311e5])
    # First record: PRN 1, toc 2005-04-02 02:00:00, af0 = 3.96659597754e-4.
    assert eph.prn[0] == 1
    assert eph.toc[0] == gps_seconds_from_datetime(2005, 4, 2, 2, 0, 0.0)
    assert eph.af0[0] == pytest.approx(3.96659597754e-4, rel=1e-12)
    assert eph.sqrt_a[0] == pytest.approx(5153.63647842, rel=1e-12)
    assert eph.week[0] == 1316 and eph.toe_sow[0] == 525600.0
    assert eph.tgd[0] == pytest.approx(-3.25962901115e-9)
    assert np.all(eph.toe == eph.week * 604800.0 + eph.toe_sow)


def test_obs_header_and_epochs(obs):
    np.testing.assert_allclose(obs.approx_position, [-3976219.5082, 3382372.5671, 3652512.9849])
    assert obs.obs_types == ("L1", "C1", "L2", "P2")
    assert obs.time.shape == (120,)
    t0 = gps_seconds_from_datetime(2005, 4, 2)
    assert obs.time[0] == t0 and obs.time[1] == t0 + 30.0
    assert obs.prn[0].tolist()[:8] == [3, 7, 8, 11, 19, 20, 24, 28]
    c1 = obs.observable("C1")
    assert c1[0, 0] == 24767686.375 and c1[0, 3] == 20311445.258
    assert np.all(np.isnan(c1[obs.prn == 0]))
    with pytest.raises(ValueError, match="name"):
        obs.observable("D1")


def _head(path, n):
    if not path.is_file():
        pytest.skip(f"real data file {path} is absent")
    return path.read_text().splitlines(keepends=True)[:n]


def _write(tmp_path, lines, name):
    f = tmp_path / name
    f.write_text("".join(lines))
    return f


@pytest.mark.parametrize(
    ("line_no", "edit", "what"),
    [
        (15, lambda s: s[:22] + "   5.153xD+03" + s[35:], "bad number"),
        (13, lambda s: "XX" + s[2:], "bad PRN/epoch"),
        (13, lambda s: "40" + s[2:], "PRN 40"),
        (1, lambda s: s.replace("RINEX VERSION / TYPE", "RINEX VERSION"), "not a RINEX"),
        (1, lambda s: "     3.02" + s[9:], "not 2.x"),
        (15, lambda s: s[:60] + "   1.0D+01\n", "implausible sqrt_a"),
    ],
)
def test_malformed_nav_names_file_and_line(tmp_path, line_no, edit, what):
    lines = _head(NAV_FILE, 20)
    lines[line_no - 1] = edit(lines[line_no - 1])
    f = _write(tmp_path, lines, "bad.05n")
    with pytest.raises(ValueError, match=rf"bad\.05n: line {line_no}: .*{what}"):
        read_rinex_nav(f)


def test_truncated_nav_record(tmp_path):
    f = _write(tmp_path, _head(NAV_FILE, 17), "short.05n")
    with pytest.raises(ValueError, match=r"short\.05n: line 13: truncated"):
        read_rinex_nav(f)


def test_obs_file_given_to_nav_reader(tmp_path):
    f = _write(tmp_path, _head(OBS_FILE, 26), "o.05o")
    with pytest.raises(ValueError, match=r"o\.05o: line 1: file type 'O' is not 'N'"):
        read_rinex_nav(f)


@pytest.mark.parametrize(
    ("line_no", "edit", "what"),
    [
        (18, lambda s: s[:10] + "x" + s[11:], "bad epoch line"),
        (20, lambda s: "  -6911x7.898" + s[13:], "bad number"),
        (9, lambda s: s.replace("APPROX POSITION XYZ", "APPROX POS"), "APPROX POSITION"),
    ],
)
def test_malformed_obs_names_file_and_line(tmp_path, line_no, edit, what):
    lines = _head(OBS_FILE, 26)
    lines[line_no - 1] = edit(lines[line_no - 1])
    f = _write(tmp_path, lines, "bad.05o")
    expected_line = 17 if what == "APPROX POSITION" else line_no
    with pytest.raises(ValueError, match=rf"bad\.05o: line {expected_line}: .*{what}"):
        read_rinex_obs(f)


def test_truncated_obs_record(tmp_path):
    f = _write(tmp_path, _head(OBS_FILE, 22), "short.05o")
    with pytest.raises(ValueError, match=r"short\.05o: line 23: truncated"):
        read_rinex_obs(f)


def _rinex_obs_with_events(tmp_path, flag: int, event_lines: list[str]) -> str:
    """A RINEX 2.11 file with 6 observation types (two lines per satellite) and one event."""

    def hdr(label, body=""):
        return f"{body:<60}{label}\n"

    text = hdr("RINEX VERSION / TYPE", "     2.11           OBSERVATION DATA    G (GPS)")
    text += hdr("APPROX POSITION XYZ", f"{-3976219.5082:14.4f}{3382372.5671:14.4f}{3652512.9849:14.4f}")
    text += hdr("# / TYPES OF OBSERV", "     6    L1    C1    L2    P2    S1    S2")
    text += hdr("END OF HEADER")

    def epoch(sec, fl, sats):
        return f" 05  4  2  0  0{sec:11.7f}  {fl:1d}{len(sats):3d}" + "".join(sats) + "\n"

    def sat(vals):
        return (
            "".join(f"{v:14.3f}  " for v in vals[:5])
            + "\n"
            + "".join(f"{v:14.3f}  " for v in vals[5:])
            + "\n"
        )

    text += epoch(0.0, 0, ["G05", "G10"]) + sat([1, 2e7 + 1, 3, 4, 5, 6]) + sat([1, 2e7 + 2, 3, 4, 5, 6])
    text += "".join(event_lines)
    text += epoch(30.0, 0, ["G05", "G10"]) + sat([1, 2e7 + 3, 3, 4, 5, 6]) + sat([1, 2e7 + 4, 3, 4, 5, 6])
    path = tmp_path / f"flag{flag}.05o"
    path.write_text(text)
    return str(path)


def test_cycle_slip_records_are_skipped_in_the_observation_format(tmp_path):
    """Flag 6 (RINEX 2.11 Table A2): a satellite list, then records like observations."""
    slip = " 05  4  2  0  0 30.0000000  6  2G05G10\n" + ("    1.000           0.000  \n" * 4)
    o = read_rinex_obs(_rinex_obs_with_events(tmp_path, 6, [slip]))
    np.testing.assert_array_equal(o.time - o.time[0], [0.0, 30.0])
    np.testing.assert_array_equal(o.observable("C1"), [[2e7 + 1, 2e7 + 2], [2e7 + 3, 2e7 + 4]])


def test_event_records_with_special_lines_are_skipped(tmp_path):
    comment = "                            4  1\n" + f"{'a comment':<60}COMMENT\n"
    o = read_rinex_obs(_rinex_obs_with_events(tmp_path, 4, [comment]))
    np.testing.assert_array_equal(o.time - o.time[0], [0.0, 30.0])


def test_an_epoch_flag_outside_0_to_6_names_file_and_line(tmp_path):
    bad = " 05  4  2  0  0 15.0000000  7  0\n"
    with pytest.raises(ValueError, match=r"flag7\.05o: line \d+: epoch flag 7"):
        read_rinex_obs(_rinex_obs_with_events(tmp_path, 7, [bad]))
