"""IMU error specifications by grade: turn-on bias, white noise (ARW/VRW), bias random walk.

Benzerrouk 2014, eq. 2 and 5 write the sensor outputs as truth minus an error, and eq. 10 gives the
error a covariance; the numbers are not in that work, so the presets below come from public
sources (all values 1-sigma, per axis):

=================  =========================  =========================  ==========================
quantity           TACTICAL                   CONSUMER_MEMS              unit in the spec
=================  =========================  =========================  ==========================
accel bias         1 mg  [1]                  1 mg  [2]                  m/s^2
accel noise (VRW)  0.065 ft/s/sqrt(h)  [1]    70 ug/sqrt(Hz)  [3]        m/s^2/sqrt(Hz) = m/s/sqrt(s)
gyro bias          1 deg/h  [1]               0.1 deg/s = 360 deg/h [2]  rad/s
gyro noise (ARW)   0.125 deg/sqrt(h)  [1]     0.0038 deg/s/sqrt(Hz) [3]  rad/s/sqrt(Hz) = rad/sqrt(s)
bias random walk   turn-on bias / 60 [4]      turn-on bias / 60 [4]      (unit of bias)/sqrt(s)
=================  =========================  =========================  ==========================

[1] Honeywell HG1700-AG58 brochure, as tabulated in NavToolkit's ``hg1700_model``
    (IS4S NavToolkit, ``navtk::filtering::hg1700_model``).
[2] El-Sheimy & Youssef, "Inertial sensors technologies for navigation applications: state of the
    art and future trends", Satellite Navigation 1:2 (2020), Table 1, commercial (automotive)
    grade: gyro drift 0.1 deg/s, accelerometer bias 100-1000 ug (upper end taken). The same table
    gives tactical grade 1-10 deg/h and 1-5 mg, consistent with [1]; the two grades therefore
    differ mainly by their gyros (360x), which dominate free-inertial drift.
[3] The project's recorded consumer MEMS IMU, ``data/recorded/walk_0827`` (rtklibexplorer
    GNSS_IMU walk_config: gyro noise 0.0038 deg/s/sqrt(Hz), accel noise 70 ug/sqrt(Hz)).
[4] Not on the sheets; chosen so that the in-run bias wanders by its turn-on 1-sigma value in one
    hour (sigma_walk * sqrt(3600 s) = sigma_bias), i.e. a rate random walk of that size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from navgym.scenarios.validation import check_nonnegative

__all__ = ["ImuErrorSpec", "PERFECT", "TACTICAL", "CONSUMER_MEMS", "IMU_GRADES", "imu_grade"]

G0 = 9.80665  # standard gravity [m/s^2], for mg and ug conversions
DEG = math.pi / 180.0
_FT = 0.3048


@dataclass(frozen=True)
class ImuErrorSpec:
    """Per-axis 1-sigma error parameters of a triad of accelerometers and gyros (SI units).

    The simulated sample error over ``[t_k, t_k + dt]`` is ``b_k + sigma_n / sqrt(dt) n_k`` with
    ``b_{k+1} = b_k + sigma_w sqrt(dt) w_k``, ``b_0 ~ N(0, sigma_b^2)``, ``n, w ~ N(0, 1)``.

    Attributes:
        name: Label.
        accel_bias: Turn-on accelerometer bias sigma_b [m/s^2].
        accel_noise: Accelerometer white-noise density (VRW) sigma_n [m/s^2/sqrt(Hz)].
        accel_bias_walk: Accelerometer bias random walk sigma_w [m/s^2/sqrt(s)].
        gyro_bias: Turn-on gyro bias [rad/s].
        gyro_noise: Gyro white-noise density (ARW) [rad/s/sqrt(Hz)].
        gyro_bias_walk: Gyro bias random walk [rad/s/sqrt(s)].

    """

    name: str
    accel_bias: float
    accel_noise: float
    accel_bias_walk: float
    gyro_bias: float
    gyro_noise: float
    gyro_bias_walk: float

    def __post_init__(self) -> None:
        for field in (
            "accel_bias",
            "accel_noise",
            "accel_bias_walk",
            "gyro_bias",
            "gyro_noise",
            "gyro_bias_walk",
        ):
            check_nonnegative(field, getattr(self, field))

    @classmethod
    def from_datasheet(
        cls,
        name: str,
        *,
        accel_bias_mg: float,
        vrw_m_s_per_sqrt_h: float,
        gyro_bias_deg_h: float,
        arw_deg_per_sqrt_h: float,
        walk_per_bias: float = 1.0 / 60.0,
    ) -> ImuErrorSpec:
        """Build a spec from datasheet units (mg, m/s/sqrt(h), deg/h, deg/sqrt(h)).

        Args:
            name: Label.
            accel_bias_mg: Accelerometer bias [mg].
            vrw_m_s_per_sqrt_h: Velocity random walk [m/s/sqrt(h)].
            gyro_bias_deg_h: Gyro bias [deg/h].
            arw_deg_per_sqrt_h: Angle random walk [deg/sqrt(h)].
            walk_per_bias: Bias random walk as a fraction of the bias per sqrt(s).

        Returns:
            The spec in SI units.

        """
        ab = accel_bias_mg * 1e-3 * G0
        gb = gyro_bias_deg_h * DEG / 3600.0
        return cls(
            name=name,
            accel_bias=ab,
            accel_noise=vrw_m_s_per_sqrt_h / 60.0,
            accel_bias_walk=ab * walk_per_bias,
            gyro_bias=gb,
            gyro_noise=arw_deg_per_sqrt_h * DEG / 60.0,
            gyro_bias_walk=gb * walk_per_bias,
        )


#: Error-free IMU.
PERFECT = ImuErrorSpec("perfect", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

#: Tactical grade (Honeywell HG1700-AG58 class), see the module table.
TACTICAL = ImuErrorSpec.from_datasheet(
    "tactical",
    accel_bias_mg=1.0,
    vrw_m_s_per_sqrt_h=0.065 * _FT,
    gyro_bias_deg_h=1.0,
    arw_deg_per_sqrt_h=0.125,
)

#: Consumer MEMS grade, see the module table.
CONSUMER_MEMS = ImuErrorSpec.from_datasheet(
    "consumer_mems",
    accel_bias_mg=1.0,
    vrw_m_s_per_sqrt_h=70e-6 * G0 * 60.0,
    gyro_bias_deg_h=0.1 * 3600.0,
    arw_deg_per_sqrt_h=0.0038 * 60.0,
)

#: Presets by name.
IMU_GRADES: dict[str, ImuErrorSpec] = {s.name: s for s in (PERFECT, TACTICAL, CONSUMER_MEMS)}


def imu_grade(name: str) -> ImuErrorSpec:
    """Return a preset by name (``"perfect"``, ``"tactical"``, ``"consumer_mems"``).

    Raises:
        ValueError: If ``name`` is unknown.

    """
    try:
        return IMU_GRADES[name]
    except KeyError:
        raise ValueError(f"name must be one of {sorted(IMU_GRADES)}, got {name!r}") from None
