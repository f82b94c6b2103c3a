"""Jpa: GNSS joint position and attitude with a multi-antenna receiver (Belles et al. 2022, §5).

One estimation problem, one folder: ``models`` (the DD observation model, the attitude-manifold
error-state filter's transition and reset, the study's simulation; shared with
``experiments.robust_jpa``), ``platform`` (the :class:`~navgym.envs.protocols.Platform`) and
``env`` (the environment classes and card; registered at v2 only).
"""
