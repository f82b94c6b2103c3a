"""Jpa's registry entry (v2 only; Belles et al. 2022, §5): made by :mod:`navgym.jpa.env`.

The Robust task (the robust threshold of the iterated ESKF) with the v2 penalty and memory
features. :mod:`navgym.envs.registration` collects :data:`ENTRIES`.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, EnvEntry

#: Every Jpa id.
ENTRIES = [
    EnvEntry(
        "navgym/JpaRobust-v2", "navgym.jpa.env", "Jpa", "robust", 120,
        {"weight": "huber", **V1_PENALTY, "memory_features": True}, release=8,
    ),
]  # fmt: skip
