"""Plausibility checks of a recording: data that parse but cannot be right.

:func:`check_recording` runs on a recording read by :func:`navgym.recordings.loader.read_recording`
and returns a :class:`RecordingCheck`: a summary (duration, rates, gaps, solution quality, the
mount's fitted residual, the gyro against the GNSS heading rate) and the problems found, each
saying what looks wrong and how to fix it. :func:`~navgym.recordings.loader.load_recording`
refuses a recording with problems; ``navgym recording check DIR`` prints the report.

The checks:

* **Mount against gravity.** While still (GNSS speed below :data:`STILL_SPEED_MS`, at least
  :data:`MIN_STILL_S` of IMU samples; else over the whole recording, where a land vehicle's
  accelerations average out) the mean body-frame specific force points up: ``f^b ~ (0, 0, -g)``
  (Groves 2013, §5.6.2, levelling). Its angle from the body's up axis is the mount's fitted
  residual; above :data:`MAX_TILT_DEG` the mount is refused (a roll of 180 deg dropped, angles
  in radians, axes swapped).
* **Gyro against the GNSS heading rate.** Where the antenna moves faster than
  :data:`HEADING_SPEED_MS`, the heading rate from the GNSS velocity (central differences of
  ``atan2(v_e, v_n)``) is compared with the rate about the measured vertical (the gyro
  projected on the still specific force: independent of the mount), averaged over the same
  interval, for time lags within :data:`LAG_SEARCH_S` (at most half the recording). The best
  lag must lie within :data:`MAX_LAG_S` (a UTC/GPST mix shifts it by the leap seconds,
  :data:`LEAP_SECONDS_NOW`; an offset in ms by a factor 1000), the correlation must be
  positive (else the axes turn the wrong way) and the regression slope within
  :data:`GYRO_SCALE_RANGE` (``gyro_unit = "deg/s"`` on rad/s data gives 1/57.3). A recording
  that turns but whose gyro follows the heading at no lag (best correlation below
  :data:`NO_CORRELATION`) is refused too. Not checked (and said so) with fewer than
  :data:`MIN_TURN_EPOCHS` usable epochs, too few turns (RMS heading rate below
  :data:`MIN_TURN_RATE`) or a best correlation between :data:`NO_CORRELATION` and
  :data:`MIN_CORRELATION` (a noisy heading).
* **IMU gaps and time jumps.** An interval longer than :data:`IMU_GAP_FACTOR` times the median
  and than :data:`IMU_GAP_MIN_S`: the replay interpolates the samples linearly, so every episode
  window across it would be wrong; it is refused naming both lines.
* **GNSS epoch grid.** Epochs on a regular grid of the median interval (within
  :data:`GNSS_GRID_TOLERANCE_S`; missing epochs are fine), as the replay needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

if TYPE_CHECKING:  # the loader runs these checks: no import back at run time
    from navgym.recordings.loader import Recording, RecordingSources

#: Speed [m/s] below which a GNSS epoch counts as still; seconds of still IMU samples needed.
STILL_SPEED_MS = 0.2
MIN_STILL_S = 2.0
#: Largest angle [deg] between the mean body-frame specific force and the body's up axis.
MAX_TILT_DEG = 25.0
#: Horizontal speed [m/s] above which the GNSS velocity gives a heading.
HEADING_SPEED_MS = 0.5
#: Usable epochs, RMS heading rate [rad/s] and correlation needed to check the gyro.
MIN_TURN_EPOCHS = 20
MIN_TURN_RATE = 0.05
MIN_CORRELATION = 0.5
#: Below this best correlation a turning recording's gyro does not follow its heading at all.
NO_CORRELATION = 0.3
#: Largest time lag [s] accepted between the gyro and the GNSS heading rate; lags searched, step.
MAX_LAG_S = 1.0
LAG_SEARCH_S = 120.0
LAG_COARSE_STEP_S = 0.25
LAG_STEP_S = 0.05
#: Accepted slope of the gyro's vertical rate against the GNSS heading rate.
GYRO_SCALE_RANGE = (0.5, 2.0)
#: An IMU interval is a gap above this many median intervals and above this many seconds.
IMU_GAP_FACTOR = 10.0
IMU_GAP_MIN_S = 0.1
#: Tolerance [s] of the GNSS epochs on their grid.
GNSS_GRID_TOLERANCE_S = 0.01
#: Leap seconds GPST - UTC in recent years (the hint of a UTC/GPST mix).
LEAP_SECONDS_NOW = 18


class ImuGap(NamedTuple):
    """An IMU interval longer than a gap (module docstring)."""

    start_s: float  #: GPST of the sample before [s]
    end_s: float  #: GPST of the sample after [s]
    line_before: int  #: 1-based line of the sample before
    line_after: int  #: 1-based line of the sample after


class HeadingFit(NamedTuple):
    """The gyro's vertical rate against the GNSS heading rate (module docstring)."""

    gyro_scale: float  #: regression slope (1 when units and axes are right)
    lag_s: float  #: the IMU's turns come this much later than the GNSS heading's [s]
    correlation: float  #: at that lag
    epochs: int  #: epochs used


