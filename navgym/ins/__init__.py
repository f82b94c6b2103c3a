"""Inertial navigation: strapdown mechanization, IMU simulation by grade, Carvalho et al. 1997 error model.

Public API (SI units, angles in radians, batch axis first, float64):

* types: ``NavState(lat, lon, h, v_ned, C_b_n)``, ``ImuSample(specific_force, angular_rate)``
* strapdown (Benzerrouk 2014, eq. 3-11 on the rotating Earth): ``make_nav_state``, ``strapdown_step``,
  ``strapdown_integrate``
* inverse mechanization: ``imu_from_kinematics`` (``imu_from_components`` on component arrays)
* IMU errors: ``ImuErrorSpec``, presets ``PERFECT``, ``TACTICAL``, ``CONSUMER_MEMS``,
  ``imu_grade(name)``; ``ImuBias``, ``sample_imu_bias``, ``imu_error_step``, ``imu_error_steps``,
  ``simulate_imu``
* two-axis INS error model (Carvalho et al. 1997, eq. 11-14): ``InsErrorParams``, ``ins_error_transition``,
  ``ins_error_process_noise``, ``receiver_clock_transition``, ``receiver_clock_process_noise``,
  ``gps_ins_transition``, ``gps_ins_process_noise``, ``ins_error_initial_covariance``,
  ``simulate_ins_errors``, ``position_error_to_radians``, ``ins_indicated_position``
* attitude algebra: ``skew``, ``rotation_matrix``, ``rotation_vector``, ``euler_to_dcm``, ``yaw_to_dcm``,
  ``dcm_to_euler``, ``dcm_to_yaw``, ``orthonormalize``; frame rates ``earth_rate_ned``,
  ``transport_rate_ned``, ``gravity_ned``
"""

from navgym.ins.attitude import (
    dcm_to_euler,
    dcm_to_yaw,
    euler_to_dcm,
    orthonormalize,
    rotation_matrix,
    rotation_vector,
    skew,
    yaw_to_dcm,
)
from navgym.ins.error_model import (
    CLOCK_A,
    CLOCK_SIGMA_W,
    InsErrorParams,
    gps_ins_process_noise,
    gps_ins_transition,
    ins_error_initial_covariance,
    ins_error_process_noise,
    ins_error_transition,
    ins_indicated_position,
    position_error_to_radians,
    receiver_clock_process_noise,
    receiver_clock_transition,
    simulate_ins_errors,
)
from navgym.ins.frame_rates import HomeFrame, earth_rate_ned, gravity_ned, home_frame, transport_rate_ned
from navgym.ins.imu_grades import (
    CONSUMER_MEMS,
    IMU_GRADES,
    PERFECT,
    TACTICAL,
    ImuErrorSpec,
    imu_grade,
)
from navgym.ins.imu_simulator import (
    IMU_NOISE_WIDTH,
    ImuBias,
    imu_bias_walks,
    imu_error_step,
    imu_error_steps,
    sample_imu_bias,
    simulate_imu,
)
from navgym.ins.inverse_mechanization import imu_from_components, imu_from_kinematics
from navgym.ins.strapdown import make_nav_state, strapdown_integrate, strapdown_step
from navgym.ins.types import ImuSample, NavState

__all__ = [
    "NavState",
    "ImuSample",
    "make_nav_state",
    "strapdown_step",
    "strapdown_integrate",
    "imu_from_components",
    "imu_from_kinematics",
    "ImuErrorSpec",
    "PERFECT",
    "TACTICAL",
    "CONSUMER_MEMS",
    "IMU_GRADES",
    "imu_grade",
    "IMU_NOISE_WIDTH",
    "ImuBias",
    "sample_imu_bias",
    "imu_bias_walks",
    "imu_error_step",
    "imu_error_steps",
    "simulate_imu",
    "InsErrorParams",
    "CLOCK_A",
    "CLOCK_SIGMA_W",
    "ins_error_transition",
    "ins_error_process_noise",
    "receiver_clock_transition",
    "receiver_clock_process_noise",
    "gps_ins_transition",
    "gps_ins_process_noise",
    "ins_error_initial_covariance",
    "simulate_ins_errors",
    "position_error_to_radians",
    "ins_indicated_position",
    "skew",
    "rotation_matrix",
    "rotation_vector",
    "euler_to_dcm",
    "yaw_to_dcm",
    "dcm_to_euler",
    "dcm_to_yaw",
    "orthonormalize",
    "earth_rate_ned",
    "HomeFrame",
    "home_frame",
    "transport_rate_ned",
    "gravity_ned",
]
