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
        (
            15,
            lambda s: s[:22] + "   5.153xD+03" + s[35:],
            "e field '   5.153xD\\+0310D-03': the field's text",
        ),
        (13, lambda s: "XX" + s[2:], "bad PRN field 'XX'"),
        (13, lambda s: "40" + s[2:], "PRN 40"),
        (1, lambda s: s.replace("RINEX VERSION / TYPE", "RINEX VERSION"), "not a RINEX"),
        (1, lambda s: "     3.02" + s[9:], "not 2.x"),
        (15, lambda s: s[:60] + " 1.000000000000D+01\n", "sqrt_a 10.0 is outside its physical range"),
    ],
)
def test_malformed_nav_names_file_and_line(tmp_path, line_no, edit, what):
    lines = _head(NAV_FILE, 20)
    lines[line_no - 1] = edit(lines[line_no - 1])
    f = _write(tmp_path, lines, "bad.05n")
    with pytest.raises(ValueError, match=rf"bad\.05n: line {line_no}: .*{what}.*; expected \S"):
        read_rinex_nav(f)


def test_truncated_nav_record(tmp_path):
    f = _write(tmp_path, _head(NAV_FILE, 17), "short.05n")
    with pytest.raises(ValueError, match=r"short\.05n: line 13: truncated.*; expected \S"):
        read_rinex_nav(f)


def test_obs_file_given_to_nav_reader(tmp_path):
    f = _write(tmp_path, _head(OBS_FILE, 26), "o.05o")
    with pytest.raises(ValueError, match=r"o\.05o: line 1: file type 'O' is not 'N'; expected 'N'"):
        read_rinex_nav(f)


@pytest.mark.parametrize(
    ("line_no", "edit", "what"),
    [
        (18, lambda s: s[:10] + "x" + s[11:], "bad epoch line"),
        (20, lambda s: "  -6911x7.898" + s[13:], "L1 field '  -6911x7.8988'"),
        (9, lambda s: s.replace("APPROX POSITION XYZ", "APPROX POS"), "APPROX POSITION"),
    ],
)
def test_malformed_obs_names_file_and_line(tmp_path, line_no, edit, what):
    lines = _head(OBS_FILE, 26)
    lines[line_no - 1] = edit(lines[line_no - 1])
    f = _write(tmp_path, lines, "bad.05o")
    expected_line = 17 if what == "APPROX POSITION" else line_no
    with pytest.raises(ValueError, match=rf"bad\.05o: line {expected_line}: .*{what}.*; expected \S"):
        read_rinex_obs(f)


def test_truncated_obs_record(tmp_path):
    f = _write(tmp_path, _head(OBS_FILE, 22), "short.05o")
    with pytest.raises(ValueError, match=r"short\.05o: line 23: truncated.*; expected \S"):
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
    slip = " 05  4  2  0  0 30.0000000  6  2G05G10\n" + (f"{1.0:14.3f}  {0.0:14.3f}\n" + f"{0.0:14.3f}\n") * 2
    o = read_rinex_obs(_rinex_obs_with_events(tmp_path, 6, [slip]))
    np.testing.assert_array_equal(o.time - o.time[0], [0.0, 30.0])
    np.testing.assert_array_equal(o.observable("C1"), [[2e7 + 1, 2e7 + 2], [2e7 + 3, 2e7 + 4]])


def test_event_records_with_special_lines_are_skipped(tmp_path):
    comment = "                            4  1\n" + f"{'a comment':<60}COMMENT\n"
    o = read_rinex_obs(_rinex_obs_with_events(tmp_path, 4, [comment]))
    np.testing.assert_array_equal(o.time - o.time[0], [0.0, 30.0])


def test_an_epoch_flag_outside_0_to_6_names_file_and_line(tmp_path):
    bad = " 05  4  2  0  0 15.0000000  7  0\n"
    with pytest.raises(ValueError, match=r"flag7\.05o: line \d+: epoch flag 7.*; expected \S"):
        read_rinex_obs(_rinex_obs_with_events(tmp_path, 7, [bad]))


# --- numbers as Fortran writes them; fields the reader does not use ------------------------------


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("0.499063314480-269", 0.499063314480e-269),  # brdc3050.12n line 320: no exponent letter
        ("-0.123456789012+100", -0.123456789012e100),
        ("  5.153636478420D+03", 5153.636478420),
        ("-.839701388031D-03", -0.839701388031e-3),
        ("1.0d+01", 10.0),
        ("0.1118E-07", 0.1118e-7),
        ("  30.0000000", 30.0),
        ("+7", 7.0),
        ("", 0.0),
        ("                   ", 0.0),
    ],
)
def test_fortran_reals(text, value):
    from navgym.gnss.rinex_fields import _fortran_real

    assert _fortran_real(text) == value


