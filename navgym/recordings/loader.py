"""Read a recording: an IMU CSV, an RTKLIB solution file (``.pos``) and a TOML sidecar.

A recording is a directory with three files (the packaged example is
``navgym/data/recordings/walk_0827``, GNSS_IMU walk_0827 in ``docs/references.md``):

``imu.csv``
    No header; one sample per line, comma-separated: column 0 the time [s] (GPS time as seconds
    since 1970-01-01, i.e. GPST on the Unix epoch, plus the sidecar's ``time_offset_s``),
    columns 1-3 the specific force ``f_ib^s`` x, y, z in the sensor frame (unit ``accel_unit``:
    ``"g"`` or ``"m/s^2"``), columns 4-6 the angular rate ``omega_ib^s`` x, y, z (``gyro_unit``:
    ``"rad/s"`` or ``"deg/s"``); further columns are ignored. Times strictly increase.
``gnss.pos``
    RTKLIB's solution format (rnx2rtkp / rtkpost output; RTKLIB in ``docs/references.md``):
    header lines start with ``%``, the last of them names the columns
    (``GPST latitude(deg) longitude(deg) height(m) Q ns sdn(m) sde(m) sdu(m) ... vn(m/s)
    ve(m/s) vu(m/s) ...``); each epoch's time is two fields, ``YYYY/MM/DD hh:mm:ss.sss`` or
    ``week tow``. Latitude, longitude, height and Q are required; the standard deviations and the
    velocities (north, east, up) are read where present. Times strictly increase.
``recording.toml``
    The sidecar (``tomllib``)::

        [imu]
        file = "imu.csv"
        accel_unit = "g"                # or "m/s^2"
        gyro_unit = "rad/s"             # or "deg/s"
        time_offset_s = 0.0             # added to the IMU times to get GPST
        mount_rpy_deg = [180.0, 0.0, -90.0]
        lever_arm_m = [0.0, -0.05, 0.0]
        accel_noise_ug_per_sqrt_hz = 70.0
        gyro_noise_deg_s_per_sqrt_hz = 0.0038
        accel_bias_mg = 1.0             # turn-on bias sigma
        gyro_bias_deg_h = 360.0
        initial_yaw_deg = 0.0           # heading guess for windows that start still

        [gnss]
        file = "gnss.pos"
        fix_q = [1, 2]                  # epochs delivered to the filter as fixes
        truth_q = [1]                   # epochs that are truth (RTK fixed)

**Mounting.** ``mount_rpy_deg = (roll, pitch, yaw)`` are the 3-2-1 Euler angles of the sensor
axes in the body frame (x forward, y right, z down): ``C_b^s = R_z(yaw) R_y(pitch) R_x(roll)``
(Groves 2013, eq. 2.22, the form of :func:`navgym.ins.attitude.euler_to_dcm`), and the body-frame
samples are ``f^b = C_b^s f^s``, ``omega^b = C_b^s omega^s``. **Lever arm**
``lever_arm_m = l^b`` is the GNSS antenna's position relative to the IMU in the body frame [m]
(Groves 2013, §14.2, the loosely coupled measurement model with the lever arm): the antenna
sits at ``p + C_b^n l^b`` and moves with
``v + C_b^n (omega_ib^b x l^b)`` (the Earth-rate term, below 1e-5 m/s at these arms, left out).

Malformed files raise ``ValueError`` naming the file (and the line or the column).
"""

from __future__ import annotations

import datetime as _dt
import math
import tomllib
import warnings
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from navgym.ins.attitude import euler_to_dcm

