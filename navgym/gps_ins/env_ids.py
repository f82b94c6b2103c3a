"""GpsIns' registry entries: its ids, the classes that make them and their defaults.

The ``-v0``/``-v1`` ids are made by :mod:`navgym.gps_ins.env`, the ``-v2`` ids by
:mod:`navgym.gps_ins.env_v2` (the v2 episodes), the ``-v3`` ids by :mod:`navgym.gps_ins.env_v3`
(the v2 episodes with per-satellite C/N0 and elevation and the IMU's context).
:mod:`navgym.envs.registration` collects :data:`ENTRIES`; loading them imports nothing of the
platform.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, V2_CHANGES, EnvEntry, v1, v2, v3_rowscale

#: The ``-v0`` ids (a v1 and a v2 id each).
V0 = [
    EnvEntry(
        "navgym/GpsInsFading-v0", "navgym.gps_ins.env", "GpsIns", "fading", 300, {"filter": "ekf"}, release=0
    ),
    EnvEntry(
        "navgym/GpsInsMixture-v0",
        "navgym.gps_ins.env",
        "GpsIns",
        "mixture",
        300,
        {"filter": "ckf"},
        release=0,
    ),
    EnvEntry(
        "navgym/GpsInsResample-v0",
        "navgym.gps_ins.env",
        "GpsIns",
        "resample",
        300,
        {"n_particles": 1000, "m_max": 8},
        release=0,
    ),
]
#: Every GpsIns id: v0, v1, v2 (the v1 tasks and the NoiseScale task new in v2), then v3.
ENTRIES = [
    *V0,
    *(v1(e) for e in V0),
    *(v2(v1(e), "navgym.gps_ins.env_v2", release=4) for e in V0),
    EnvEntry(
        "navgym/GpsInsNoiseScale-v2", "navgym.gps_ins.env_v2", "GpsIns", "noisescale", 300,
        {"filter": "ekf", **V1_PENALTY, **V2_CHANGES["noisescale"]}, release=4,
    ),
    v3_rowscale("GpsIns", "navgym.gps_ins.env_v3", 300),
]  # fmt: skip
