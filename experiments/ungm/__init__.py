"""Touil & Ghadi 2012, example 1 (UNGM): bootstrap PF vs EKF (see README.md)."""
