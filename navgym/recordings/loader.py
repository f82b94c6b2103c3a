"""Read a recording: an IMU CSV, an RTKLIB solution file (``.pos``) and a TOML sidecar.

A recording is a directory with three files (the packaged example is
``navgym/data/recordings/walk_0827``, GNSS_IMU walk_0827 in ``docs/references.md``; the user's
guide with a worked car sidecar is ``docs/recordings.md``):

``imu.csv``
    UTF-8 (or ASCII) text, no header; one sample per line, comma-separated: column 0 the time
    [s] (GPS time as seconds since 1970-01-01, i.e. GPST on the Unix epoch, after adding the
    sidecar's ``time_offset_s``), columns 1-3 the specific force ``f_ib^s`` x, y, z in the
    sensor frame (unit ``accel_unit``: ``"g"`` or ``"m/s^2"``), columns 4-6 the angular rate
    ``omega_ib^s`` x, y, z (``gyro_unit``: ``"rad/s"`` or ``"deg/s"``); further columns are
    ignored. Times strictly increase; every value is finite and within an IMU's range
    (:data:`MAX_SPECIFIC_FORCE`, :data:`MAX_RATE`).
``gnss.pos``
    RTKLIB's solution format (rnx2rtkp / rtkpost output; RTKLIB in ``docs/references.md``),
    UTF-8 text: header lines start with ``%``, the last of them names the columns
    (``GPST latitude(deg) longitude(deg) height(m) Q ns sdn(m) sde(m) sdu(m) ... vn(m/s)
    ve(m/s) vu(m/s) ...``); each epoch's time is two fields, ``YYYY/MM/DD hh:mm:ss.sss`` or
    ``week tow``, in GPST (a file written in UTC or JST, ``%  UTC ...``, is refused: rerun
    RTKLIB with GPST output). Latitude, longitude, height and Q are required; Q is an integer
    1-6 (1 fixed, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP). The standard deviations are read
    where present. The velocity columns ``vn(m/s) ve(m/s) vu(m/s)`` are optional (RTKLIB writes
    them with ``out-outvel``): without them the velocity is derived from the positions by
    central differences in time (:func:`numpy.gradient` over the epochs' times, one-sided at
    the ends; its noise is about the positions' times ``sqrt(2) / (2 dt)``; NaN for a file of
    one epoch), and ``GnssLog.velocity_from_positions`` says so. Times strictly increase.
``recording.toml``
    The sidecar (``tomllib``). Required keys (:data:`REQUIRED_IMU_KEYS`: no default could be
    right for another recording) and optional ones with their defaults::

        [imu]
        accel_unit = "g"                # required: "g" or "m/s^2"
        gyro_unit = "rad/s"             # required: "rad/s" or "deg/s"
        time_offset_s = 0.0             # required: added to the IMU times to get GPST [s]
        mount_rpy_deg = [180.0, 0.0, -90.0]  # required: the sensor axes in the body frame [deg]
        lever_arm_m = [0.0, -0.05, 0.0] # required: antenna relative to the IMU, body frame [m]
        file = "imu.csv"                # optional
        accel_noise_ug_per_sqrt_hz = 70.0     # optional (defaults: the walk's consumer MEMS)
        gyro_noise_deg_s_per_sqrt_hz = 0.0038 # optional
        accel_bias_mg = 1.0             # optional: turn-on bias sigma
        gyro_bias_deg_h = 360.0         # optional: turn-on bias sigma
        initial_yaw_deg = 0.0           # optional: heading guess for windows that start still

        [gnss]
        file = "gnss.pos"               # optional
        fix_q = [1, 2]                  # optional: epochs delivered to the filter as fixes
        truth_q = [1]                   # optional: epochs that are truth (RTK fixed)

    Every number is checked against a plausible range (:data:`SIDECAR_RANGES`,
    :data:`MAX_LEVER_ARM_M`); Q flags are integers 1-6.

**Mounting.** ``mount_rpy_deg = (roll, pitch, yaw)`` are the 3-2-1 Euler angles of the sensor
axes in the body frame (x forward, y right, z down), the way a body's Euler angles give its
axes in the navigation frame: ``C_s^b = R_z(yaw) R_y(pitch) R_x(roll)`` (Groves 2013, eq. 2.22
transposed, the form of :func:`navgym.ins.attitude.euler_to_dcm`), whose columns are the sensor
axes x, y, z expressed in the body frame. The body-frame samples are ``f^b = C_s^b f^s`` and
``omega^b = C_s^b omega^s`` (sensor to body). Example: ``[0, 0, 90]`` is a sensor whose x axis
points to the body's right and whose y axis points backwards (a forward acceleration reads
negative on the sensor's y). **Lever arm** ``lever_arm_m = l^b`` is the GNSS antenna's position
relative to the IMU in the body frame [m] (Groves 2013, §14.2, the loosely coupled measurement
model with the lever arm): the antenna sits at ``p + C_b^n l^b`` and moves with
``v + C_b^n (omega_ib^b x l^b)`` (the Earth-rate term, below 1e-5 m/s at these arms, left out).

**Checks.** :func:`load_recording` reads the files (format errors raise at once), then runs the
plausibility checks of :mod:`navgym.recordings.checks` (the mount against gravity while still,
the gyro against the GNSS heading rate and its time lag, IMU gaps and time jumps, the GNSS
epoch grid) and refuses the recording with every problem found. ``navgym recording check DIR``
prints the same checks with a summary.

Malformed files raise ``ValueError`` naming the file, the 1-based line (or the key) and what is
expected; numbers in messages are plain.
"""

