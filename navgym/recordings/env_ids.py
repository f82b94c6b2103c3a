"""The replay ids' registry entries (v2 only): made by :mod:`navgym.recordings.env_v2`.

A real recording with injected v2 events; defaults of a v1 id with the v2 changes.
:mod:`navgym.envs.registration` collects :data:`ENTRIES`.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, V2_CHANGES, EnvEntry

#: Every replay id.
ENTRIES = [
    EnvEntry(
        f"navgym/Replay{title}-v2", "navgym.recordings.env_v2", "Replay", task, 240,
        {"filter": "ekf", **V1_PENALTY, **V2_CHANGES[task]}, release=10,
    )
    for task, title in (("fading", "Fading"), ("noisescale", "NoiseScale"))
]  # fmt: skip
