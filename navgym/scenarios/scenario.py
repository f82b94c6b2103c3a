"""Frozen descriptions of what degrades in one episode.

A :class:`Scenario` lists time intervals (seconds from the episode start, active on
``start <= t < end``) of:

* full GNSS outages (no measurement at all; Touil & Ghadi 2012, Tab. 1 and Benzerrouk 2014, §2.7a
  "GNSS-denied"),
* partial outages capping the usable satellites to ``max_satellites`` (down to k satellites),
* impulsive noise: the Gaussian mixture of Benzerrouk 2014, eq. 71 with contamination ``eps`` and
  variance ratio ``var_ratio = sigma_2^2 / sigma_1^2`` (50 to 2000 in Benzerrouk 2014, §2.5),
* jamming: extra Gaussian noise ``jam_sigma`` and per-satellite loss probability ``loss_prob``
  (Benzerrouk 2014, §2.7a: chirp jammers "with fatal impact" on GNSS over the flight zone),
* outlier satellites: gross errors of size ``scale`` with probability ``probability`` per step on
  chosen PRNs (Belles et al. 2022's outlier scenario),

and the within-episode events of the v2 tasks (unknown to the filter, several per episode; the
evaluators of :mod:`navgym.scenarios.batch` serve every platform; Robot2d and GpsIns apply all of
them, see their cards and platform modules (GpsIns: a burst is an unmodelled manoeuvre in the INS,
a multipath ``row`` an elevation rank resolved to a satellite); Quadrotor: see its card):

* motion bursts: unmodelled motion, a process-noise burst (Robot2d: wheel slip, a white
  horizontal velocity error ``velocity_sigma`` and yaw-rate error ``yaw_rate_sigma``),
* multipath/NLOS: a persistent non-zero-mean ``bias`` (plus extra noise ``sigma``) on one
  measurement ``row``,
* urban canyons: fewer satellites (``max_satellites``, a partial outage) with the fix noise
  multiplied by ``noise_scale`` and fixes lost with ``loss_prob``,
* jamming ramps: a :class:`Jamming` with ``ramp > 0`` fades in and out instead of switching,

(several full outages per episode are ``outages`` with more than one interval),

plus the elevation mask and the critical flag of Carvalho et al. 1997, §V (50 deg mask, visible satellites
falling from 3 to 2 in a 3600 s run at 1 s; :mod:`navgym.gnss.critical` finds the place/time).
The field names of the noise parameters match :func:`navgym.gnss.make_regime`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from navgym.scenarios.validation import check_nonnegative, check_probability

__all__ = [
    "MAX_PRN",
    "Outage",
    "PartialOutage",
    "ImpulsiveNoise",
    "Jamming",
    "OutlierSatellites",
    "MotionBurst",
    "Multipath",
    "UrbanCanyon",
    "Scenario",
    "CRITICAL_MASK_DEG",
    "CRITICAL_DURATION_S",
    "CRITICAL_DT_S",
    "critical_scenario",
    "check_mask_deg",
]

#: Largest GPS PRN (same as ``navgym.gnss.noise.MAX_PRN``).
MAX_PRN = 32
#: Carvalho et al. 1997, §V: visibility mask of the critical scenario [deg].
CRITICAL_MASK_DEG = 50.0
#: Carvalho et al. 1997, §V: run length [s].
CRITICAL_DURATION_S = 3600.0
#: Carvalho et al. 1997, §V: pseudo-range interval [s].
CRITICAL_DT_S = 1.0


def check_mask_deg(mask_deg: float) -> float:
    """Validate an elevation mask angle: finite and in [0, 90) degrees."""
    m = float(mask_deg)
    if not (math.isfinite(m) and 0.0 <= m < 90.0):
        raise ValueError(f"mask_deg must be in [0, 90) degrees, got {mask_deg!r}")
    return m


def _check_interval(start: float, end: float) -> None:
    s = float(start)
    e = float(end)
    if not (math.isfinite(s) and s >= 0.0):
        raise ValueError(f"start must be a finite time >= 0 s, got {start!r}")
    if math.isnan(e) or e < s:
        raise ValueError(f"end must be >= start (non-negative duration), got start={s}, end={e}")


@dataclass(frozen=True)
class Outage:
    """Full GNSS outage on ``[start, end)`` [s]."""

    start: float
    end: float

    def __post_init__(self) -> None:
        _check_interval(self.start, self.end)

    @property
    def duration(self) -> float:
        """Length [s]."""
        return self.end - self.start


@dataclass(frozen=True)
class PartialOutage(Outage):
    """At most ``max_satellites`` usable satellites on ``[start, end)``."""

    max_satellites: int = 0

    def __post_init__(self) -> None:
        super().__post_init__()
        if int(self.max_satellites) != self.max_satellites or self.max_satellites < 0:
            raise ValueError(f"max_satellites must be an integer >= 0, got {self.max_satellites!r}")


@dataclass(frozen=True)
class ImpulsiveNoise(Outage):
    """Gaussian-mixture measurement noise of Benzerrouk 2014, eq. 71 on ``[start, end)``.

    ``p(x) = (1 - eps) N(0, sigma_1^2) + eps N(0, var_ratio sigma_1^2)``.
    """

    eps: float = 0.1
    var_ratio: float = 100.0

    def __post_init__(self) -> None:
        super().__post_init__()
        check_probability("eps", self.eps)
        if not (math.isfinite(self.var_ratio) and self.var_ratio >= 1.0):
            raise ValueError(f"var_ratio must be a finite ratio >= 1, got {self.var_ratio!r}")


@dataclass(frozen=True)
class Jamming(Outage):
    """Jamming on ``[start, end)``: extra noise ``jam_sigma`` [m], satellite loss ``loss_prob``.

    With ``ramp`` [s] > 0 the jammer's power fades in and out: both ``jam_sigma`` and
    ``loss_prob`` are scaled by :meth:`profile`, which rises linearly from 0 at ``start`` to 1 at
    ``start + ramp``, stays at 1 and falls linearly back to 0 at ``end`` (a triangle peaking at
    ``duration / (2 ramp)`` when ``2 ramp > duration``). ``ramp = 0`` (the default) is a step:
    full strength on the whole interval.
    """

    jam_sigma: float = 20.0
    loss_prob: float = 0.0
    ramp: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        check_nonnegative("jam_sigma", self.jam_sigma)
        check_probability("loss_prob", self.loss_prob)
        check_nonnegative("ramp", self.ramp)

    def profile(self, t: float) -> float:
        """Strength in [0, 1] at time ``t`` [s] (0 outside ``[start, end)``)."""
        if not self.start <= t < self.end:
            return 0.0
        if self.ramp <= 0.0:
            return 1.0
        return min(1.0, (t - self.start) / self.ramp, (self.end - t) / self.ramp)


@dataclass(frozen=True)
class OutlierSatellites(Outage):
    """Gross errors of ``+-scale`` [m] with ``probability`` per step on ``prns``."""

    prns: tuple[int, ...] = ()
    probability: float = 0.2
    scale: float = 100.0

    def __post_init__(self) -> None:
        super().__post_init__()
        prns = tuple(int(p) for p in self.prns)
        if any(p < 1 or p > MAX_PRN for p in prns):
            raise ValueError(f"prns must be PRNs in 1..{MAX_PRN}, got {self.prns!r}")
        object.__setattr__(self, "prns", prns)
        check_probability("probability", self.probability)
        check_nonnegative("scale", self.scale)


@dataclass(frozen=True)
class MotionBurst(Outage):
    """Unmodelled motion on ``[start, end)``: a process-noise burst (Robot2d: wheel slip).

    Every filter step that starts inside the interval adds white errors the filter's ``Q`` does
    not hold: a horizontal velocity error of ``velocity_sigma`` [m/s] per axis (a position error
    of ``velocity_sigma dt`` per step and axis) and a yaw-rate error of ``yaw_rate_sigma`` [rad/s]
    (``yaw_rate_sigma dt`` per step on the heading, which then turns the rest of the path).
    """

    velocity_sigma: float = 1.0
    yaw_rate_sigma: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        check_nonnegative("velocity_sigma", self.velocity_sigma)
        check_nonnegative("yaw_rate_sigma", self.yaw_rate_sigma)


@dataclass(frozen=True)
class Multipath(Outage):
    """Multipath/NLOS on measurement ``row`` on ``[start, end)``: a persistent biased error.

    The row's measurements get ``bias`` [m] (either sign: the mean error) plus zero-mean noise
    of ``sigma`` [m] on top of the sensor's. ``row`` indexes the platform's measurement vector
    (Robot2d: 0 GPS N, 1 GPS E, 2 GLONASS N, 3 GLONASS E). Overlapping segments on one row add
    (biases and variances).
    """

    row: int = 0
    bias: float = 10.0
    sigma: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if isinstance(self.row, bool) or int(self.row) != self.row or self.row < 0:
            raise ValueError(f"row must be an integer >= 0, got {self.row!r}")
        object.__setattr__(self, "row", int(self.row))
        b = float(self.bias)
        if not math.isfinite(b):
            raise ValueError(f"bias must be finite, got {self.bias!r}")
        check_nonnegative("sigma", self.sigma)


@dataclass(frozen=True)
class UrbanCanyon(PartialOutage):
    """Urban canyon on ``[start, end)``: fewer satellites plus more noise.

    At most ``max_satellites`` usable satellites (a partial outage: Robot2d has no fix below 4),
    the fix noise multiplied by ``noise_scale`` >= 1 (geometry and reflections) and each fix lost
    with probability ``loss_prob`` (blockage).
    """

    noise_scale: float = 2.0
    loss_prob: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (math.isfinite(self.noise_scale) and self.noise_scale >= 1.0):
            raise ValueError(f"noise_scale must be a finite factor >= 1, got {self.noise_scale!r}")
        check_probability("loss_prob", self.loss_prob)


def _as_tuple(value, kind: type, name: str) -> tuple:
    items = tuple(value)
    for item in items:
        if not isinstance(item, kind):
            raise ValueError(f"{name} must hold {kind.__name__} items, got {item!r}")
    return items


@dataclass(frozen=True)
class Scenario:
    """What degrades in one episode (immutable, hashable, pinnable with ``reset(options=...)``).

    Attributes:
        duration: Episode length [s] the scenario was drawn for.
        mask_deg: Elevation mask [deg] in [0, 90).
        max_satellites: Receiver channels (rows of the measurement vector) when unconstrained.
        outages: Full GNSS outages.
        partial_outages: Satellite-count caps.
        impulsive: Gaussian-mixture noise periods (Benzerrouk 2014, eq. 71).
        jamming: Jamming periods.
        outliers: Outlier-satellite periods.
        critical: The Carvalho et al. 1997, §V critical 3-to-2 satellite situation (50 deg mask); the
            environment places the receiver and the start time where it happens
            (``navgym.gnss.default_critical_window``).
        bursts: Unmodelled-motion (process-noise) bursts (v2 events).
        multipath: Multipath/NLOS bias segments on measurement rows (v2 events).
        canyons: Urban-canyon segments (v2 events).

    """

    duration: float = 300.0
    mask_deg: float = 10.0
    max_satellites: int = 12
    outages: tuple[Outage, ...] = field(default=())
    partial_outages: tuple[PartialOutage, ...] = field(default=())
    impulsive: tuple[ImpulsiveNoise, ...] = field(default=())
    jamming: tuple[Jamming, ...] = field(default=())
    outliers: tuple[OutlierSatellites, ...] = field(default=())
    critical: bool = False
    bursts: tuple[MotionBurst, ...] = field(default=())
    multipath: tuple[Multipath, ...] = field(default=())
    canyons: tuple[UrbanCanyon, ...] = field(default=())

    def __post_init__(self) -> None:
        d = float(self.duration)
        if not (math.isfinite(d) and d > 0.0):
            raise ValueError(f"duration must be a finite time > 0 s, got {self.duration!r}")
        check_mask_deg(self.mask_deg)
        if int(self.max_satellites) != self.max_satellites or self.max_satellites < 1:
            raise ValueError(f"max_satellites must be an integer >= 1, got {self.max_satellites!r}")
        for name, kind in (
            ("outages", Outage),
            ("partial_outages", PartialOutage),
            ("impulsive", ImpulsiveNoise),
            ("jamming", Jamming),
            ("outliers", OutlierSatellites),
            ("bursts", MotionBurst),
            ("multipath", Multipath),
            ("canyons", UrbanCanyon),
        ):
            object.__setattr__(self, name, _as_tuple(getattr(self, name), kind, name))
            # Intervals are [start, end) and the last epoch is at t = duration, so an interval that
            # lasts to the end of the episode ends after ``duration``; one that starts after it
            # can never happen.
            for i, x in enumerate(getattr(self, name)):
                if x.start >= d:
                    raise ValueError(
                        f"{name}[{i}] starts at {x.start:g} s, not before the scenario's end {d:g} s"
                    )
        object.__setattr__(self, "critical", bool(self.critical))


def critical_scenario(**overrides) -> Scenario:
    """The critical scenario of Carvalho et al. 1997, §V: 3600 s, 50 deg mask, ``critical=True``.

    Args:
        **overrides: Other :class:`Scenario` fields (e.g. added impulsive noise).

    Returns:
        The scenario.

    """
    kw = {"duration": CRITICAL_DURATION_S, "mask_deg": CRITICAL_MASK_DEG, "critical": True}
    kw.update(overrides)
    return Scenario(**kw)