#: Standard gravity [m/s^2] (the ``g`` of ``accel_unit = "g"``).
G0 = 9.80665
#: Unix time of the GPS epoch 1980-01-06 00:00:00 (GPST on the Unix epoch, no leap seconds).
GPS_EPOCH_UNIX = 315964800.0
#: Sidecar file name in a recording directory.
SIDECAR = "recording.toml"
#: The packaged recording directory (GNSS_IMU walk_0827).
PACKAGED = Path(__file__).resolve().parent.parent / "data" / "recordings" / "walk_0827"
#: Units accepted for the specific force and the rates, and their factor to SI.
ACCEL_UNITS = {"g": G0, "m/s^2": 1.0}
GYRO_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
#: Columns of the .pos file the loader needs.
POS_REQUIRED = ("latitude(deg)", "longitude(deg)", "height(m)", "Q")


class ImuLog(NamedTuple):
    """IMU samples in the body frame (after units, time offset and mounting rotation)."""

    t: np.ndarray  #: (N,) GPST [s since 1970-01-01]
    accel: np.ndarray  #: (N, 3) specific force f_ib^b [m/s^2]
    gyro: np.ndarray  #: (N, 3) angular rate omega_ib^b [rad/s]


class GnssLog(NamedTuple):
    """An RTKLIB solution (one row per epoch)."""

    t: np.ndarray  #: (K,) GPST [s since 1970-01-01]
    lla: np.ndarray  #: (K, 3) latitude [rad], longitude [rad], ellipsoidal height [m]
    q: np.ndarray  #: (K,) RTKLIB quality flag (1 fixed, 2 float, 5 single, ...)
    sd: np.ndarray  #: (K, 3) sdn, sde, sdu [m] (NaN where the file has none)
    vel_ned: np.ndarray  #: (K, 3) velocity north, east, down [m/s] (NaN where the file has none)


class Recording(NamedTuple):
    """A recording: its IMU and GNSS logs and the sidecar's numbers."""

    name: str
    imu: ImuLog
    gnss: GnssLog
    lever_arm: np.ndarray  #: (3,) antenna relative to the IMU, body frame [m]
    mount: np.ndarray  #: (3, 3) C_b^s, sensor to body
    accel_noise: float  #: accelerometer noise density [m/s^2/sqrt(Hz)]
    gyro_noise: float  #: gyro noise density [rad/s/sqrt(Hz)]
    accel_bias: float  #: turn-on accelerometer bias sigma [m/s^2]
    gyro_bias: float  #: turn-on gyro bias sigma [rad/s]
    initial_yaw_deg: float  #: the body's heading guess [deg] for windows that start still
    fix_q: tuple[int, ...]  #: Q flags of the epochs delivered to the filter
    truth_q: tuple[int, ...]  #: Q flags of the epochs that are truth

    @property
    def fix_epochs(self) -> np.ndarray:
        """(K,) bool: the epoch is delivered to the filter."""
        return np.isin(self.gnss.q, self.fix_q)

    @property
    def truth_epochs(self) -> np.ndarray:
        """(K,) bool: the epoch is truth."""
        return np.isin(self.gnss.q, self.truth_q)


def _float_table(path: Path, rows: list[list[str]], lines: list[int]) -> np.ndarray:
    out = np.empty((len(rows), len(rows[0]) if rows else 0))
    for i, (r, ln) in enumerate(zip(rows, lines, strict=True)):
        try:
            out[i] = [float(x) for x in r]
        except ValueError:
            raise ValueError(f"{path}: line {ln}: not a number in {','.join(r)!r}") from None
    return out


def _check_time(path: Path, t: np.ndarray, what: str) -> None:
    if not np.isfinite(t).all():
        raise ValueError(f"{path}: {what} time column holds non-finite values")
    d = np.diff(t)
    if d.size and not (d > 0).all():
        i = int(np.flatnonzero(~(d > 0))[0])
        raise ValueError(
            f"{path}: {what} time is not strictly increasing: row {i + 1} at {t[i + 1]!r} s follows "
            f"{t[i]!r} s"
        )


