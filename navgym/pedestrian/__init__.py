"""Pedestrian navigation (Benzerrouk 2014, §2.7c): foot-mounted IMU, ZUPTs and GPS/GLONASS fixes.

:class:`PedestrianPlatform` is imported on first use, so that the registry can read the
package's ids (:mod:`navgym.pedestrian.env_ids`) without the platform's imports.
"""

from __future__ import annotations

from typing import Any

__all__ = ["PedestrianPlatform"]


def __getattr__(name: str) -> Any:
    if name == "PedestrianPlatform":
        from navgym.pedestrian.platform import PedestrianPlatform

        return PedestrianPlatform
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
