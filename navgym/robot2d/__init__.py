"""Robot2d: a car-like robot with wheel encoder, compass, GPS and GLONASS (Benzerrouk 2014, eq. 77).

One estimation problem, one folder: ``robot`` (kinematics and truth), ``sensors`` (sensor
schedules and readings), ``models`` (odometry transition, fix/compass model), ``platform`` (the
:class:`~navgym.envs.protocols.Platform`) and ``env`` (the environment classes and card).
"""
