"""The replay ids' registry entries: v2 (:mod:`navgym.recordings.env_v2`) and v3 (its ``env_v3``).

A real recording with injected v2 events; defaults of a v1 id with the v2 changes; v3 adds the
context and the RowScale knob (an evaluation id). :mod:`navgym.envs.registration` collects
:data:`ENTRIES`.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, V2_CHANGES, EnvEntry, v3_rowscale

#: Every replay id.
ENTRIES = [
    EnvEntry(
        f"navgym/Replay{title}-v2", "navgym.recordings.env_v2", "Replay", task, 240,
        {"filter": "ekf", **V1_PENALTY, **V2_CHANGES[task]}, release=10,
    )
    for task, title in (("fading", "Fading"), ("noisescale", "NoiseScale"))
]  # fmt: skip
ENTRIES.append(v3_rowscale("Replay", "navgym.recordings.env_v3", 240, release=13))