from __future__ import annotations

import datetime as _dt
import io
import math
import tomllib
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from navgym.ins.attitude import euler_to_dcm
from navgym.recordings.checks import check_recording

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
#: The optional velocity columns of the .pos file (north, east, up).
POS_VELOCITY = ("vn(m/s)", "ve(m/s)", "vu(m/s)")
#: RTKLIB's solution quality flags (1 fixed, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP).
Q_FLAGS = (1, 2, 3, 4, 5, 6)
#: Largest specific force [m/s^2] (about 20 g) and angular rate [rad/s] (2000 deg/s, a MEMS
#: full scale) a sample may hold after its unit: beyond them a row is corrupted or mislabelled.
MAX_SPECIFIC_FORCE = 200.0
MAX_RATE = 35.0
#: Plausible .pos values: height [m] and speed [m/s] (a land vehicle or a drone).
HEIGHT_RANGE_M = (-1000.0, 50000.0)
MAX_GNSS_SPEED = 200.0
#: Longest lever arm [m] (the norm): a car's antenna-to-IMU distance, not a centimetre figure.
MAX_LEVER_ARM_M = 3.0

#: The [imu] keys a sidecar must give, and what each means (the error text when one is missing).
REQUIRED_IMU_KEYS = {
    "accel_unit": 'the unit of columns 1-3, "g" or "m/s^2"',
    "gyro_unit": 'the unit of columns 4-6, "rad/s" or "deg/s"',
    "time_offset_s": "seconds added to column 0 to get GPST (0.0 when the IMU is stamped in GPST)",
    "mount_rpy_deg": "roll, pitch, yaw [deg] of the sensor axes in the body frame (x fwd, y right, z down)",
    "lever_arm_m": "the GNSS antenna relative to the IMU in the body frame [m], e.g. [0.0, 0.0, 0.0]",
}
#: Optional [imu] / [gnss] keys and their defaults (the noise figures: the walk's consumer MEMS).
OPTIONAL_IMU_DEFAULTS: dict[str, Any] = {
    "file": "imu.csv",
    "accel_noise_ug_per_sqrt_hz": 70.0,
    "gyro_noise_deg_s_per_sqrt_hz": 0.0038,
    "accel_bias_mg": 1.0,
    "gyro_bias_deg_h": 360.0,
    "initial_yaw_deg": 0.0,
}
OPTIONAL_GNSS_DEFAULTS: dict[str, Any] = {"file": "gnss.pos", "fix_q": [1, 2], "truth_q": [1]}
#: Plausible ranges ``(low, high, what)`` of the sidecar's numbers (``low`` exclusive where 0).
SIDECAR_RANGES: dict[str, tuple[float, float, str]] = {
    "accel_noise_ug_per_sqrt_hz": (
        0.0,
        10000.0,
        "ug/sqrt(Hz), a datasheet's noise density (consumer MEMS 50-300)",
    ),
    "gyro_noise_deg_s_per_sqrt_hz": (0.0, 1.0, "deg/s/sqrt(Hz) (consumer MEMS 0.003-0.05)"),
    "accel_bias_mg": (0.0, 1000.0, "mg, the turn-on bias sigma (consumer MEMS 1-60)"),
    "gyro_bias_deg_h": (0.0, 36000.0, "deg/h, the turn-on bias sigma (consumer MEMS 10-3600)"),
    "initial_yaw_deg": (-360.0, 360.0, "deg, a heading"),
}


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
    vel_ned: np.ndarray  #: (K, 3) velocity north, east, down [m/s] (module docstring)
    velocity_from_positions: bool = False  #: the file has no velocity columns: derived


