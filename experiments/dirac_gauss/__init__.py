"""Seed 003: deterministic vs random Dirac-Gauss particle filters for GPS signal reception (README.md)."""
