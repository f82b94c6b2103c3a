"""Dirac-Gauss DPF n.d.: deterministic vs random Dirac-Gauss PFs for GPS signal reception (README.md)."""
