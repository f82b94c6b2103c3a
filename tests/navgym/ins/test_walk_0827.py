"""Sanity check of the strapdown conventions on real data (walk_0827, consumer MEMS + RTK).

Static alignment over the first 10 s (levelling, gyro bias, vertical accelerometer bias), then
free-inertial navigation for 17 s: 2.5 s of rest, then the first 14.5 s of walking. The heading is not
observable at rest, so one yaw angle is fitted to the RTK-fixed track; the remaining misfit is
what the conventions (specific force sign, rotation sense, Earth rate) must keep small: a
wrong gyro sign gives ~70 m here instead of ~1.3 m.
"""

import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from navgym import geo
from navgym.ins import ImuSample, earth_rate_ned, euler_to_dcm, make_nav_state, strapdown_step

#: The real walk_0827 recording in the project's shared data folder beside the repository.
DATA = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "recorded" / "walk_0827"
pytestmark = pytest.mark.skipif(not DATA.exists(), reason="shared walk_0827 recording not available")

G0 = 9.80665
ALIGN_S, WINDOW_S = 10.0, 17.0
#: Bounds for 14.5 s of handheld walking, consumer MEMS IMU (observed 1.34 m and 0.12 m).
HORIZONTAL_RMS_M, VERTICAL_MAX_M = 3.0, 1.0


def _load():
    imu = np.loadtxt(DATA / "imu.csv", delimiter=",")
    rows = [ln.split() for ln in (DATA / "gnss.pos").read_text().splitlines() if ln and ln[0] != "%"]
    t = np.array(
        [
            dt.datetime.strptime(f"{r[0]} {r[1]}", "%Y/%m/%d %H:%M:%S.%f").replace(tzinfo=dt.UTC).timestamp()
            for r in rows
        ]
    )
    sol = np.array([[float(x) for x in r[2:6]] for r in rows])
    return imu, t, np.deg2rad(sol[:, 0]), np.deg2rad(sol[:, 1]), sol[:, 2], sol[:, 3] == 1


def test_free_inertial_track_follows_rtk_while_walking():
    imu, tg, lat, lon, h, fixed = _load()
    t, f, w = imu[:, 0], imu[:, 1:4] * G0, imu[:, 4:7]
    t_align = tg[0] + ALIGN_S
    still = t < t_align
    f_bar, w_bar = f[still].mean(axis=0), w[still].mean(axis=0)
    ref = fixed & (tg < t_align)
    lat0, lon0, h0 = lat[ref].mean(), lon[ref].mean(), h[ref].mean()
    gamma = geo.gravity(lat0, h0)
    assert abs(np.linalg.norm(f_bar) - gamma) < 0.02 * gamma  # at rest it senses normal gravity

    # levelling (Groves eq. 5.101): f^b = C_n^b [0, 0, -g] at rest
    roll = np.arctan2(-f_bar[1], -f_bar[2])
    pitch = np.arctan(f_bar[0] / np.hypot(f_bar[1], f_bar[2]))
    C0 = euler_to_dcm(roll, pitch, 0.0)
    gyro_bias = w_bar - C0.T @ earth_rate_ned(lat0)
    accel_bias = (np.linalg.norm(f_bar) - gamma) * f_bar / np.linalg.norm(f_bar)

    k0 = int(np.argmax(t >= t_align))
    k1 = int(np.argmax(t >= t_align + WINDOW_S))
    nav = make_nav_state([lat0], [lon0], [h0], np.zeros((1, 3)), C0[None])
    track = [nav]
    for k in range(k0, k1):
        fm = 0.5 * (f[k] + f[k + 1]) - accel_bias  # interval means of the samples
        wm = 0.5 * (w[k] + w[k + 1]) - gyro_bias
        nav = strapdown_step(nav, ImuSample(fm[None], wm[None]), t[k + 1] - t[k])
        track.append(nav)
    ts = t[k0 : k1 + 1]
    la, lo, hh = (np.array([getattr(s, n)[0] for s in track]) for n in ("lat", "lon", "h"))

    sel = fixed & (tg >= ts[0]) & (tg <= ts[-1])
    ins = geo.ecef_to_ned(
        geo.geodetic_to_ecef(*(np.interp(tg[sel], ts, x) for x in (la, lo, hh))), lat0, lon0, h0
    )
    rtk = geo.ecef_to_ned(geo.geodetic_to_ecef(lat[sel], lon[sel], h[sel]), lat0, lon0, h0)
    a, b = ins[:, :2], rtk[:, :2]
    assert np.abs(b).max() > 5.0  # the window does include real motion
    yaw = np.arctan2((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum(), (a * b).sum())
    rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    residual = np.linalg.norm(b - a @ rot.T, axis=1)
    assert np.sqrt(np.mean(residual**2)) < HORIZONTAL_RMS_M
    assert np.abs(ins[:, 2] - rtk[:, 2]).max() < VERTICAL_MAX_M