def read_imu_csv(
    path: str | Path,
    accel_unit: str = "g",
    gyro_unit: str = "rad/s",
    time_offset_s: float = 0.0,
    mount: np.ndarray | None = None,
) -> ImuLog:
    """The IMU samples of ``path`` in SI units and the body frame (module docstring).

    Raises:
        ValueError: an unreadable line, fewer than 7 columns, non-finite or non-increasing time,
            an unknown unit, or a specific force whose median magnitude is off from gravity by the
            factor ``g`` (``accel_unit`` says ``"m/s^2"`` but the data are in g, or the other way
            round; any median outside 0.5-1.5 g after the unit is refused).
    """
    path = Path(path)
    if accel_unit not in ACCEL_UNITS:
        raise ValueError(f"{path}: accel_unit must be one of {sorted(ACCEL_UNITS)}; got {accel_unit!r}")
    if gyro_unit not in GYRO_UNITS:
        raise ValueError(f"{path}: gyro_unit must be one of {sorted(GYRO_UNITS)}; got {gyro_unit!r}")
    try:  # the fast reader; on any failure the line reader below names the line
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = np.loadtxt(path, delimiter=",", usecols=range(7), ndmin=2, dtype=np.float64)
    except (ValueError, IndexError):
        d = None
    if d is None or d.shape[0] == 0:
        rows, lines = [], []
        with open(path, encoding="utf-8") as fh:
            for ln, line in enumerate(fh, 1):
                s = line.strip()
                if not s:
                    continue
                r = [x.strip() for x in s.split(",")]
                if len(r) < 7:
                    raise ValueError(
                        f"{path}: line {ln}: {len(r)} columns, need 7 (time, accel x y z, gyro x y z)"
                    )
                rows.append(r[:7])
                lines.append(ln)
        if not rows:
            raise ValueError(f"{path}: no IMU samples")
        d = _float_table(path, rows, lines)
    if not np.isfinite(d[:, 1:]).all():
        raise ValueError(f"{path}: non-finite specific force or angular rate")
    t = d[:, 0] + float(time_offset_s)
    _check_time(path, t, "IMU")
    f = d[:, 1:4] * ACCEL_UNITS[accel_unit]
    w = d[:, 4:7] * GYRO_UNITS[gyro_unit]
    g = float(np.median(np.linalg.norm(f, axis=1)))
    if not 0.5 * G0 <= g <= 1.5 * G0:
        hint = ""
        if 0.5 * G0 <= g * G0 <= 1.5 * G0:
            hint = ' (the data look like g: set accel_unit = "g")'
        elif 0.5 * G0 <= g / G0 <= 1.5 * G0:
            hint = ' (the data look like m/s^2: set accel_unit = "m/s^2")'
        raise ValueError(
            f"{path}: columns 1-3 (specific force) have a median magnitude of {g:.4g} m/s^2 with "
            f"accel_unit = {accel_unit!r}, not about g = {G0} m/s^2{hint}"
        )
    if mount is not None:
        f = f @ np.asarray(mount).T
        w = w @ np.asarray(mount).T
    return ImuLog(t, f, w)


def _pos_time(path: Path, ln: int, a: str, b: str) -> float:
    try:
        if "/" in a:
            day = _dt.datetime.strptime(a, "%Y/%m/%d").replace(tzinfo=_dt.UTC)
            hh, mm, ss = b.split(":")
            return day.timestamp() + 3600.0 * int(hh) + 60.0 * int(mm) + float(ss)
        return GPS_EPOCH_UNIX + 604800.0 * int(a) + float(b)
    except ValueError:
        raise ValueError(
            f"{path}: line {ln}: GPST must be 'YYYY/MM/DD hh:mm:ss.sss' or 'week tow'; got {a!r} {b!r}"
        ) from None


