"""Tolerances for the filter tests, in one place."""

#: Relative tolerance for comparisons between implementations of the same algorithm.
RTOL = 1e-9
#: Absolute floor for those comparisons (quantities of order 1 or larger).
ATOL = 1e-9
#: Masked rows must contribute "exactly nothing": agreement to a few ulps.
MASK_RTOL = 1e-12
MASK_ATOL = 1e-12
