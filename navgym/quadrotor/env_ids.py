"""Quadrotor's registry entries: its ids, the classes that make them and their defaults.

The ``-v0``/``-v1`` ids are made by :mod:`navgym.quadrotor.env`, the ``-v2`` ids by
:mod:`navgym.quadrotor.env_v2` (the v2 episodes), the ``-v3`` ids by
:mod:`navgym.quadrotor.env_v3` (the v2 episodes with a receiver's and the IMU's context).
:mod:`navgym.envs.registration` collects :data:`ENTRIES`; loading them imports nothing of the
platform.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, V2_CHANGES, EnvEntry, v1, v2, v3_rowscale

#: The ``-v0`` ids (a v1 and a v2 id each).
V0 = [
    EnvEntry(
        "navgym/QuadrotorFading-v0",
        "navgym.quadrotor.env",
        "Quadrotor",
        "fading",
        600,
        {"filter": "ekf"},
        release=0,
    ),
    EnvEntry(
        "navgym/QuadrotorMixture-v0",
        "navgym.quadrotor.env",
        "Quadrotor",
        "mixture",
        600,
        {"filter": "ckf"},
        release=0,
    ),
]
#: Every Quadrotor id: v0, v1, v2 (the v1 tasks and the NoiseScale task new in v2), then v3.
ENTRIES = [
    *V0,
    *(v1(e) for e in V0),
    *(v2(v1(e), "navgym.quadrotor.env_v2", release=5) for e in V0),
    EnvEntry(
        "navgym/QuadrotorNoiseScale-v2", "navgym.quadrotor.env_v2", "Quadrotor", "noisescale", 600,
        {"filter": "ekf", **V1_PENALTY, **V2_CHANGES["noisescale"]}, release=5,
    ),
    v3_rowscale("Quadrotor", "navgym.quadrotor.env_v3", 600),
]  # fmt: skip
