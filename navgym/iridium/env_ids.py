"""Iridium's registry entries (v2 only; Benzerrouk 2014, §2.7d): made by :mod:`navgym.iridium.env`.

Their defaults are a v1 id's with the v2 changes; the filter is the (exact, linear) Kalman
filter. :mod:`navgym.envs.registration` collects :data:`ENTRIES`.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, V2_CHANGES, EnvEntry

#: Every Iridium id.
ENTRIES = [
    EnvEntry(
        f"navgym/Iridium{title}-v2", "navgym.iridium.env", "Iridium", task, 360,
        {"filter": "ekf", **V1_PENALTY, **V2_CHANGES[task]}, release=6,
    )
    for task, title in (("mixture", "Mixture"), ("noisescale", "NoiseScale"))
]  # fmt: skip