@pytest.mark.parametrize("text", ["5.153xD+03", "1.0D", "1.0-", "D+03", "nan", "1.0D+0 3", "1,5"])
def test_fortran_reals_reject_malformed_text(text):
    from navgym.gnss.rinex_fields import _fortran_real

    with pytest.raises(ValueError, match="not a Fortran real"):
        _fortran_real(text)


def _nav_head(n_records):
    return _head(NAV_FILE, 12 + 8 * n_records)


def _orbit_field(line, k, text):
    """Line ``line`` with broadcast-orbit field ``k`` (0-3, columns 4+19k to 22+19k) set to text."""
    body = line.rstrip("\n").ljust(79)
    return body[: 3 + 19 * k] + f"{text:>19}" + body[22 + 19 * k :] + "\n"


def test_used_fields_may_drop_the_exponent_letter(tmp_path):
    """A three-digit exponent without its letter is read wherever a number is read."""
    lines = _nav_head(1)
    lines[12] = lines[12][:60] + "-0.123456789012-100\n"  # a_f2 of record 1
    lines[14] = _orbit_field(lines[14], 1, "0.595761800651-002")  # e, exponent letter dropped
    eph = read_rinex_nav(_write(tmp_path, lines, "nav.05n")).ephemeris
    assert eph.af2[0] == -0.123456789012e-100
    assert eph.e[0] == 5.95761800651e-3


def test_unused_fields_never_fail_a_read(tmp_path):
    """L2 codes, L2 P flag, transmission time, fit interval and spares are skipped unparsed."""
    clean = read_rinex_nav(_write(tmp_path, _nav_head(2), "clean.05n")).ephemeris
    lines = _nav_head(2)
    lines[17] = _orbit_field(_orbit_field(lines[17], 1, "L2 codes?"), 3, "****")  # orbit 5
    lines[19] = "   " + "garbage".rjust(19) + "n/a".rjust(19) + " 0.499063314480-269" + "?" * 19 + "\n"
    lines[27] = "   \n"  # orbit 7 of record 2: blank (only spare and unused fields)
    eph = read_rinex_nav(_write(tmp_path, lines, "unused.05n")).ephemeris
    for a, b in zip(eph, clean, strict=True):
        np.testing.assert_array_equal(a, b)


def test_blank_used_fields_read_as_zero(tmp_path):
    """RINEX: a value not known may be written as zero or blank."""
    lines = _nav_head(1)
    lines[12] = lines[12][:60] + " " * 19 + "\n"  # a_f2 blank
    lines[18] = _orbit_field(lines[18], 2, "")  # tgd blank
    eph = read_rinex_nav(_write(tmp_path, lines, "blank.05n")).ephemeris
    assert eph.af2[0] == 0.0 and eph.tgd[0] == 0.0


# --- observation epochs: satellite lists and time order -----------------------------------------


def _obs_text(epochs) -> str:
    """RINEX 2.11 observation file with 4 types; ``epochs`` = (seconds, flag, satellite ids,
    number announced or None, rows of values or None for the default)."""

    def hdr(label, body=""):
        return f"{body:<60}{label}\n"

    text = hdr("RINEX VERSION / TYPE", "     2.11           OBSERVATION DATA    G (GPS)")
    text += hdr("APPROX POSITION XYZ", f"{-3976219.5082:14.4f}{3382372.5671:14.4f}{3652512.9849:14.4f}")
    text += hdr("# / TYPES OF OBSERV", "     4    L1    C1    L2    P2")
    text += hdr("END OF HEADER")
    for sec, flag, sats, announced, rows in epochs:
        n = len(sats) if announced is None else announced
        ids = "".join(sats)
        text += f" 05  4  2  0  0{sec:11.7f}  {flag:1d}{n:3d}" + ids[:36] + "\n"
        for k in range(36, len(ids), 36):
            text += " " * 32 + ids[k : k + 36] + "\n"
        for s in range(len(sats)) if rows is None else range(rows):
            text += "".join(f"{v:14.3f}  " for v in (1.0, 2e7 + s, 3.0, 4.0)) + "\n"
    return text


def _obs_file(tmp_path, name, epochs):
    f = tmp_path / name
    f.write_text(_obs_text(epochs))
    return f


def test_obs_builder_reads(tmp_path):
    sats = [f"G{p:02d}" for p in range(1, 15)]  # 14 satellites: a continuation line
    o = read_rinex_obs(
        _obs_file(tmp_path, "ok.05o", [(0.0, 0, sats, None, None), (30.0, 0, ["G05"], None, None)])
    )
    np.testing.assert_array_equal(o.time - o.time[0], [0.0, 30.0])
    assert o.prn[0].tolist() == list(range(1, 15)) and o.prn[1].tolist() == [5] + [0] * 13


def test_epoch_announcing_more_satellites_than_listed_names_file_line_and_counts(tmp_path):
    """Was ``IndexError: string index out of range`` with no file or line."""
    f = _obs_file(tmp_path, "few.05o", [(0.0, 0, ["G05", "G10"], 3, 3)])
    with pytest.raises(ValueError, match=r"few\.05o: line 5: .*announces 3 satellites but lists 2; expected"):
        read_rinex_obs(f)