class Recording(NamedTuple):
    """A recording: its IMU and GNSS logs and the sidecar's numbers."""

    name: str
    imu: ImuLog
    gnss: GnssLog
    lever_arm: np.ndarray  #: (3,) antenna relative to the IMU, body frame [m]
    mount: np.ndarray  #: (3, 3) C_s^b, sensor to body (module docstring)
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


class RecordingSources(NamedTuple):
    """Where a recording's numbers came from: files, 1-based lines and the sidecar's values."""

    directory: Path
    sidecar: Path
    imu_path: Path
    pos_path: Path
    imu_lines: np.ndarray  #: (N,) the file line of each IMU row
    gnss_lines: np.ndarray  #: (K,) the file line of each GNSS epoch
    mount_rpy_deg: tuple[float, float, float]
    accel_unit: str
    gyro_unit: str
    time_offset_s: float


def _num(x: float) -> str:
    """A number as plain text for messages (never a numpy repr)."""
    x = float(x)
    return str(int(x)) if x.is_integer() and abs(x) < 1e15 else f"{x:.10g}"


def _nums(xs: Any) -> str:
    """A sequence of numbers as plain text: ``[0, -5, 0.25]``."""
    return "[" + ", ".join(_num(x) for x in xs) + "]"


def _read_text(path: Path) -> str:
    """The UTF-8 text of ``path``; a byte that is not UTF-8 is named with its 1-based line."""
    data = path.read_bytes()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise ValueError(
            f"{path}: line {line}: byte 0x{data[exc.start]:02x} at column {col} is not UTF-8 text; "
            "save the file as UTF-8 (or plain ASCII)"
        ) from None


def _float_table(path: Path, rows: list[list[str]], lines: list[int]) -> np.ndarray:
    out = np.empty((len(rows), len(rows[0]) if rows else 0))
    for i, (r, ln) in enumerate(zip(rows, lines, strict=True)):
        try:
            out[i] = [float(x) for x in r]
        except ValueError:
            raise ValueError(f"{path}: line {ln}: not a number in {','.join(r)!r}") from None
    return out


def _check_time(path: Path, t: np.ndarray, lines: np.ndarray, what: str) -> None:
    """Finite, strictly increasing times; errors name the 1-based lines and plain seconds."""
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"{path}: line {int(lines[bad[0]])}: the {what} time is not a finite number")
    d = np.diff(t)
    if d.size and not (d > 0).all():
        i = int(np.flatnonzero(~(d > 0))[0])
        raise ValueError(
            f"{path}: line {int(lines[i + 1])}: {what} time is not strictly increasing: "
            f"{t[i + 1]:.6f} s does not follow {t[i]:.6f} s of line {int(lines[i])}; "
            "expected one sample per line in increasing time"
        )


