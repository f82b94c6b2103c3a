"""Seed 002 example 1 (UNGM): bootstrap PF vs EKF (see README.md)."""
