"""Quadrotor: "return to home" INS/GNSS flights of a quadrotor UAV (Benzerrouk 2014, §2.7a).

One estimation problem, one folder: ``flight`` (truth), ``models`` (preintegrated strapdown
transition and GNSS fix model), ``imu_kernel`` (compiled IMU simulation), ``platform`` (the
:class:`~navgym.envs.protocols.Platform`) and ``env`` (the environment classes and card).
"""