def _imu_table(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The IMU file's first 7 columns ``(N, 7)`` and the 1-based line of each row."""
    text = _read_text(path)
    raw = text.split("\n")
    lines = np.array([k + 1 for k, ln in enumerate(raw) if ln not in ("", "\r")], dtype=np.int64)
    try:  # the fast reader; on any failure the line reader below names the line
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = np.loadtxt(
                io.StringIO(text), delimiter=",", usecols=range(7), ndmin=2, dtype=np.float64, comments=None
            )
        if d.shape[0] == lines.size and d.shape[0] > 0:
            return d, lines
    except (ValueError, IndexError):
        pass
    rows, found = [], []
    for ln, line in enumerate(raw, 1):
        s = line.strip()
        if not s:
            continue
        r = [x.strip() for x in s.split(",")]
        if len(r) < 7:
            raise ValueError(f"{path}: line {ln}: {len(r)} columns, need 7 (time, accel x y z, gyro x y z)")
        rows.append(r[:7])
        found.append(ln)
    if not rows:
        raise ValueError(f"{path}: no IMU samples")
    return _float_table(path, rows, found), np.asarray(found, dtype=np.int64)


def _read_imu(
    path: Path, accel_unit: str, gyro_unit: str, time_offset_s: float, mount: np.ndarray | None
) -> tuple[ImuLog, np.ndarray]:
    """:func:`read_imu_csv` and the 1-based line of each row."""
    if accel_unit not in ACCEL_UNITS:
        raise ValueError(f"{path}: accel_unit must be one of {sorted(ACCEL_UNITS)}; got {accel_unit!r}")
    if gyro_unit not in GYRO_UNITS:
        raise ValueError(f"{path}: gyro_unit must be one of {sorted(GYRO_UNITS)}; got {gyro_unit!r}")
    d, lines = _imu_table(path)
    bad = np.flatnonzero(~np.isfinite(d[:, 1:7]).all(axis=1))
    if bad.size:
        raise ValueError(f"{path}: line {int(lines[bad[0]])}: non-finite specific force or angular rate")
    t = d[:, 0] + float(time_offset_s)
    _check_time(path, t, lines, "IMU")
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
    _check_sample_range(path, lines, f, MAX_SPECIFIC_FORCE, "specific force", "m/s^2", "1-3", "")
    deg_hint = ""
    if gyro_unit == "rad/s" and np.abs(w).max() * GYRO_UNITS["deg/s"] <= MAX_RATE:
        deg_hint = ' (if the whole file is in deg/s: set gyro_unit = "deg/s")'
    _check_sample_range(path, lines, w, MAX_RATE, "angular rate", "rad/s", "4-6", deg_hint)
    if mount is not None:
        f = f @ np.asarray(mount).T
        w = w @ np.asarray(mount).T
    return ImuLog(t, f, w), lines


def _check_sample_range(
    path: Path, lines: np.ndarray, x: np.ndarray, limit: float, what: str, unit: str, cols: str, hint: str
) -> None:
    bad = np.flatnonzero((np.abs(x) > limit).any(axis=1))
    if bad.size:
        i = int(bad[0])
        v = x[i][np.argmax(np.abs(x[i]))]
        raise ValueError(
            f"{path}: line {int(lines[i])}: {what} {_num(v)} {unit} (columns {cols}, after the unit) is "
            f"beyond any IMU's range (|x| <= {_num(limit)} {unit}); {bad.size} such row(s): a corrupted row"
            f" or a wrong unit{hint}"
        )


def read_imu_csv(
    path: str | Path,
    accel_unit: str = "g",
    gyro_unit: str = "rad/s",
    time_offset_s: float = 0.0,
    mount: np.ndarray | None = None,
) -> ImuLog:
    """The IMU samples of ``path`` in SI units and the body frame (module docstring).

    ``mount`` is ``C_s^b`` (sensor to body); ``None`` keeps the sensor frame.

    Raises:
        ValueError: text that is not UTF-8, an unreadable line, fewer than 7 columns, a
            non-finite value, non-increasing time, an unknown unit, a specific force whose
            median magnitude is off from gravity by the factor ``g`` (``accel_unit`` says
            ``"m/s^2"`` but the data are in g, or the other way round; any median outside
            0.5-1.5 g after the unit is refused), or a sample beyond :data:`MAX_SPECIFIC_FORCE` /
            :data:`MAX_RATE`; the message names the 1-based line.
    """
    return _read_imu(Path(path), accel_unit, gyro_unit, time_offset_s, mount)[0]


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


#: Time systems RTKLIB may write in the column header instead of GPST.
_OTHER_TIME_SYSTEMS = ("UTC", "JST")


def _pos_rows(path: Path) -> tuple[list[str], list[list[str]], list[int], list[float]]:
    """The column names, the rows' fields, their 1-based lines and times of a ``.pos`` file."""
    names: list[str] | None = None
    rows, lines, times = [], [], []
    for ln, line in enumerate(_read_text(path).splitlines(), 1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("%"):
            tok = s[1:].split()
            if tok and tok[0] == "GPST":
                names = tok[1:]
            elif tok and tok[0] in _OTHER_TIME_SYSTEMS and len(tok) > 2:
                raise ValueError(
                    f"{path}: line {ln}: the times are {tok[0]} (column header '% {tok[0]} ...'); the loader "
                    f"needs GPST: rerun RTKLIB with GPST output (rnx2rtkp without -u; rtkpost / "
                    f"out-timesys = gpst)"
                )
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
    return names, rows, lines, times


def _first_bad(path: Path, lines: np.ndarray, bad: np.ndarray, text: Callable[[int], str]) -> None:
    """Raise naming the first row where ``bad`` holds, with ``text(row)`` saying what is wrong."""
    idx = np.flatnonzero(bad)
    if idx.size:
        raise ValueError(f"{path}: line {int(lines[idx[0]])}: {text(int(idx[0]))}")


def _velocity_from_positions(t: np.ndarray, lla: np.ndarray) -> np.ndarray:
    """NED velocity [m/s] by central differences of the ECEF positions (module docstring)."""
    from navgym.geo import geodetic_to_ecef

    ecef = geodetic_to_ecef(lla[:, 0], lla[:, 1], lla[:, 2])
    v = np.gradient(ecef, t, axis=0)
    sl, cl, sp, cp = np.sin(lla[:, 1]), np.cos(lla[:, 1]), np.sin(lla[:, 0]), np.cos(lla[:, 0])
    n = -sp * cl * v[:, 0] - sp * sl * v[:, 1] + cp * v[:, 2]
    e = -sl * v[:, 0] + cl * v[:, 1]
    d = -cp * cl * v[:, 0] - cp * sl * v[:, 1] - sp * v[:, 2]
    return np.stack([n, e, d], axis=-1)


def _read_pos(path: Path) -> tuple[GnssLog, np.ndarray]:
    """:func:`read_rtklib_pos` and the 1-based line of each epoch."""
    names, rows, lines_list, times = _pos_rows(path)
    missing = [c for c in POS_REQUIRED if c not in names]
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing} (RTKLIB lat/lon/height output with Q)")
    vel_cols = [c for c in POS_VELOCITY if c in names]
    if vel_cols and len(vel_cols) < 3:
        raise ValueError(
            f"{path}: velocity columns {vel_cols} without {[c for c in POS_VELOCITY if c not in names]}; "
            "expected all of vn(m/s) ve(m/s) vu(m/s) or none"
        )
    if not rows:
        raise ValueError(f"{path}: no epochs")
    lines = np.asarray(lines_list, dtype=np.int64)
    d = _float_table(path, rows, lines_list)
    t = np.asarray(times)
    _check_time(path, t, lines, "GNSS")

    def col(name: str) -> np.ndarray:
        return d[:, names.index(name)] if name in names else np.full(len(t), np.nan)

    lat, lon, h, q = col("latitude(deg)"), col("longitude(deg)"), col("height(m)"), col("Q")
    for name, x in (("latitude(deg)", lat), ("longitude(deg)", lon), ("height(m)", h), ("Q", q)):
        _first_bad(path, lines, ~np.isfinite(x), lambda i, n=name, x=x: f"{n} is not a finite number")
    _first_bad(path, lines, np.abs(lat) > 90.0, lambda i: f"latitude {_num(lat[i])} deg outside [-90, 90]")
    _first_bad(
        path, lines, np.abs(lon) > 180.0, lambda i: f"longitude {_num(lon[i])} deg outside [-180, 180]"
    )
    lo, hi = HEIGHT_RANGE_M
    _first_bad(
        path,
        lines,
        (h < lo) | (h > hi),
        lambda i: f"height {_num(h[i])} m outside [{_num(lo)}, {_num(hi)}] (ellipsoidal height in metres)",
    )
    _first_bad(
        path,
        lines,
        ~np.isin(q, Q_FLAGS),
        lambda i: f"Q {_num(q[i])} is not one of RTKLIB's flags 1-6 (an integer: 1 fixed, 2 float, 5 single)",
    )
    sd = np.stack([col("sdn(m)"), col("sde(m)"), col("sdu(m)")], -1)
    _first_bad(
        path,
        lines,
        (sd < 0).any(axis=1) | np.isinf(sd).any(axis=1),
        lambda i: "a standard deviation sdn/sde/sdu is negative or infinite",
    )
    lla = np.stack([np.deg2rad(lat), np.deg2rad(lon), h], -1)
    if vel_cols:
        vel = np.stack([col("vn(m/s)"), col("ve(m/s)"), -col("vu(m/s)")], -1)
        _first_bad(
            path,
            lines,
            ~(np.abs(vel) <= MAX_GNSS_SPEED).all(axis=1),
            lambda i: f"a velocity vn/ve/vu is not finite or beyond {_num(MAX_GNSS_SPEED)} m/s",
        )
    elif t.size < 2:
        vel = np.full((1, 3), np.nan)  # one epoch: nothing to derive a velocity from
    else:
        vel = _velocity_from_positions(t, lla)
    return GnssLog(t, lla, q.astype(np.int64), sd, vel, velocity_from_positions=not vel_cols), lines


def read_rtklib_pos(path: str | Path) -> GnssLog:
    """An RTKLIB ``.pos`` solution (module docstring): times, lat/lon/height, Q, sd, velocities.

    Raises:
        ValueError: text that is not UTF-8, no column header, times in UTC/JST, a required
            column missing (named), a line with too few fields or a field that is not a number,
            non-increasing time, a value out of its range (latitude, longitude, height, Q not an
            integer 1-6, a negative standard deviation, a speed beyond :data:`MAX_GNSS_SPEED`),
            or no epoch; the message names the 1-based line.
    """
    return _read_pos(Path(path))[0]


def _vec3(path: Path, key: str, value: Any) -> np.ndarray:
    ok = isinstance(value, list | tuple) and all(
        isinstance(x, int | float) and not isinstance(x, bool) for x in value
    )
    a = np.asarray(value, dtype=float) if ok else None
    if a is None or a.shape != (3,) or not np.isfinite(a).all():
        raise ValueError(f"{path}: {key} must be a list of 3 finite numbers; got {value!r}")
    return a


def _finite(path: Path, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"{path}: {key} must be a finite number; got {value!r}")
    return float(value)


def _ranged(path: Path, key: str, value: Any) -> float:
    """A sidecar number inside :data:`SIDECAR_RANGES` (0 an exclusive low end)."""
    x = _finite(path, key, value)
    lo, hi, what = SIDECAR_RANGES[key]
    if not ((x > lo if lo == 0.0 else x >= lo) and x <= hi):
        low = f"> {_num(lo)}" if lo == 0.0 else f">= {_num(lo)}"
        raise ValueError(
            f"{path}: {key} = {_num(x)} is not plausible: expected {low} and <= {_num(hi)} ({what})"
        )
    return x


class _Sidecar(NamedTuple):
    imu: dict[str, Any]
    gnss: dict[str, Any]


def _read_sidecar(d: Path) -> tuple[Path, _Sidecar]:
    if not d.exists():
        raise ValueError(
            f"{d}: the recording directory does not exist (expected a directory with imu.csv, gnss.pos "
            f"and {SIDECAR}; see docs/recordings.md)"
        )
    if not d.is_dir():
        raise ValueError(
            f"{d}: not a directory (a recording is a directory with imu.csv, gnss.pos and {SIDECAR})"
        )
    side = d / SIDECAR
    if not side.is_file():
        raise ValueError(f"{d}: no {SIDECAR} sidecar (see docs/recordings.md or navgym.recordings.loader)")
    try:
        cfg = tomllib.loads(_read_text(side))
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{side}: not valid TOML: {e}") from None
    imu_cfg, gnss_cfg = cfg.get("imu"), cfg.get("gnss")
    if not isinstance(imu_cfg, dict) or not isinstance(gnss_cfg, dict):
        raise ValueError(f"{side}: needs the tables [imu] and [gnss]")
    allowed_imu = set(REQUIRED_IMU_KEYS) | set(OPTIONAL_IMU_DEFAULTS)
    allowed_gnss = set(OPTIONAL_GNSS_DEFAULTS)
    for table, allowed, name in ((imu_cfg, allowed_imu, "imu"), (gnss_cfg, allowed_gnss, "gnss")):
        extra = sorted(set(table) - allowed)
        if extra:
            raise ValueError(f"{side}: unknown key(s) {extra} in [{name}] (known: {sorted(allowed)})")
    missing = [k for k in REQUIRED_IMU_KEYS if k not in imu_cfg]
    if missing:
        what = "; ".join(f"{k}: {REQUIRED_IMU_KEYS[k]}" for k in missing)
        raise ValueError(
            f"{side}: [imu] lacks the required key(s) {missing} (no default is right for every recording): "
            f"{what}; see docs/recordings.md"
        )
    return side, _Sidecar({**OPTIONAL_IMU_DEFAULTS, **imu_cfg}, {**OPTIONAL_GNSS_DEFAULTS, **gnss_cfg})


def _q_flags(side: Path, key: str, v: Any) -> tuple[int, ...]:
    if (
        not isinstance(v, list)
        or not v
        or not all(isinstance(x, int) and not isinstance(x, bool) and x in Q_FLAGS for x in v)
    ):
        raise ValueError(f"{side}: {key} must be a non-empty list of RTKLIB Q flags, integers 1-6; got {v!r}")
    return tuple(v)


def read_recording(directory: str | Path | None = None) -> tuple[Recording, RecordingSources]:
    """The recording in ``directory`` read and format-checked, without the plausibility checks.

    :func:`load_recording` adds them; ``navgym recording check`` reports them.

    Raises:
        ValueError: a missing directory, sidecar or file, a malformed file or sidecar key (named),
            or IMU and GNSS logs that do not overlap in time.
    """
    d = PACKAGED if directory is None else Path(directory)
    side, cfg = _read_sidecar(d)
    imu_cfg, gnss_cfg = cfg
    rpy = _vec3(side, "mount_rpy_deg", imu_cfg["mount_rpy_deg"])
    if (np.abs(rpy) > 360.0).any():
        raise ValueError(f"{side}: mount_rpy_deg = {_nums(rpy)} must be angles in [-360, 360] deg")
    mount = euler_to_dcm(*np.deg2rad(rpy))
    lever = _vec3(side, "lever_arm_m", imu_cfg["lever_arm_m"])
    if float(np.linalg.norm(lever)) > MAX_LEVER_ARM_M:
        raise ValueError(
            f"{side}: lever_arm_m = {_nums(lever)} is {_num(round(float(np.linalg.norm(lever)), 3))} m"
            f" long, more than {_num(MAX_LEVER_ARM_M)} m: the lever arm is in metres (5 cm is 0.05)"
        )
    offset = _finite(side, "time_offset_s", imu_cfg["time_offset_s"])
    for key in ("accel_unit", "gyro_unit", "file"):
        if not isinstance(imu_cfg[key], str):
            raise ValueError(f"{side}: {key} must be a string; got {imu_cfg[key]!r}")
    if not isinstance(gnss_cfg["file"], str):
        raise ValueError(f"{side}: file in [gnss] must be a string; got {gnss_cfg['file']!r}")
    numbers = {k: _ranged(side, k, imu_cfg[k]) for k in SIDECAR_RANGES}
    qs = {key: _q_flags(side, key, gnss_cfg[key]) for key in ("fix_q", "truth_q")}
    imu_path, pos_path = d / imu_cfg["file"], d / gnss_cfg["file"]
    for p in (imu_path, pos_path):
        if not p.is_file():
            raise ValueError(f"{side}: the file {p.name!r} it names is not in {d}")
    imu, imu_lines = _read_imu(imu_path, imu_cfg["accel_unit"], imu_cfg["gyro_unit"], offset, mount)
    gnss, gnss_lines = _read_pos(pos_path)
    rec = Recording(
        name=d.name,
        imu=imu,
        gnss=gnss,
        lever_arm=lever,
        mount=mount,
        accel_noise=numbers["accel_noise_ug_per_sqrt_hz"] * 1e-6 * G0,
        gyro_noise=np.deg2rad(numbers["gyro_noise_deg_s_per_sqrt_hz"]),
        accel_bias=numbers["accel_bias_mg"] * 1e-3 * G0,
        gyro_bias=np.deg2rad(numbers["gyro_bias_deg_h"] / 3600.0),
        initial_yaw_deg=numbers["initial_yaw_deg"],
        fix_q=qs["fix_q"],
        truth_q=qs["truth_q"],
    )
    inside = (gnss.t >= imu.t[0]) & (gnss.t <= imu.t[-1])
    if not (inside & rec.fix_epochs).any():
        raise ValueError(
            f"{d}: the IMU ({imu.t[0]:.3f} - {imu.t[-1]:.3f} s GPST) and the GNSS fixes "
            f"({gnss.t[0]:.3f} - {gnss.t[-1]:.3f} s) do not overlap in time (check time_offset_s: "
            f"seconds added to the IMU times to get GPST)"
        )
    if not (inside & rec.truth_epochs).any():
        raise ValueError(f"{d}: no truth epoch (Q in {list(rec.truth_q)}) inside the IMU's time span")
    sources = RecordingSources(
        d, side, imu_path, pos_path, imu_lines, gnss_lines, (rpy[0], rpy[1], rpy[2]),
        imu_cfg["accel_unit"], imu_cfg["gyro_unit"], offset,
    )  # fmt: skip
    return rec, sources


def load_recording(directory: str | Path | None = None) -> Recording:
    """The recording in ``directory`` (default: the packaged walk_0827), checked (module docstring).

    Raises:
        ValueError: a missing directory, sidecar or file, a malformed file or sidecar key, IMU
            and GNSS logs that do not overlap in time (:func:`read_recording`), or a recording
            the plausibility checks find wrong (:func:`navgym.recordings.checks.check_recording`:
            every problem, each with what looks wrong and how to fix it).
    """
    rec, sources = read_recording(directory)
    report = check_recording(rec, sources)
    if report.problems:
        listed = "\n".join(f"  - {p}" for p in report.problems)
        raise ValueError(
            f"{sources.directory}: the recording looks wrong ({len(report.problems)} problem(s); "
            f"'navgym recording check {sources.directory}' prints a summary):\n{listed}"
        )
    return rec
