"""Tolerances of the GNSS tests, in one place, with their reasons."""

#: SPP median error bounds [m] over the 120 epochs of GEONET 0759 (task acceptance).
SPP_MEDIAN_NO_CORRECTIONS_M = 20.0
SPP_MEDIAN_WITH_ATMOSPHERE_M = 3.0
#: Almanac-model vs broadcast-model orbit over one hour [m] ("a few km").
ALMANAC_VS_BROADCAST_M = 5000.0
#: Analytic orbit velocity vs central finite difference [m/s].
ORBIT_VELOCITY_MPS = 1e-3
#: First-order light-time + Sagnac vs iterated exact transmit-time solution [m].
LIGHT_TIME_M = 5e-3
#: Range rate vs finite difference of the range [m/s].
RANGE_RATE_MPS = 1e-4
#: Relative tolerance on Monte-Carlo standard deviations (N >= 1e5 samples: ~0.3 % 1-sigma).
MC_STD_REL = 0.02
