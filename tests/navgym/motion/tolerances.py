"""Numerical tolerances of the platform tests (one place, documented)."""

#: Closed-form trajectories evaluated twice (batch vs single, step vs whole): rounding level.
EXACT_ATOL = 1e-9
#: Central-difference checks of v = dp/dt, a = dv/dt with step 1e-3 s: error ~ 1e-7 * jerk.
FD_ATOL = 1e-5
#: Loop closure of a triangle flight [m].
CLOSURE_M = 1e-6
#: Continuity at 200 Hz: the largest change between samples relative to the bound peak * dt.
CONTINUITY_FACTOR = 1.05