class RecordingCheck(NamedTuple):
    """Summary and problems of a recording (module docstring)."""

    name: str
    directory: str
    imu_samples: int
    imu_duration_s: float
    imu_rate_hz: float
    imu_max_interval_s: float
    imu_gaps: tuple[ImuGap, ...]
    gnss_epochs: int
    gnss_duration_s: float
    gnss_rate_hz: float
    gnss_missing_epochs: int
    q_counts: dict[int, int]
    fix_share: float  #: share of epochs with Q in fix_q
    truth_share: float  #: share of epochs with Q in truth_q
    velocity_from_positions: bool
    still_s: float  #: seconds of still IMU samples the gravity check used (0: the whole recording)
    specific_force_body: tuple[float, float, float]  #: mean f^b [m/s^2] of the gravity check
    mount_residual_deg: float  #: angle of that mean from the body's up axis
    heading: HeadingFit | None  #: None: not checked (``heading_note`` says why)
    heading_note: str
    problems: tuple[str, ...]


def _f(x: float, digits: int = 3) -> str:
    return f"{float(x):.{digits}f}"


def _still_mask(rec: Recording) -> np.ndarray:
    """IMU samples nearest a GNSS epoch (within half an interval) whose speed is still."""
    g, t = rec.gnss, rec.imu.t
    step = float(np.median(np.diff(g.t))) if g.t.size > 1 else 1.0
    still = np.linalg.norm(g.vel_ned, axis=1) < STILL_SPEED_MS
    k = np.clip(np.searchsorted(g.t, t), 1, max(g.t.size - 1, 1))
    k = np.where(np.abs(t - g.t[k - 1]) <= np.abs(t - g.t[k]), k - 1, k) if g.t.size > 1 else np.zeros_like(k)
    return still[k] & (np.abs(t - g.t[k]) <= 0.5 * step)


def _mount_problem(rec: Recording, src: RecordingSources, f_mean: np.ndarray, tilt: float, basis: str) -> str:
    f_s = rec.mount.T @ f_mean
    k = int(np.argmax(np.abs(f_s)))
    up = f"{'+' if f_s[k] > 0 else '-'}{'xyz'[k]}"
    rpy = [round(float(x), 6) for x in src.mount_rpy_deg]
    text = (
        f"mount: the specific force {basis} points {_f(tilt, 1)} deg from the body's up axis (mean f^b = "
        f"({_f(f_mean[0], 2)}, {_f(f_mean[1], 2)}, {_f(f_mean[2], 2)}) m/s^2; at rest it is about "
        f"(0, 0, -9.8) with z down), so mount_rpy_deg = {rpy} does not turn the sensor onto the body. "
        f"In the sensor frame it points along {up}: the sensor's {up} axis points up. Set mount_rpy_deg to "
        "the roll, pitch, yaw in degrees of the sensor axes in the body frame (x forward, y right, z down), "
        "e.g. a roll of 180 turns a z-up sensor onto the z-down body (docs/recordings.md)"
    )
    r = np.asarray(src.mount_rpy_deg, float)
    if np.all(np.abs(r) <= 2 * np.pi + 1e-6) and np.any(r != np.round(r)):
        deg = [round(float(x), 3) for x in np.rad2deg(r)]
        text += f"; the angles look like radians: in degrees they are {deg}"
    return text


def _heading_rate(rec: Recording) -> tuple[np.ndarray, np.ndarray, float]:
    """Epoch times, GNSS heading rates [rad/s] (central differences) and the epoch interval."""
    g = rec.gnss
    if g.t.size < 3:
        return np.zeros(0), np.zeros(0), 1.0
    step = float(np.median(np.diff(g.t)))
    psi = np.arctan2(g.vel_ned[:, 1], g.vel_ned[:, 0])
    moving = np.hypot(g.vel_ned[:, 0], g.vel_ned[:, 1]) > HEADING_SPEED_MS
    dpsi = np.angle(np.exp(1j * (psi[2:] - psi[:-2])))
    span = g.t[2:] - g.t[:-2]
    ok = moving[2:] & moving[1:-1] & moving[:-2] & (span <= 2.5 * step)
    return g.t[1:-1][ok], (dpsi / span)[ok], step


