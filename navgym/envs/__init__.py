"""navgym environments: platforms (GpsIns, Quadrotor, Robot2d) x tasks (Fading, Mixture, Resample)."""

from navgym.envs.registration import ENVIRONMENTS, register_all

__all__ = ["ENVIRONMENTS", "register_all"]
