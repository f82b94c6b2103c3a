"""Numerical tolerances and bounds of the INS tests (one place, documented)."""

#: Perfect IMU, quadrotor triangle flight of 300 s at 200 Hz: 3-D position drift bound [m].
#: Observed ~0.3 mm; the scheme is second order in dt, so 1 cm leaves a wide margin.
PERFECT_IMU_DRIFT_M = 0.01
#: Perfect IMU: velocity error bound over the same flight [m/s] (observed ~5e-6).
PERFECT_IMU_VEL_MPS = 1e-3
#: Stationary body, perfect IMU, rotating Earth, 600 s at 10 Hz: drift bound [m].
STATIC_DRIFT_M = 1e-3
#: Constant-bias error growth vs. 0.5 b t^2 and g eps t^3 / 6 (short, level, at rest): relative.
BIAS_GROWTH_RTOL = 0.05
#: Grade drift (300 s flight) relative to the grade's 1-sigma budget 0.5 sigma_a t^2 +
#: g sigma_g t^3 / 6 (observed 0.1-0.3: sampled biases, cancellation over the yaw turns).
GRADE_DRIFT_RATIO = (0.02, 3.0)
#: Monte Carlo (N episodes) vs. covariance propagation: relative error of variances.
MC_VAR_RTOL = 0.15
#: Rounding-level agreement of two evaluations of the same arithmetic.
EXACT_ATOL = 1e-12
