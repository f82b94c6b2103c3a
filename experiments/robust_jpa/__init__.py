"""Seed 004 §5: robust iterated ESKF for GNSS joint position and attitude under outliers (README.md)."""
