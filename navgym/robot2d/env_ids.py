"""Robot2d's registry entries: its ids, the classes that make them and their defaults.

The ``-v0``/``-v1`` ids are made by :mod:`navgym.robot2d.env`, the ``-v2`` ids by
:mod:`navgym.robot2d.env_v2` (the v2 episodes), the ``-v3`` ids by :mod:`navgym.robot2d.env_v3`.
:mod:`navgym.envs.registration` collects :data:`ENTRIES`; loading them imports nothing of the
platform.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, V2_CHANGES, EnvEntry, v1, v2, v3_rowscale

#: The ``-v0`` ids (a v1 and a v2 id each).
V0 = [
    EnvEntry(
        "navgym/Robot2dFading-v0",
        "navgym.robot2d.env",
        "Robot2d",
        "fading",
        600,
        {"filter": "ekf"},
        release=0,
    ),
    EnvEntry(
        "navgym/Robot2dMixture-v0",
        "navgym.robot2d.env",
        "Robot2d",
        "mixture",
        600,
        {"filter": "ckf"},
        release=0,
    ),
    EnvEntry(
        "navgym/Robot2dResample-v0",
        "navgym.robot2d.env",
        "Robot2d",
        "resample",
        600,
        {"n_particles": 1000},
        release=0,
    ),
]
#: The ``-v3`` ids: the v2 episodes with the context of :mod:`navgym.robot2d.context`.
V3 = [v3_rowscale("Robot2d", "navgym.robot2d.env_v3", 600)]
#: Every Robot2d id: v0, v1, v2 (the v1 tasks and the NoiseScale task new in v2), then v3.
ENTRIES = [
    *V0,
    *(v1(e) for e in V0),
    *(v2(v1(e), "navgym.robot2d.env_v2", release=3) for e in V0),
    EnvEntry(
        "navgym/Robot2dNoiseScale-v2", "navgym.robot2d.env_v2", "Robot2d", "noisescale", 600,
        {"filter": "ekf", **V1_PENALTY, **V2_CHANGES["noisescale"]}, release=3,
    ),
    *V3,
]  # fmt: skip
