"""Pedestrian's registry entries (Benzerrouk 2014, §2.7c).

The v2 ids are made by :mod:`navgym.pedestrian.env`, the v3 ids by :mod:`navgym.pedestrian.env_v3`
(the v2 episodes with the receiver's and the foot IMU's context). The Quadrotor's strapdown
EKF with zero-velocity updates and GPS/GLONASS fixes; defaults of a v1 id with the v2 changes.
:mod:`navgym.envs.registration` collects :data:`ENTRIES`.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, V2_CHANGES, EnvEntry, v3_noisescale, v3_rowscale

#: Every Pedestrian id.
ENTRIES = [
    *(EnvEntry(
        f"navgym/Pedestrian{title}-v2", "navgym.pedestrian.env", "Pedestrian", task, 180,
        {"filter": "ekf", **V1_PENALTY, **V2_CHANGES[task]}, release=7,
    )
    for task, title in (("fading", "Fading"), ("noisescale", "NoiseScale"), ("mixture", "Mixture"))),
    v3_rowscale("Pedestrian", "navgym.pedestrian.env_v3", 180),
    v3_noisescale("Pedestrian", "navgym.pedestrian.env_v3", 180),
]  # fmt: skip