def _lag_fit(
    te: np.ndarray,
    rate: np.ndarray,
    step: float,
    t: np.ndarray,
    cum: np.ndarray,
    gaps: tuple[ImuGap, ...],
    lag: float,
) -> tuple[float, float, int]:
    """Correlation, slope and epochs of the gyro's mean vertical rate ``lag`` later against ``rate``.

    The gyro is averaged over each epoch's central-difference interval (``cum``: its integral
    over ``t``); intervals outside the IMU or over a gap are left out. NaN when too few remain.
    """
    a, b = te - step + lag, te + step + lag
    ok = (a >= t[0]) & (b <= t[-1])
    for gap in gaps:
        ok &= (b <= gap.start_s) | (a >= gap.end_s)
    n = int(ok.sum())
    if n < MIN_TURN_EPOCHS:
        return np.nan, np.nan, n
    gyro = (np.interp(b[ok], t, cum) - np.interp(a[ok], t, cum)) / (b[ok] - a[ok])
    x = rate[ok]
    if gyro.std() == 0 or x.std() == 0:
        return np.nan, np.nan, n
    return float(np.corrcoef(x, gyro)[0, 1]), float(x @ gyro / (x @ x)), n


def _fit_heading(
    rec: Recording, down: np.ndarray, gaps: tuple[ImuGap, ...] = ()
) -> tuple[HeadingFit | None, str]:
    """The gyro's rate about ``down`` against the GNSS heading rate (module docstring).

    Lags are searched in steps of :data:`LAG_COARSE_STEP_S` over ``LAG_SEARCH_S`` (at most half
    the recording), then in steps of :data:`LAG_STEP_S` around the best. The note says why the
    fit is None (not checked).
    """
    te, rate, step = _heading_rate(rec)
    if te.size < MIN_TURN_EPOCHS:
        return (
            None,
            f"not checked: {te.size} epochs moving faster than {HEADING_SPEED_MS} m/s"
            f" (need {MIN_TURN_EPOCHS})",
        )
    rms = float(np.sqrt(np.mean(rate**2)))
    if rms < MIN_TURN_RATE:
        return None, f"not checked: too few turns (RMS heading rate {_f(rms, 4)} rad/s < {MIN_TURN_RATE})"
    t = rec.imu.t
    w = rec.imu.gyro @ down
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
    reach = min(LAG_SEARCH_S, max(MAX_LAG_S + 1.0, 0.5 * float(t[-1] - t[0])))
    coarse = np.arange(-reach, reach + 1e-9, LAG_COARSE_STEP_S)
    fits = [_lag_fit(te, rate, step, t, cum, gaps, lag) for lag in coarse]
    corr = np.array([f[0] for f in fits])
    if not np.isfinite(corr).any():
        return None, "not checked: the IMU and the moving GNSS epochs overlap too little"
    center = coarse[int(np.nanargmax(np.abs(corr)))]
    fine = center + np.arange(-LAG_COARSE_STEP_S, LAG_COARSE_STEP_S + 1e-9, LAG_STEP_S)
    fine_fits = [
        (abs(c) if np.isfinite(c) else -1.0, lag, c, s, n)
        for lag in fine
        for c, s, n in [_lag_fit(te, rate, step, t, cum, gaps, lag)]
    ]
    _, lag, c, s, n = max(fine_fits, key=lambda f: f[0])
    fit = HeadingFit(float(s), float(lag), float(c), int(n))
    if abs(fit.correlation) < NO_CORRELATION:
        return None, (
            f"gyro: the recording turns (RMS heading rate {_f(rms, 3)} rad/s over {fit.epochs} epochs) but "
            f"the gyro's rate about the vertical follows the GNSS heading rate at no time lag within "
            f"{_f(reach, 0)} s (best correlation {_f(fit.correlation, 2)}): time_offset_s is off by more "
            "than that (in seconds, not ms?), or columns 4-6 are not the angular rate"
        )
    if abs(fit.correlation) < MIN_CORRELATION:
        return None, (
            f"not checked: the gyro's vertical rate and the GNSS heading rate correlate at most "
            f"{_f(fit.correlation, 2)} (lag {_f(fit.lag_s, 2)} s; RMS heading rate {_f(rms, 3)} rad/s)"
        )
    return fit, ""


