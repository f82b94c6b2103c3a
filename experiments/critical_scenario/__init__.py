"""Seed 000 §V: bootstrap PF against the EKF in the critical scenario (3 -> 2 satellites)."""
