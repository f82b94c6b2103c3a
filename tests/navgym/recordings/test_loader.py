"""The recording loader: the packaged walk, a synthetic recording's known answers, clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from navgym.recordings import PACKAGED, load_recording, read_imu_csv, read_rtklib_pos
from navgym.recordings.loader import G0
from tests.navgym.recordings.synthetic import T0, body_samples, write_recording


def test_the_packaged_walk_loads_with_its_provenance():
    rec = load_recording()
    assert rec.name == "walk_0827"
    assert rec.imu.t.shape == (20455,) and rec.gnss.t.shape == (536,)
    assert rec.truth_epochs.sum() == 349 and rec.fix_epochs.sum() == 536
    # still at the start: the body-frame specific force points up (z down: -g) after the mounting
    f = np.median(rec.imu.accel[:100], axis=0)
    assert abs(np.linalg.norm(f) - G0) < 0.3 and f[2] < -9.5
    for name in ("LICENSE-GNSS_IMU.txt", "PROVENANCE.md", "recording.toml"):
        assert (PACKAGED / name).is_file()
    np.testing.assert_allclose(rec.lever_arm, [0.0, -0.05, 0.0])


@pytest.mark.parametrize(("accel_unit", "gyro_unit"), [("g", "deg/s"), ("m/s^2", "rad/s")])
@pytest.mark.parametrize("mount", [(180.0, 0.0, -90.0), (10.0, -20.0, 135.0)])
def test_units_and_mounting_give_the_known_body_samples(tmp_path, accel_unit, gyro_unit, mount):
    d = write_recording(
        tmp_path / "r", yaw_deg=30.0, mount_rpy_deg=mount, accel_unit=accel_unit, gyro_unit=gyro_unit
    )
    rec = load_recording(d)
    f_b, w_b = body_samples(30.0)
    np.testing.assert_allclose(rec.imu.accel, np.broadcast_to(f_b, rec.imu.accel.shape), atol=1e-8)
    np.testing.assert_allclose(rec.imu.gyro, np.broadcast_to(w_b, rec.imu.gyro.shape), atol=1e-9)
    assert rec.imu.t[0] == pytest.approx(T0 + 0.3, abs=1e-6)
    assert rec.gnss.t[1] - rec.gnss.t[0] == pytest.approx(0.25, abs=1e-9)


def test_gps_week_and_tow_times_read_like_calendar_times(tmp_path):
    p = tmp_path / "a.pos"
    p.write_text("%  GPST latitude(deg) longitude(deg) height(m) Q\n2086 503808.000 40 -105 1600 1\n")
    g = read_rtklib_pos(p)
    assert g.t[0] == pytest.approx(315964800.0 + 2086 * 604800 + 503808)
    assert np.isnan(g.vel_ned).all() and g.q[0] == 1


def test_time_offset_shifts_the_imu(tmp_path):
    d = write_recording(tmp_path / "r", time_offset_s=2.5)  # IMU stamped 2.5 s before GPST
    assert load_recording(d).imu.t[0] == pytest.approx(T0 + 0.3, abs=1e-6)
    text = (d / "recording.toml").read_text().replace("time_offset_s = 2.5", "time_offset_s = 3.0")
    (d / "recording.toml").write_text(text)
    assert load_recording(d).imu.t[0] == pytest.approx(T0 + 0.8, abs=1e-6)


def test_units_off_by_g_are_refused_both_ways(tmp_path):
    d = write_recording(tmp_path / "g", accel_unit="g")
    with pytest.raises(ValueError, match=r"imu.csv.*look like g"):
        read_imu_csv(d / "imu.csv", accel_unit="m/s^2")
    d = write_recording(tmp_path / "si", accel_unit="m/s^2")
    with pytest.raises(ValueError, match=r"imu.csv.*look like m/s\^2"):
        read_imu_csv(d / "imu.csv", accel_unit="g")


def test_non_monotonic_time_is_refused_naming_the_file(tmp_path):
    d = write_recording(tmp_path / "r")
    lines = (d / "imu.csv").read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    (d / "imu.csv").write_text("\n".join(lines))
    with pytest.raises(
        ValueError,
        match=r"imu.csv: line 7: IMU time is not strictly increasing: 1756402240\.331250 s does not follow "
        r"1756402240\.337500 s of line 6",
    ):
        load_recording(d)
    pos = (d / "gnss.pos").read_text().splitlines()
    pos[3], pos[4] = pos[4], pos[3]
    (d / "gnss.pos").write_text("\n".join(pos))
    with pytest.raises(
        ValueError, match=r"gnss.pos: line 5: GNSS time is not strictly increasing: 1756402240\.250000 s"
    ):
        read_rtklib_pos(d / "gnss.pos")


def test_malformed_files_and_missing_columns_are_named(tmp_path):
    d = write_recording(tmp_path / "r")
    lines = (d / "imu.csv").read_text().splitlines()
    (d / "imu.csv").write_text("\n".join([*lines[:3], "1.0,2.0,x,4,5,6,7", *lines[3:]]))
    with pytest.raises(ValueError, match=r"imu.csv: line 4: not a number"):
        load_recording(d)
    (d / "imu.csv").write_text("\n".join([*lines[:3], "1.0,2.0", *lines[3:]]))
    with pytest.raises(ValueError, match=r"imu.csv: line 4: 2 columns, need 7"):
        load_recording(d)
    (d / "imu.csv").write_text("\n".join(lines))
    pos = (d / "gnss.pos").read_text().replace("height(m)", "hgt")
    (d / "gnss.pos").write_text(pos)
    with pytest.raises(ValueError, match=r"gnss.pos: missing column\(s\) \['height\(m\)'\]"):
        load_recording(d)
    (d / "gnss.pos").write_text("2025/08/28 17:30:39.749 40 -105 1600 1\n")
    with pytest.raises(ValueError, match=r"gnss.pos: line 1: data before the column header"):
        load_recording(d)
    keys = 'accel_unit = "g"\ngyro_unit = "deg/s"\ntime_offset_s = 0.0\nlever_arm_m = [0, 0, 0]\n'
    (d / "recording.toml").write_text(f"[imu]\n{keys}mount_rpy_deg = [1, 2]\n[gnss]\n")
    with pytest.raises(ValueError, match=r"recording.toml: mount_rpy_deg must be a list of 3"):
        load_recording(d)
    (d / "recording.toml").write_text("[imu]\nbogus = 1\n[gnss]\n")
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['bogus'\] in \[imu\]"):
        load_recording(d)
    (d / "recording.toml").unlink()
    with pytest.raises(ValueError, match=r"no recording.toml sidecar"):
        load_recording(d)


def test_imu_and_gnss_without_overlap_are_refused(tmp_path):
    d = write_recording(tmp_path / "r", duration=5.0, imu_start=100.0)
    with pytest.raises(ValueError, match=r"do not overlap in time \(check time_offset_s: seconds added"):
        load_recording(d)
