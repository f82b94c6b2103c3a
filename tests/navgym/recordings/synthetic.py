"""A small synthetic recording in the format of :mod:`navgym.recordings.loader` (for the tests).

A level, still IMU (body axes x north, y east, z down, yaw ``yaw_deg``) at a known place: it
senses ``f^b = C_n^b (0, 0, -gamma)`` and ``omega^b = C_n^b omega_ie^n``; the sensor axes are
rotated by ``mount_rpy_deg`` (``f^s = C_b^s^T f^b``), the antenna sits at ``lever`` (body) from
the IMU, every fix (4 Hz, Q = 1) is the antenna's true position.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

from navgym.geo import ecef_to_geodetic, geodetic_to_ecef, gravity, ned_to_ecef
from navgym.ins import earth_rate_ned
from navgym.ins.attitude import euler_to_dcm

LAT, LON, H = np.deg2rad(40.0), np.deg2rad(-105.0), 1600.0
T0 = 1756402240.0  # GPST on the Unix epoch


def body_samples(yaw_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """The still IMU's body-frame specific force [m/s^2] and rate [rad/s]."""
    C_bn = euler_to_dcm(0.0, 0.0, np.deg2rad(yaw_deg))
    f_b = C_bn.T @ np.array([0.0, 0.0, -float(gravity(LAT, H))])
    w_b = C_bn.T @ earth_rate_ned(np.array([LAT]))[0]
    return f_b, w_b


def write_recording(
    d: Path,
    *,
    duration: float = 30.0,
    imu_rate: float = 160.0,
    yaw_deg: float = 30.0,
    mount_rpy_deg=(180.0, 0.0, -90.0),
    lever=(0.3, -0.2, 0.0),
    accel_unit: str = "g",
    gyro_unit: str = "deg/s",
    imu_start: float = 0.3,
    time_offset_s: float = 0.0,
) -> Path:
    """Write imu.csv, gnss.pos and recording.toml into ``d`` (created) and return ``d``."""
    d.mkdir(parents=True, exist_ok=True)
    f_b, w_b = body_samples(yaw_deg)
    C_bs = euler_to_dcm(*np.deg2rad(mount_rpy_deg))
    f_s, w_s = C_bs.T @ f_b, C_bs.T @ w_b
    f_s = f_s / (9.80665 if accel_unit == "g" else 1.0)
    w_s = w_s * (180.0 / np.pi if gyro_unit == "deg/s" else 1.0)
    t = T0 + imu_start - time_offset_s + np.arange(int(duration * imu_rate)) / imu_rate
    rows = [f"{ti:.7f}," + ",".join(f"{x:.10f}" for x in (*f_s, *w_s)) + ",0,0,0,0" for ti in t]
    (d / "imu.csv").write_text("\n".join(rows) + "\n")
    # the antenna: IMU at the origin plus C_b^n lever
    ant = euler_to_dcm(0.0, 0.0, np.deg2rad(yaw_deg)) @ np.asarray(lever, float)
    lat, lon, h = ecef_to_geodetic(ned_to_ecef(ant, LAT, LON, H))
    head = (
        "% program   : synthetic\n"
        "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   "
        "sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio    vn(m/s)    ve(m/s)    vu(m/s)\n"
    )
    lines = []
    for k in range(int(duration * 4) + 8):
        tk = T0 + k * 0.25
        s = dt.datetime.fromtimestamp(tk, tz=dt.UTC)
        lines.append(
            f"{s:%Y/%m/%d %H:%M:%S}.{s.microsecond // 1000:03d} "
            f"{np.rad2deg(lat):.10f} {np.rad2deg(lon):.10f} {h:.4f} 1 20 0.01 0.01 0.01 0 0 0 0 0 0.0 0.0 0.0"
        )
    (d / "gnss.pos").write_text(head + "\n".join(lines) + "\n")
    (d / "recording.toml").write_text(
        "[imu]\n"
        f'accel_unit = "{accel_unit}"\n'
        f'gyro_unit = "{gyro_unit}"\n'
        f"time_offset_s = {float(time_offset_s)}\n"
        f"mount_rpy_deg = [{', '.join(str(float(x)) for x in mount_rpy_deg)}]\n"
        f"lever_arm_m = [{', '.join(str(float(x)) for x in lever)}]\n"
        f"initial_yaw_deg = {float(yaw_deg)}\n"
        "[gnss]\n"
        "fix_q = [1]\n"
        "truth_q = [1]\n"
    )
    return d


__all__ = ["write_recording", "body_samples", "geodetic_to_ecef", "LAT", "LON", "H", "T0"]