def _heading_problems(fit: HeadingFit, src: RecordingSources) -> list[str]:
    out = []
    if fit.correlation < 0:
        out.append(
            f"gyro: the rate about the vertical turns against the GNSS heading (correlation "
            f"{_f(fit.correlation, 2)}): a gyro axis has the wrong sign, or the gyro columns are in another "
            "order than x, y, z of the accelerometer"
        )
    if abs(fit.lag_s) > MAX_LAG_S:
        out.append(
            f"time: the IMU's turns match the GNSS heading rate {_f(abs(fit.lag_s), 2)} s "
            f"{'later' if fit.lag_s > 0 else 'earlier'} (correlation {_f(fit.correlation, 2)}): "
            f"time_offset_s = {src.time_offset_s:g} looks off by about that much (try about "
            f"{src.time_offset_s - fit.lag_s:.1f}; a GNSS velocity may itself lag by a few tenths of a "
            f"second). A UTC/GPST mix is off by the leap seconds, {LEAP_SECONDS_NOW} s since 2017; "
            "time_offset_s is in seconds, not ms"
        )
    lo, hi = GYRO_SCALE_RANGE
    s = abs(fit.gyro_scale)
    if not lo <= s <= hi:
        hint = ""
        if lo <= s * 180.0 / np.pi <= hi:
            hint = f' (they look like rad/s read as deg/s: gyro_unit = "{src.gyro_unit}" should be "rad/s")'
        elif lo <= s * np.pi / 180.0 <= hi:
            hint = f' (they look like deg/s read as rad/s: gyro_unit = "{src.gyro_unit}" should be "deg/s")'
        out.append(
            f"gyro: the rates about the vertical are {s:.3g} times the GNSS heading rate (expected about 1, "
            f"{lo}-{hi}){hint}"
        )
    return out


def _imu_gaps(rec: Recording, src: RecordingSources) -> tuple[tuple[ImuGap, ...], float]:
    t = rec.imu.t
    if t.size < 2:
        return (), 0.0
    dt = np.diff(t)
    threshold = max(IMU_GAP_MIN_S, IMU_GAP_FACTOR * float(np.median(dt)))
    gaps = tuple(
        ImuGap(float(t[i]), float(t[i + 1]), int(src.imu_lines[i]), int(src.imu_lines[i + 1]))
        for i in np.flatnonzero(dt > threshold)
    )
    return gaps, threshold


def _gap_problems(gaps: tuple[ImuGap, ...], threshold: float, src: RecordingSources) -> list[str]:
    out = []
    for gap in gaps[:3]:
        out.append(
            f"IMU gap: {src.imu_path.name} jumps {_f(gap.end_s - gap.start_s)} s from line "
            f"{gap.line_before} ({_f(gap.start_s)} s GPST) to line {gap.line_after} ({_f(gap.end_s)} s): "
            f"lost samples or a jump of the timestamps (an interval above {_f(threshold)} s). The replay "
            "would interpolate across it and every window over it would be wrong: split the recording into "
            "two directories at the gap, or fix the timestamps"
        )
    if len(gaps) > 3:
        out.append(f"IMU gap: {len(gaps) - 3} more gap(s) after these")
    return out


def _grid(rec: Recording, src: RecordingSources) -> tuple[float, int, list[str]]:
    """The GNSS epoch interval, the epochs missing from its grid and the grid's problems."""
    t = rec.gnss.t
    if t.size < 2:
        return 0.0, 0, []
    step = float(np.median(np.diff(t)))
    k = np.rint((t - t[0]) / step)
    off = np.abs(t - t[0] - k * step)
    bad = np.flatnonzero(off > GNSS_GRID_TOLERANCE_S)
    problems = []
    if bad.size:
        i = int(bad[0])
        problems.append(
            f"GNSS epochs: line {int(src.gnss_lines[i])} of {src.pos_path.name} ({_f(t[i])} s GPST) is "
            f"{_f(off[i])} s off the grid of the median interval {step:g} s ({bad.size} such epoch(s)): "
            "the replay needs epochs on one grid (missing epochs are fine); check for a time jump"
        )
    missing = int(k[-1]) + 1 - t.size
    return step, missing, problems


