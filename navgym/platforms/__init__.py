"""Truth generators (batched): land vehicle/ship, quadrotor triangle flights, car-like robot.

Public API (SI units, radians, batch axis first):

* ``Trajectory`` (3-D truth with ideal IMU outputs), ``midpoint_times``, ``query_times``,
  ``nav_state_at``, ``ideal_imu``, ``trajectory_heading``, ``trajectory_ecef``,
  ``replace_episodes``
* quadrotor (seed 001 §2.7a): ``QuadrotorParams``, ``QuadrotorPlan``,
  ``sample_quadrotor_plans``, ``quadrotor_trajectory``, ``quadrotor_imu``, ``quadrotor_leg_lengths``
* land vehicle / ship (seed 000): ``VehicleParams``, ``LAND_VEHICLE``, ``SHIP``,
  ``VehiclePlan``, ``sample_vehicle_plans``, ``vehicle_trajectory``
* car-like robot (seed 001 eq. 77): ``RobotGeometry``, ``RobotParams``, ``RobotPlan``,
  ``RobotTrajectory``, ``robot_derivative``, ``robot_transition``, ``encoder_speed``,
  ``sample_robot_plans``, ``robot_trajectory``
* measurements: ``GPS_RATE_HZ``, ``GLONASS_RATE_HZ``, ``COMPASS_RATE_HZ``, ``schedule_stride``,
  ``measurement_schedule``, ``is_measurement_step``, ``position_fixes``, ``RobotSensorNoise``,
  ``RobotMeasurements``, ``robot_measurements``, ``simulate_robot_measurements``

Every sampler takes one seed or generator per episode: sampling B episodes at once equals B
single-episode draws. Trajectories are closed-form in time, so environments can evaluate them
for a whole episode at reset or step by step (``t`` of shape ``(B, 1)``) with identical values.
"""

from navgym.platforms.measurements import (
    COMPASS_RATE_HZ,
    GLONASS_RATE_HZ,
    GPS_RATE_HZ,
    ROBOT_NOISE_WIDTH,
    RobotMeasurements,
    RobotSensorNoise,
    is_measurement_step,
    measurement_schedule,
    position_fixes,
    robot_measurements,
    schedule_stride,
    simulate_robot_measurements,
)
from navgym.platforms.quadrotor import (
    N_PHASES,
    QuadrotorParams,
    QuadrotorPlan,
    quadrotor_imu,
    quadrotor_leg_lengths,
    quadrotor_trajectory,
    sample_quadrotor_plans,
)
from navgym.platforms.robot import (
    RobotGeometry,
    RobotParams,
    RobotPlan,
    RobotTrajectory,
    encoder_speed,
    robot_derivative,
    robot_trajectory,
    robot_transition,
    sample_robot_plans,
)
from navgym.platforms.trajectory import (
    Trajectory,
    ideal_imu,
    midpoint_times,
    nav_state_at,
    query_times,
    replace_episodes,
    trajectory_ecef,
    trajectory_heading,
)
from navgym.platforms.vehicle import (
    LAND_VEHICLE,
    SHIP,
    VehicleParams,
    VehiclePlan,
    sample_vehicle_plans,
    vehicle_trajectory,
)

__all__ = [
    "Trajectory",
    "ideal_imu",
    "midpoint_times",
    "nav_state_at",
    "query_times",
    "replace_episodes",
    "trajectory_ecef",
    "trajectory_heading",
    "N_PHASES",
    "QuadrotorParams",
    "QuadrotorPlan",
    "sample_quadrotor_plans",
    "quadrotor_trajectory",
    "quadrotor_imu",
    "quadrotor_leg_lengths",
    "VehicleParams",
    "LAND_VEHICLE",
    "SHIP",
    "VehiclePlan",
    "sample_vehicle_plans",
    "vehicle_trajectory",
    "RobotGeometry",
    "RobotParams",
    "RobotPlan",
    "RobotTrajectory",
    "robot_derivative",
    "robot_transition",
    "encoder_speed",
    "sample_robot_plans",
    "robot_trajectory",
    "GPS_RATE_HZ",
    "GLONASS_RATE_HZ",
    "COMPASS_RATE_HZ",
    "schedule_stride",
    "measurement_schedule",
    "is_measurement_step",
    "position_fixes",
    "RobotSensorNoise",
    "RobotMeasurements",
    "ROBOT_NOISE_WIDTH",
    "robot_measurements",
    "simulate_robot_measurements",
]