def read_rtklib_pos(path: str | Path) -> GnssLog:
    """An RTKLIB ``.pos`` solution (module docstring): times, lat/lon/height, Q, sd, velocities.

    Raises:
        ValueError: no column header, a required column missing (named), a line with too few
            fields or a field that is not a number, non-increasing time, or no epoch.
    """
    path = Path(path)
    names: list[str] | None = None
    rows, lines, times = [], [], []
    with open(path, encoding="utf-8") as fh:
        for ln, line in enumerate(fh, 1):
            s = line.strip()
            if not s:
                continue
            if s.startswith("%"):
                tok = s[1:].split()
                if tok and tok[0] == "GPST":
                    names = tok[1:]
                continue
            if names is None:
                raise ValueError(
                    f"{path}: line {ln}: data before the column header ('%  GPST  latitude(deg) ...')"
                )
            tok = s.split()
            if len(tok) < 2 + len(names):
                raise ValueError(f"{path}: line {ln}: {len(tok)} fields, the header names {2 + len(names)}")
            times.append(_pos_time(path, ln, tok[0], tok[1]))
            rows.append(tok[2 : 2 + len(names)])
            lines.append(ln)
    if names is None:
        raise ValueError(
            f"{path}: no column header ('%  GPST  latitude(deg) longitude(deg) height(m) Q ...')"
        )
    missing = [c for c in POS_REQUIRED if c not in names]
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing} (RTKLIB lat/lon/height output with Q)")
    if not rows:
        raise ValueError(f"{path}: no epochs")
    d = _float_table(path, rows, lines)
    t = np.asarray(times)
    _check_time(path, t, "GNSS")

    def col(name: str) -> np.ndarray:
        return d[:, names.index(name)] if name in names else np.full(len(t), np.nan)

    lla = np.stack(
        [np.deg2rad(col("latitude(deg)")), np.deg2rad(col("longitude(deg)")), col("height(m)")], -1
    )
    if not np.isfinite(lla).all():
        raise ValueError(f"{path}: non-finite latitude, longitude or height")
    if (np.abs(lla[:, 0]) > np.pi / 2).any():
        raise ValueError(f"{path}: column latitude(deg) outside [-90, 90]")
    sd = np.stack([col("sdn(m)"), col("sde(m)"), col("sdu(m)")], -1)
    vel = np.stack([col("vn(m/s)"), col("ve(m/s)"), -col("vu(m/s)")], -1)
    return GnssLog(t, lla, col("Q").astype(np.int64), sd, vel)


def _vec3(path: Path, key: str, value: Any) -> np.ndarray:
    a = np.asarray(value, dtype=float) if isinstance(value, list | tuple) else None
    if a is None or a.shape != (3,) or not np.isfinite(a).all():
        raise ValueError(f"{path}: {key} must be a list of 3 finite numbers; got {value!r}")
    return a


def _finite(path: Path, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"{path}: {key} must be a finite number; got {value!r}")
    return float(value)


def _positive(path: Path, key: str, value: Any) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not (math.isfinite(value) and value > 0)
    ):
        raise ValueError(f"{path}: {key} must be a finite number > 0; got {value!r}")
    return float(value)