def check_recording(rec: Recording, sources: RecordingSources) -> RecordingCheck:
    """The plausibility checks of ``rec`` (module docstring), with the summary of the recording."""
    imu, g = rec.imu, rec.gnss
    problems: list[str] = []
    dt_imu = np.diff(imu.t)
    gaps, threshold = _imu_gaps(rec, sources)
    problems += _gap_problems(gaps, threshold, sources)
    step, missing, grid_problems = _grid(rec, sources)
    problems += grid_problems

    still = _still_mask(rec)
    median_dt = float(np.median(dt_imu)) if dt_imu.size else 0.0
    still_s = float(still.sum()) * median_dt
    if still_s >= MIN_STILL_S:
        f_mean, basis = imu.accel[still].mean(axis=0), f"while still ({_f(still_s, 1)} s)"
    else:
        f_mean, basis, still_s = (
            imu.accel.mean(axis=0),
            "averaged over the whole recording (no still period)",
            0.0,
        )
    norm = float(np.linalg.norm(f_mean))
    tilt = float(np.degrees(np.arccos(np.clip(-f_mean[2] / norm, -1.0, 1.0)))) if norm > 0 else 180.0
    if tilt > MAX_TILT_DEG:
        problems.append(_mount_problem(rec, sources, f_mean, tilt, basis))

    down = -f_mean / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
    fit, note = _fit_heading(rec, down, gaps)
    if fit is not None:
        problems += _heading_problems(fit, sources)
    elif note.startswith("gyro:"):
        problems.append(note)

    qs, counts = np.unique(g.q, return_counts=True)
    return RecordingCheck(
        name=rec.name,
        directory=str(sources.directory),
        imu_samples=int(imu.t.size),
        imu_duration_s=float(imu.t[-1] - imu.t[0]),
        imu_rate_hz=1.0 / median_dt if median_dt > 0 else 0.0,
        imu_max_interval_s=float(dt_imu.max()) if dt_imu.size else 0.0,
        imu_gaps=gaps,
        gnss_epochs=int(g.t.size),
        gnss_duration_s=float(g.t[-1] - g.t[0]),
        gnss_rate_hz=1.0 / step if step > 0 else 0.0,
        gnss_missing_epochs=missing,
        q_counts={int(q): int(c) for q, c in zip(qs, counts, strict=True)},
        fix_share=float(rec.fix_epochs.mean()),
        truth_share=float(rec.truth_epochs.mean()),
        velocity_from_positions=bool(g.velocity_from_positions),
        still_s=still_s,
        specific_force_body=(float(f_mean[0]), float(f_mean[1]), float(f_mean[2])),
        mount_residual_deg=tilt,
        heading=fit,
        heading_note=note,
        problems=tuple(problems),
    )


_Q_NAMES = {1: "fixed", 2: "float", 3: "SBAS", 4: "DGPS", 5: "single", 6: "PPP"}


def format_report(check: RecordingCheck, fix_q: tuple[int, ...], truth_q: tuple[int, ...]) -> str:
    """The summary of ``check`` as text (``navgym recording check``)."""
    n = max(check.gnss_epochs, 1)
    quality = ", ".join(
        f"Q{q} {_Q_NAMES.get(q, '?')} {100.0 * c / n:.1f} %" for q, c in sorted(check.q_counts.items())
    )
    fb = check.specific_force_body
    basis = f"still {check.still_s:.1f} s" if check.still_s > 0 else "whole recording, no still period"
    if check.heading is None:
        heading = check.heading_note
    else:
        h = check.heading
        heading = (
            f"scale {h.gyro_scale:.3f}, lag {h.lag_s:.2f} s, correlation {h.correlation:.2f}"
            f" ({h.epochs} epochs)"
        )
    gaps = (
        "none"
        if not check.imu_gaps
        else f"{len(check.imu_gaps)}, longest {max(g.end_s - g.start_s for g in check.imu_gaps):.3f} s"
    )
    rows = [
        f"recording {check.name} ({check.directory})",
        f"  IMU            {check.imu_duration_s:.1f} s, {check.imu_samples} samples,"
        f" {check.imu_rate_hz:.1f} Hz, largest interval {1e3 * check.imu_max_interval_s:.1f} ms",
        f"  IMU gaps       {gaps}",
        f"  GNSS           {check.gnss_duration_s:.1f} s, {check.gnss_epochs} epochs,"
        f" {check.gnss_rate_hz:.3g} Hz, {check.gnss_missing_epochs} missing from the grid",
        f"  solution       {quality}; fixes (Q in {list(fix_q)}) {100 * check.fix_share:.1f} %,"
        f" truth (Q in {list(truth_q)}) {100 * check.truth_share:.1f} %",
        "  velocity       "
        + (
            "derived from the positions (no vn/ve/vu columns)"
            if check.velocity_from_positions
            else "vn/ve/vu columns"
        ),
        f"  mount          residual {check.mount_residual_deg:.1f} deg (gravity from the body's up axis;"
        f" {basis}; mean f^b = ({fb[0]:.2f}, {fb[1]:.2f}, {fb[2]:.2f}) m/s^2)",
        f"  gyro vs GNSS   {heading}",
    ]
    if check.problems:
        rows.append(f"  result         {len(check.problems)} problem(s):")
        rows += [f"    - {p}" for p in check.problems]
    else:
        rows.append("  result         OK")
    return "\n".join(rows)
