"""Learned zoo agents vs tuned classical baselines on held-out episodes (see README.md)."""