def load_recording(directory: str | Path | None = None) -> Recording:
    """The recording in ``directory`` (default: the packaged walk_0827), checked (module docstring).

    Raises:
        ValueError: a missing or malformed file (named), or IMU and GNSS logs that do not overlap
            in time (no fix epoch inside the IMU's time span).
    """
    d = PACKAGED if directory is None else Path(directory)
    side = d / SIDECAR
    if not side.is_file():
        raise ValueError(f"{d}: no {SIDECAR} sidecar (see navgym.recordings.loader for its format)")
    try:
        cfg = tomllib.loads(side.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{side}: not valid TOML: {e}") from None
    imu_cfg, gnss_cfg = cfg.get("imu"), cfg.get("gnss")
    if not isinstance(imu_cfg, dict) or not isinstance(gnss_cfg, dict):
        raise ValueError(f"{side}: needs the tables [imu] and [gnss]")
    allowed_imu = {
        "file", "accel_unit", "gyro_unit", "time_offset_s", "mount_rpy_deg", "lever_arm_m",
        "accel_noise_ug_per_sqrt_hz", "gyro_noise_deg_s_per_sqrt_hz", "accel_bias_mg", "gyro_bias_deg_h",
        "initial_yaw_deg",
    }  # fmt: skip
    allowed_gnss = {"file", "fix_q", "truth_q"}
    for table, allowed, name in ((imu_cfg, allowed_imu, "imu"), (gnss_cfg, allowed_gnss, "gnss")):
        extra = sorted(set(table) - allowed)
        if extra:
            raise ValueError(f"{side}: unknown key(s) {extra} in [{name}] (known: {sorted(allowed)})")
    rpy = _vec3(side, "mount_rpy_deg", imu_cfg.get("mount_rpy_deg", [0.0, 0.0, 0.0]))
    mount = euler_to_dcm(*np.deg2rad(rpy))
    lever = _vec3(side, "lever_arm_m", imu_cfg.get("lever_arm_m", [0.0, 0.0, 0.0]))
    offset = _finite(side, "time_offset_s", imu_cfg.get("time_offset_s", 0.0))
    yaw0 = _finite(side, "initial_yaw_deg", imu_cfg.get("initial_yaw_deg", 0.0))
    imu_path = d / str(imu_cfg.get("file", "imu.csv"))
    pos_path = d / str(gnss_cfg.get("file", "gnss.pos"))
    for p in (imu_path, pos_path):
        if not p.is_file():
            raise ValueError(f"{side}: the file {p.name!r} it names is not in {d}")
    imu = read_imu_csv(
        imu_path,
        imu_cfg.get("accel_unit", "m/s^2"),
        imu_cfg.get("gyro_unit", "rad/s"),
        float(offset),
        mount,
    )
    gnss = read_rtklib_pos(pos_path)
    qs = {}
    for key, default in (("fix_q", [1, 2]), ("truth_q", [1])):
        v = gnss_cfg.get(key, default)
        if (
            not isinstance(v, list)
            or not v
            or not all(isinstance(x, int) and not isinstance(x, bool) for x in v)
        ):
            raise ValueError(f"{side}: {key} must be a non-empty list of integer Q flags; got {v!r}")
        qs[key] = tuple(v)
    rec = Recording(
        name=d.name,
        imu=imu,
        gnss=gnss,
        lever_arm=lever,
        mount=mount,
        accel_noise=_positive(
            side, "accel_noise_ug_per_sqrt_hz", imu_cfg.get("accel_noise_ug_per_sqrt_hz", 70.0)
        )
        * 1e-6
        * G0,
        gyro_noise=np.deg2rad(
            _positive(
                side, "gyro_noise_deg_s_per_sqrt_hz", imu_cfg.get("gyro_noise_deg_s_per_sqrt_hz", 0.0038)
            )
        ),
        accel_bias=_positive(side, "accel_bias_mg", imu_cfg.get("accel_bias_mg", 1.0)) * 1e-3 * G0,
        gyro_bias=np.deg2rad(
            _positive(side, "gyro_bias_deg_h", imu_cfg.get("gyro_bias_deg_h", 360.0)) / 3600.0
        ),
        initial_yaw_deg=yaw0,
        fix_q=qs["fix_q"],
        truth_q=qs["truth_q"],
    )
    inside = (gnss.t >= imu.t[0]) & (gnss.t <= imu.t[-1])
    if not (inside & rec.fix_epochs).any():
        raise ValueError(
            f"{d}: the IMU ({imu.t[0]:.3f} - {imu.t[-1]:.3f} s GPST) and the GNSS fixes "
            f"({gnss.t[0]:.3f} - {gnss.t[-1]:.3f} s) do not overlap in time (check time_offset_s)"
        )
    if not (inside & rec.truth_epochs).any():
        raise ValueError(f"{d}: no truth epoch (Q in {rec.truth_q}) inside the IMU's time span")
    return rec
