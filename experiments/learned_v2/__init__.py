"""Learned v2 zoo agents vs the best tuned baseline and the clairvoyant filter (see README.md)."""
