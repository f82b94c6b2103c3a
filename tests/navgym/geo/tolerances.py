"""Numerical tolerances of the geodesy tests (one place, documented)."""

#: Round-trip / cross-implementation position agreement [m].
POS_ATOL_M = 1e-3
#: Angle agreement for geodetic conversions [rad] (~0.6 mm on the ground).
ANGLE_ATOL_RAD = 1e-10
#: Rotation matrix orthonormality.
ORTHO_ATOL = 1e-12
