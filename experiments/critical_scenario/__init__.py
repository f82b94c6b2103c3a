"""Carvalho et al. 1997, §V: bootstrap PF against the EKF in the critical scenario (3 -> 2 satellites)."""
