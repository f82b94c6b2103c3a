"""SignalTracking's registry entry (v2 only; Dirac-Gauss DPF n.d., §3-4).

Made by :mod:`navgym.signal_tracking.env`: the platform's own Jumps task
(:mod:`navgym.signal_tracking.task`, registered when the env module imports it) with the v2
penalty and memory features. :mod:`navgym.envs.registration` collects :data:`ENTRIES`.
"""

from __future__ import annotations

from navgym.envs.ids import V1_PENALTY, EnvEntry

#: Every SignalTracking id.
ENTRIES = [
    EnvEntry(
        "navgym/SignalTrackingJumps-v2", "navgym.signal_tracking.env", "SignalTracking", "jumps", 100,
        {**V1_PENALTY, "memory_features": True}, release=9,
    ),
]  # fmt: skip
