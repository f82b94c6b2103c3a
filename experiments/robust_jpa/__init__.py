"""Belles et al. 2022, §5: robust iterated ESKF for GNSS joint position and attitude (README.md)."""