def test_epoch_announcing_a_continuation_line_that_is_not_there(tmp_path):
    sats = [f"G{p:02d}" for p in range(1, 13)]  # 12 listed on the epoch line, 13 announced
    f = _obs_file(tmp_path, "cont.05o", [(0.0, 0, sats, 13, 13)])
    with pytest.raises(ValueError, match=r"cont\.05o: line 6: .*line 5 announces 13 satellites but lists 12"):
        read_rinex_obs(f)


def test_epoch_listing_more_satellites_than_announced(tmp_path):
    f = _obs_file(tmp_path, "many.05o", [(0.0, 0, ["G05", "G10"], 1, 1)])
    with pytest.raises(ValueError, match=r"many\.05o: line 5: .*announces 1 satellites but lists more"):
        read_rinex_obs(f)


def test_bad_satellite_id_names_its_line(tmp_path):
    sats = [f"G{p:02d}" for p in range(1, 14)]
    sats[12] = "G1x"  # on the continuation line
    f = _obs_file(tmp_path, "id.05o", [(0.0, 0, sats, None, None)])
    with pytest.raises(ValueError, match=r"id\.05o: line 6: bad satellite id 'G1x'; expected"):
        read_rinex_obs(f)


@pytest.mark.parametrize("first, second", [("G20", "G20"), ("G20", " 20"), (" 20", "G20")])
def test_satellite_listed_twice_in_one_epoch_names_file_line_and_both_ids(tmp_path, first, second):
    """Was read silently: two rows for one satellite at one epoch (a blank letter is GPS)."""
    sats = [f"G{p:02d}" for p in range(1, 14)]
    sats[3], sats[12] = first, second  # the repeat on the continuation line
    f = _obs_file(tmp_path, "twice.05o", [(0.0, 0, sats, None, None)])
    pattern = rf"twice\.05o: line 6: the epoch record of line 5 lists satellite '{second}' twice"
    pattern += rf" \(also as '{first}'\)"
    with pytest.raises(ValueError, match=pattern):
        read_rinex_obs(f)


def test_other_systems_may_share_a_prn_with_gps(tmp_path):
    o = read_rinex_obs(_obs_file(tmp_path, "mixed.05o", [(0.0, 0, ["G05", "R05"], None, None)]))
    assert o.prn[0].tolist() == [5]


def test_epoch_without_satellites_is_read(tmp_path):
    """An epoch announcing 0 satellites spans its epoch line (the reader looped on it forever)."""
    import signal

    def timeout(*_):
        raise TimeoutError("read_rinex_obs did not return")

    old = signal.signal(signal.SIGALRM, timeout)
    signal.alarm(10)
    try:
        o = read_rinex_obs(
            _obs_file(tmp_path, "empty.05o", [(0.0, 0, [], None, None), (30.0, 0, ["G05"], None, None)])
        )
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    assert o.prn.tolist() == [[0], [5]]


def test_epochs_out_of_time_order_name_file_line_and_both_times(tmp_path):
    f = _obs_file(
        tmp_path,
        "order.05o",
        [(0.0, 0, ["G05"], None, None), (30.0, 0, ["G05"], None, None), (15.0, 0, ["G05"], None, None)],
    )
    with pytest.raises(
        ValueError,
        match=r"order\.05o: line 9: epoch 2005-04-02 00:00:15\.0000000 is not after the previous epoch "
        r"2005-04-02 00:00:30\.0000000 \(line 7\); expected .*increasing time order",
    ):
        read_rinex_obs(f)


def test_repeated_epoch_time_tag_is_rejected(tmp_path):
    f = _obs_file(tmp_path, "dup.05o", [(30.0, 0, ["G05"], None, None), (30.0, 1, ["G07"], None, None)])
    with pytest.raises(
        ValueError, match=r"dup\.05o: line 7: epoch 2005-04-02 00:00:30\.0000000 is not after"
    ):
        read_rinex_obs(f)


def test_event_records_may_repeat_or_precede_observation_times(tmp_path):
    """RINEX 3.04 §6.5 excepts event records from the time order; the slips come in obs format."""
    event = (10.0, 5, [], 0, 0)  # external event, earlier than the epoch before it
    slips = (30.0, 6, ["G05"], None, None)  # cycle slips at the time of the epoch before them
    o = read_rinex_obs(
        _obs_file(
            tmp_path, "ev.05o", [(30.0, 0, ["G05"], None, None), event, slips, (50.0, 0, ["G05"], None, None)]
        )
    )
    np.testing.assert_array_equal(o.time - o.time[0], [0.0, 20.0])


def test_real_observation_file_is_in_time_order(obs):
    assert np.all(np.diff(obs.time) > 0)
