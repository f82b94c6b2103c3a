"""Issue 38, items 5-6: recordings that were accepted silently, or failed late or unclearly.

Every case is a modified copy of the packaged walk_0827 (real data) in ``tmp_path``: a sidecar
key missing or in the wrong unit, a mount that does not turn the sensor onto the body, IMU gaps
and time jumps, a UTC/GPST mix, values out of range, a ``.pos`` without velocities or in UTC,
text that is not UTF-8. Each must be refused with a message naming the file, the 1-based line or
the key, what looks wrong and how to fix it, with plain numbers.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from navgym.recordings.checks import check_recording
from navgym.recordings.loader import (
    G0,
    PACKAGED,
    REQUIRED_IMU_KEYS,
    SIDECAR_RANGES,
    load_recording,
    read_recording,
    read_rtklib_pos,
)

#: First IMU time of the walk [s GPST on the Unix epoch].
T_IMU0 = 1756402240.961


def _walk(tmp_path: Path, name: str = "walk") -> Path:
    d = tmp_path / name
    shutil.copytree(PACKAGED, d)
    for p in d.iterdir():
        p.chmod(0o644)
    return d


def _sidecar(d: Path, old: str, new: str) -> None:
    p = d / "recording.toml"
    text = p.read_text()
    assert old in text, old
    p.write_text(text.replace(old, new))


def _imu(d: Path, edit) -> None:
    p = d / "imu.csv"
    p.write_text("\n".join(edit(p.read_text().splitlines())) + "\n")


def _pos(d: Path, edit) -> None:
    p = d / "gnss.pos"
    p.write_text("\n".join(edit(p.read_text().splitlines())) + "\n")


def _refused(d: Path, pattern: str) -> str:
    """``load_recording(d)`` raises a message matching ``pattern``, with plain numbers."""
    with pytest.raises(ValueError, match=pattern) as info:
        load_recording(d)
    message = str(info.value)
    assert "np.float" not in message and "np.int" not in message and "array(" not in message, message
    return message


def _shift_rows(rows: list[str], first: int, dt: float) -> list[str]:
    out = []
    for i, r in enumerate(rows):
        if i >= first:
            f = r.split(",")
            f[0] = f"{float(f[0]) + dt:.7f}"
            r = ",".join(f)
        out.append(r)
    return out


def _drop_rows(rows: list[str], t0: float, t1: float) -> list[str]:
    return [r for r in rows if not t0 <= float(r.split(",")[0]) - T_IMU0 < t1]


def _pos_field(rows: list[str], line: int, column: int, text: str) -> list[str]:
    out = list(rows)
    f = out[line - 1].split()
    f[column] = text
    out[line - 1] = " ".join(f)
    return out


# --- the packaged walk ---------------------------------------------------------------------------


def test_the_packaged_walk_passes_every_check():
    rec, sources = read_recording()
    check = check_recording(rec, sources)
    assert check.problems == ()
    assert check.imu_gaps == () and check.gnss_missing_epochs == 0
    assert check.mount_residual_deg < 3.0 and check.still_s > 20.0
    assert check.heading is not None
    assert 0.7 < check.heading.gyro_scale < 1.1 and abs(check.heading.lag_s) < 0.5
    assert check.heading.correlation > 0.85


# --- item 5: silently accepted -------------------------------------------------------------------


@pytest.mark.parametrize("key", sorted(REQUIRED_IMU_KEYS))
def test_a_missing_physical_key_is_refused_not_defaulted(tmp_path, key):
    d = _walk(tmp_path)
    text = (d / "recording.toml").read_text()
    (d / "recording.toml").write_text(re.sub(rf"(?m)^{key} = .*\n", "", text))
    _refused(
        d,
        rf"recording\.toml: \[imu\] lacks the required key\(s\) \['{key}'\] \(no default is right for every "
        rf"recording\): {key}: .*; see docs/recordings\.md",
    )


def test_a_mount_in_radians_is_refused_with_the_degrees(tmp_path):
    d = _walk(tmp_path)
    _sidecar(d, "[180.0, 0.0, -90.0]", "[3.14159, 0.0, -1.5708]")
    _refused(
        d,
        r"mount: the specific force while still \([\d.]+ s\) points 175\.\d deg from the body's up axis .*"
        r"the sensor's \+z axis points up.*the angles look like radians: in degrees they are "
        r"\[180\.0, 0\.0, -90\.0\]",
    )


def test_the_180_deg_roll_dropped_is_refused(tmp_path):
    d = _walk(tmp_path)
    _sidecar(d, "[180.0, 0.0, -90.0]", "[0.0, 0.0, -90.0]")
    message = _refused(
        d, r"mount: the specific force while still .* points 178\.\d deg from the body's up axis"
    )
    assert "radians" not in message


def test_gyro_unit_deg_s_on_rad_s_data_is_refused(tmp_path):
    d = _walk(tmp_path)
    _sidecar(d, 'gyro_unit = "rad/s"', 'gyro_unit = "deg/s"')
    _refused(
        d,
        r"gyro: the rates about the vertical are 0\.01\d+ times the GNSS heading rate \(expected about 1, "
        r'0\.5-2\.0\) \(they look like rad/s read as deg/s: gyro_unit = "deg/s" should be "rad/s"\)',
    )


def test_gyro_unit_rad_s_on_deg_s_data_is_refused(tmp_path):
    d = _walk(tmp_path)

    def to_deg(rows):
        out = []
        for r in rows:
            f = r.split(",")
            f[4:7] = [f"{np.rad2deg(float(x)):.7f}" for x in f[4:7]]
            out.append(",".join(f))
        return out

    _imu(d, to_deg)
    _refused(
        d,
        r"imu\.csv: line \d+: angular rate -?\d+\.?\d* rad/s \(columns 4-6, after the unit\) is beyond "
        r'any IMU.s range .*\(if the whole file is in deg/s: set gyro_unit = "deg/s"\)',
    )
    _sidecar(d, 'gyro_unit = "rad/s"', 'gyro_unit = "deg/s"')
    assert load_recording(d).imu.gyro.shape == (20455, 3)


@pytest.mark.parametrize(("start", "length"), [(50.0, 2.0), (30.0, 60.0)])
def test_an_imu_gap_is_refused_naming_both_lines(tmp_path, start, length):
    """Was bridged by linear interpolation; every window over it was wrong."""
    d = _walk(tmp_path)
    _imu(d, lambda rows: _drop_rows(rows, start, start + length))
    _refused(
        d,
        rf"IMU gap: imu\.csv jumps {length:.0f}\.0\d\d s from line (\d+) \([\d.]+ s GPST\) to line (\d+) "
        r"\([\d.]+ s\): lost samples or a jump of the timestamps .* split the recording into two directories",
    )


def test_imu_timestamps_jumping_forward_are_refused(tmp_path):
    d = _walk(tmp_path)
    _imu(d, lambda rows: _shift_rows(rows, 10000, 5.0))
    _refused(d, r"IMU gap: imu\.csv jumps 5\.00\d s from line 10000 \(1756402306\.792 s GPST\) to line 10001")


def test_a_utc_gpst_mix_in_the_time_offset_is_refused(tmp_path):
    d = _walk(tmp_path)
    _sidecar(d, "time_offset_s = 0.0", "time_offset_s = 18.0")
    _refused(
        d,
        r"time: the IMU's turns match the GNSS heading rate 18\.\d\d s later \(correlation 0\.9\d\): "
        r"time_offset_s = 18 looks off by about that much \(try about -0\.\d;.*A UTC/GPST mix is off by the "
        r"leap seconds, 18 s since 2017; time_offset_s is in seconds, not ms",
    )


@pytest.mark.parametrize("offset", [1.5, -3.0, 50.0])
def test_a_time_offset_off_by_seconds_is_refused(tmp_path, offset):
    d = _walk(tmp_path)
    _sidecar(d, "time_offset_s = 0.0", f"time_offset_s = {offset}")
    later = "later" if offset > 0 else "earlier"
    message = _refused(d, rf"time: the IMU's turns match the GNSS heading rate \d+\.\d\d s {later}")
    lag = float(re.search(r"heading rate (\d+\.\d\d) s", message).group(1))
    assert lag == pytest.approx(abs(offset + 0.3), abs=0.1)  # the walk's GNSS velocity lags by 0.3 s


def test_a_gyro_that_follows_no_heading_is_refused(tmp_path):
    d = _walk(tmp_path)
    rng = np.random.default_rng(0)

    def noise(rows):
        out = []
        for r in rows:
            f = r.split(",")
            f[4:7] = [f"{x:.7f}" for x in rng.normal(0.0, 0.5, 3)]
            out.append(",".join(f))
        return out

    _imu(d, noise)
    _refused(
        d,
        r"gyro: the recording turns \(RMS heading rate [\d.]+ rad/s over \d+ epochs\) but the gyro's rate "
        r"about the vertical follows the GNSS heading rate at no time lag within 67 s",
    )


def test_a_time_offset_in_ms_is_refused(tmp_path):
    d = _walk(tmp_path)
    _sidecar(d, "time_offset_s = 0.0", "time_offset_s = 300.0")  # 0.3 s written in ms
    _refused(d, r"do not overlap in time \(check time_offset_s: seconds added to the IMU times to get GPST\)")


def test_a_lever_arm_in_cm_is_refused(tmp_path):
    d = _walk(tmp_path)
    _sidecar(d, "lever_arm_m = [0.0, -0.05, 0.0]", "lever_arm_m = [0.0, -5.0, 0.0]")
    _refused(
        d,
        r"recording\.toml: lever_arm_m = \[0, -5, 0\] is 5 m long, more than 3 m: the lever arm is in metres",
    )


@pytest.mark.parametrize(
    ("column", "text", "message"),
    [
        (3, "400.0000000", r"longitude 400 deg outside \[-180, 180\]"),
        (2, "-95.0000000", r"latitude -95 deg outside \[-90, 90\]"),
        (4, "1601435.0", r"height 1601435 m outside \[-1000, 50000\]"),
        (5, "1.5000000", r"Q 1\.5 is not one of RTKLIB's flags 1-6 \(an integer"),
        (5, "-1.0000000", r"Q -1 is not one of RTKLIB's flags 1-6"),
        (5, "7", r"Q 7 is not one of RTKLIB's flags 1-6"),
        (5, "nan", r"Q is not a finite number"),
        (7, "-0.0098995", r"a standard deviation sdn/sde/sdu is negative or infinite"),
        (15, "1e30", r"a velocity vn/ve/vu is not finite or beyond 200 m/s"),
    ],
)
def test_pos_values_out_of_range_are_refused_naming_the_line(tmp_path, column, text, message):
    """Q 1.5 became an RTK-fixed truth epoch; longitude 400 was accepted."""
    d = _walk(tmp_path)
    _pos(d, lambda rows: _pos_field(rows, 31, column, text))
    _refused(d, rf"gnss\.pos: line 31: {message}")


@pytest.mark.parametrize(("value", "column"), [("1e30", 1), ("-1e30", 5), ("nan", 2), ("inf", 6)])
def test_an_imu_sample_out_of_range_is_refused_naming_the_line(tmp_path, value, column):
    """A 1e30 sample made every episode end at step 1."""
    d = _walk(tmp_path)

    def edit(rows):
        f = rows[499].split(",")
        f[column] = value
        rows[499] = ",".join(f)
        return rows

    _imu(d, edit)
    if value in ("nan", "inf"):
        _refused(d, r"imu\.csv: line 500: non-finite specific force or angular rate")
    else:
        _refused(
            d, r"imu\.csv: line 500: (specific force|angular rate) -?\d.*e\+30 .* is beyond any IMU's range"
        )


@pytest.mark.parametrize("key", sorted(SIDECAR_RANGES))
@pytest.mark.parametrize("value", ["1e30", "-1.0"])
def test_a_noise_figure_or_yaw_out_of_range_is_refused(tmp_path, key, value):
    d = _walk(tmp_path)
    text = (d / "recording.toml").read_text()
    (d / "recording.toml").write_text(re.sub(rf"(?m)^{key} = .*$", f"{key} = {value}", text))
    lo, _, _ = SIDECAR_RANGES[key]
    shown = {"1e30": r"1e\+30", "-1.0": "-1"}[value]
    if value == "-1.0" and lo < 0:
        load_recording(d)  # a heading of -1 deg is fine
        return
    _refused(
        d,
        rf"recording\.toml: {key} = {shown} is not plausible: expected",
    )


@pytest.mark.parametrize("value", ["[1.5]", "[7]", "[]", "[true]"])
def test_q_flags_in_the_sidecar_are_integers_1_to_6(tmp_path, value):
    d = _walk(tmp_path)
    _sidecar(d, "truth_q = [1]", f"truth_q = {value}")
    _refused(d, r"recording\.toml: truth_q must be a non-empty list of RTKLIB Q flags, integers 1-6")


def test_a_gyro_turning_the_wrong_way_is_refused(tmp_path):
    d = _walk(tmp_path)

    def flip(rows):
        out = []
        for r in rows:
            f = r.split(",")
            f[4:7] = [f"{-float(x):.7f}" for x in f[4:7]]
            out.append(",".join(f))
        return out

    _imu(d, flip)
    _refused(d, r"gyro: the rate about the vertical turns against the GNSS heading \(correlation -0\.9\d\)")


def test_a_gnss_epoch_off_the_grid_is_refused_naming_the_line(tmp_path):
    d = _walk(tmp_path)
    _pos(d, lambda rows: [r.replace("17:30:46.999", "17:30:47.099") for r in rows])
    _refused(d, r"GNSS epochs: line 31 of gnss\.pos \([\d.]+ s GPST\) is 0\.100 s off the grid of the median")


def test_every_problem_is_listed_at_once(tmp_path):
    d = _walk(tmp_path)
    _sidecar(d, "[180.0, 0.0, -90.0]", "[0.0, 0.0, -90.0]")
    _imu(d, lambda rows: _drop_rows(rows, 50.0, 52.0))
    message = _refused(d, r"the recording looks wrong \(2 problem\(s\); 'navgym recording check .*' prints")
    assert "  - IMU gap" in message and "  - mount" in message


# --- item 6: late or unclear failures ------------------------------------------------------------


def _strip_velocity(rows: list[str]) -> list[str]:
    """The .pos without the vn ve vu columns and their standard deviations (RTKLIB without outvel)."""
    out = []
    for r in rows:
        if r.startswith("%  GPST"):
            names = r[1:].split()
            out.append("% " + " ".join(names[:14]))
        elif r.startswith("%"):
            out.append(r)
        else:
            out.append(" ".join(r.split()[:15]))
    return out


def test_a_pos_without_velocity_columns_derives_the_velocity(tmp_path):
    """Was 'state.m has non-finite entries' at the first step."""
    d = _walk(tmp_path)
    _pos(d, _strip_velocity)
    g = read_rtklib_pos(d / "gnss.pos")
    ref = read_rtklib_pos(PACKAGED / "gnss.pos")
    assert g.velocity_from_positions and not ref.velocity_from_positions
    assert np.isfinite(g.vel_ned).all()
    err = np.linalg.norm(g.vel_ned[:, :2] - ref.vel_ned[:, :2], axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.15, np.sqrt(np.mean(err**2))  # the walk's speed: about 1.2 m/s
    rec = load_recording(d)
    assert rec.gnss.velocity_from_positions


def test_a_pos_without_velocity_columns_replays(tmp_path):
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the ids
    from navgym.scenarios import Scenario

    d = _walk(tmp_path)
    _pos(d, _strip_velocity)
    env = gym.make("navgym/ReplayFading-v2", recording=str(d), episode_steps=40, max_episode_steps=40)
    obs, _ = env.reset(seed=0, options={"scenario": Scenario(duration=10.0)})
    plain = env.unwrapped.core.task.neutral_action().astype(np.float32)
    errs = []
    for _ in range(40):
        obs, _, terminated, _, info = env.step(plain)
        assert np.isfinite(obs).all() and not terminated
        errs.append(float(info["pos_err_m"]))
    assert max(errs) < 1.0


def test_a_pos_one_velocity_column_short_is_refused(tmp_path):
    d = _walk(tmp_path)
    _pos(d, lambda rows: [r.replace("vu(m/s)", "vz(m/s)") for r in rows])
    _refused(d, r"gnss\.pos: velocity columns \['vn\(m/s\)', 've\(m/s\)'\] without \['vu\(m/s\)'\]")


@pytest.mark.parametrize("system", ["UTC", "JST"])
def test_a_utc_pos_is_named_as_such(tmp_path, system):
    """Was 'data before the column header'."""
    d = _walk(tmp_path)
    _pos(d, lambda rows: [r.replace("%  GPST", f"%  {system}", 1) for r in rows])
    _refused(
        d,
        rf"gnss\.pos: line 1: the times are {system} \(column header '% {system} \.\.\.'\); the loader needs "
        r"GPST: rerun RTKLIB with GPST output",
    )


def test_a_nonexistent_directory_says_it_does_not_exist(tmp_path):
    """Was 'no recording.toml sidecar'."""
    _refused(tmp_path / "nowhere", r"nowhere: the recording directory does not exist \(expected a directory")
    (tmp_path / "file").write_text("x")
    _refused(tmp_path / "file", r"file: not a directory")
    _refused(tmp_path, r"no recording\.toml sidecar")


@pytest.mark.parametrize(
    ("name", "offset", "line"), [("imu.csv", 1000, 9), ("gnss.pos", 300, 2), ("recording.toml", 5, 1)]
)
def test_text_that_is_not_utf8_names_the_file_and_line(tmp_path, name, offset, line):
    """Was a bare UnicodeDecodeError."""
    d = _walk(tmp_path)
    data = (d / name).read_bytes()
    (d / name).write_bytes(data[:offset] + b"\xff" + data[offset:])
    _refused(
        d,
        rf"{re.escape(name)}: line {line}: byte 0xff at column \d+ is not UTF-8 text; save the file as UTF-8",
    )


def test_time_errors_give_1_based_lines_and_plain_numbers(tmp_path):
    """Was 'row 20000 at np.float64(...)': 0-based rows and numpy reprs."""
    d = _walk(tmp_path)
    _imu(d, lambda rows: ["", *_shift_rows(rows, 19999, -1.0)])  # a blank first line: lines != rows
    _refused(
        d,
        r"imu\.csv: line 20001: IMU time is not strictly increasing: 1756402371\.\d{6} s does not follow "
        r"1756402372\.\d{6} s of line 20000; expected one sample per line in increasing time",
    )


def test_a_malformed_row_after_a_blank_line_names_its_file_line(tmp_path):
    d = _walk(tmp_path)
    _imu(d, lambda rows: [*rows[:3], "", "1756402241.0,x,0,0,0,0,0", *rows[3:]])
    _refused(d, r"imu\.csv: line 5: not a number in '1756402241\.0,x,0,0,0,0,0'")


def test_the_loaded_walk_is_the_file_through_units_and_mount():
    """The loader's numbers for the walk: unchanged by the checks (the replay traces hold them)."""
    rec = load_recording()
    raw = np.loadtxt(PACKAGED / "imu.csv", delimiter=",")
    np.testing.assert_array_equal(rec.imu.t, raw[:, 0])
    np.testing.assert_array_equal(rec.imu.accel, (raw[:, 1:4] * G0) @ rec.mount.T)
    np.testing.assert_array_equal(rec.imu.gyro, raw[:, 4:7] @ rec.mount.T)
    assert not rec.gnss.velocity_from_positions
