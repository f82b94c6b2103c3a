"""The headroom gate of the v2 ids (issue #21): clairvoyant filter vs the best tuned baseline."""
