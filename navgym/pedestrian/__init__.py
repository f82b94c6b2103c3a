"""Pedestrian navigation (Benzerrouk 2014, §2.7c): foot-mounted IMU, ZUPTs and GPS/GLONASS fixes."""

from navgym.pedestrian.platform import PedestrianPlatform

__all__ = ["PedestrianPlatform"]
