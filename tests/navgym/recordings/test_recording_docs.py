"""Issue 38, item 7: the documented sidecar keys, the mount's direction and the worked car sidecar.

``docs/recordings.md`` must name every key with its default, and what it says about the mount
must be what the loader does: an asymmetric mount (not its own inverse, unlike the walk's) read
on hand-made samples, and the worked car sidecar loading on a recording made for it.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np

from navgym.ins.attitude import dcm_to_euler, euler_to_dcm
from navgym.recordings import loader
from navgym.recordings.loader import (
    OPTIONAL_GNSS_DEFAULTS,
    OPTIONAL_IMU_DEFAULTS,
    REQUIRED_IMU_KEYS,
    load_recording,
    read_imu_csv,
)
from tests.navgym.recordings.synthetic import write_recording

DOC = Path(__file__).resolve().parents[3] / "docs" / "recordings.md"
G = 9.80665


def _doc() -> str:
    return DOC.read_text()


def test_the_docs_name_every_required_key_and_every_default():
    text = _doc()
    required = text[text.index("### Required keys") : text.index("### Optional keys")]
    for key in REQUIRED_IMU_KEYS:
        assert f"| `{key}` |" in required, key
    optional = text[text.index("### Optional keys") : text.index("**Where the noise defaults")]
    for key, default in {**OPTIONAL_IMU_DEFAULTS, **OPTIONAL_GNSS_DEFAULTS}.items():
        if key == "file":
            continue
        shown = f"`{default}`" if isinstance(default, list) else loader._num(default)
        assert re.search(rf"\| `{key}` \| {re.escape(shown)} \|", optional), (key, shown)


def _imu_file(tmp_path: Path, f_s, w_s=(0.0, 0.0, 0.0)) -> Path:
    p = tmp_path / "imu.csv"
    row = ",".join(f"{x:.6f}" for x in (*f_s, *w_s))
    p.write_text("".join(f"{1756402240.0 + k * 0.01:.3f},{row}\n" for k in range(10)))
    return p


def test_an_asymmetric_mount_turns_sensor_samples_into_the_body_as_documented(tmp_path):
    """[0, 0, 90]: sensor x = body right, sensor y = body back; driving off reads -2 on y."""
    C = euler_to_dcm(*np.deg2rad([0.0, 0.0, 90.0]))
    assert not np.allclose(C, C.T)  # not its own inverse: the direction shows
    np.testing.assert_allclose(C[:, 0], [0, 1, 0], atol=1e-12)  # sensor x in the body: right
    np.testing.assert_allclose(C[:, 1], [-1, 0, 0], atol=1e-12)  # sensor y: backwards
    imu = read_imu_csv(_imu_file(tmp_path, (0.0, -2.0, -G), (0.1, 0.0, 0.0)), "m/s^2", "rad/s", 0.0, C)
    np.testing.assert_allclose(imu.accel[0], [2.0, 0.0, -G], atol=1e-9)  # forward
    np.testing.assert_allclose(imu.gyro[0], [0.0, 0.1, 0.0], atol=1e-12)  # a rate about sensor x: body y


def test_the_walks_mount_is_its_own_inverse():
    C = euler_to_dcm(*np.deg2rad([180.0, 0.0, -90.0]))
    np.testing.assert_allclose(C, C.T, atol=1e-12)


def test_the_car_phone_mount_of_the_docs(tmp_path):
    """Phone upright, screen to the driver: y up, z backwards; the docs' snippet gives its angles."""
    columns = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    np.testing.assert_allclose(np.rad2deg(dcm_to_euler(columns)), [-90.0, 0.0, 90.0], atol=1e-9)
    assert "[-90.  0.  90.]" in _doc()
    C = euler_to_dcm(*np.deg2rad([-90.0, 0.0, 90.0]))
    imu = read_imu_csv(_imu_file(tmp_path, (0.0, G, -2.0)), "m/s^2", "rad/s", 0.0, C)
    np.testing.assert_allclose(imu.accel[0], [2.0, 0.0, -G], atol=1e-9)


def _car_sidecar() -> str:
    text = _doc()
    start = text.index("# my_drive/recording.toml")
    return text[start : text.index("```", start)]


def test_the_worked_car_sidecar_loads_on_a_recording_made_for_it(tmp_path):
    side = tomllib.loads(_car_sidecar())
    imu = side["imu"]
    assert set(REQUIRED_IMU_KEYS) <= set(imu)
    d = write_recording(
        tmp_path / "my_drive",
        mount_rpy_deg=imu["mount_rpy_deg"],
        lever=imu["lever_arm_m"],
        accel_unit=imu["accel_unit"],
        gyro_unit=imu["gyro_unit"],
    )
    (d / "recording.toml").write_text(_car_sidecar())
    rec = load_recording(d)
    np.testing.assert_allclose(rec.lever_arm, [-0.3, 0.0, -0.9])
    assert rec.fix_q == (1, 2, 5)
    f = rec.imu.accel.mean(axis=0)  # the still phone's samples, through the mount: gravity down
    assert f[2] < -9.7 and abs(f[0]) < 1e-6 and abs(f[1]) < 1e-6


def test_the_loader_docstring_names_the_direction_it_applies():
    doc = loader.__doc__
    assert "C_s^b = R_z(yaw) R_y(pitch) R_x(roll)" in doc and "f^b = C_s^b f^s" in doc
    assert "C_b^s" not in doc
