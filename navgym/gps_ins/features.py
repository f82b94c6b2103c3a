"""GpsIns observation features specific to the platform: covariance blocks and bias estimates.

The innovation, NIS and covariance features are shared (:mod:`navgym.envs.features`); this
module declares the GpsIns covariance blocks and, with ``bias_features=True`` (the v2 ids), the
filter's own accelerometer-bias and clock-drift estimates and their rates (:data:`BIAS_FEATURES`).
"""

from __future__ import annotations

import numpy as np

from navgym.envs.features import CovarianceBlock, Feature
from navgym.ins.imu_grades import G0

__all__ = ["BIAS_BOUNDS", "BIAS_FEATURES", "BIAS_SCALES", "BIAS_STATES", "COVARIANCE_BLOCKS", "bias_values"]

#: Log-sigma features of the filter's covariance.
COVARIANCE_BLOCKS = (
    CovarianceBlock("log_sigma_pos", (0, 1), -2.0, 5.0, "log10 m", "log10 sqrt(P_ee + P_nn)"),
    CovarianceBlock(
        "log_sigma_vel", (2, 3), -4.0, 2.0, "log10 m/s", "log10 sqrt of the velocity-error variances"
    ),
    CovarianceBlock("log_sigma_bias", (4, 5), -8.0, 0.0, "log10 m/s^2", "log10 sqrt of the bias variances"),
    CovarianceBlock("log_sigma_clock", (6,), -2.0, 6.0, "log10 m", "log10 sqrt(P_bb)"),
)
#: The bias features of ``bias_features=True`` (v2): the filter's own estimates of the states
#: that are biases (x, y accelerometer biases, clock drift) and their rates, per bound.
#: Accelerometer bias [mg] within +-1 mg (100 times the navigation-grade limit of 10 ug: an
#: estimate beyond it is clipped), its rate [mg/s] within +-0.1; clock drift [m/s] within +-5
#: (c times the drift's prior sigma 1e-9 is 0.3 m/s), its rate [m/s^2] within +-0.5.
BIAS_SCALES = {
    "accel_bias": 1e-3 * G0,
    "accel_bias_rate": 1e-3 * G0,
    "clock_drift": 1.0,
    "clock_drift_rate": 1.0,
}
BIAS_BOUNDS = {"accel_bias": 1.0, "accel_bias_rate": 0.1, "clock_drift": 5.0, "clock_drift_rate": 0.5}
#: States published by ``bias_features``: x, y accelerometer biases [m/s^2], clock drift [m/s].
BIAS_STATES = [4, 5, 7]
#: The bias features (``bias_features=True``): the filter's estimates and their change over the
#: last step, scaled and bounded as :data:`BIAS_SCALES` and :data:`BIAS_BOUNDS` say (values beyond
#: are clipped).
BIAS_FEATURES = (
    Feature("accel_bias", -BIAS_BOUNDS["accel_bias"], BIAS_BOUNDS["accel_bias"], "mg",
            "the filter's x, y accelerometer-bias estimates (along / across the heading)", 2),
    Feature("accel_bias_rate", -BIAS_BOUNDS["accel_bias_rate"], BIAS_BOUNDS["accel_bias_rate"], "mg/s",
            "change of the accelerometer-bias estimates over the last step / dt", 2),
    Feature("clock_drift", -BIAS_BOUNDS["clock_drift"], BIAS_BOUNDS["clock_drift"], "m/s",
            "the filter's clock-drift estimate (c times the drift)"),
    Feature("clock_drift_rate", -BIAS_BOUNDS["clock_drift_rate"], BIAS_BOUNDS["clock_drift_rate"], "m/s^2",
            "change of the clock-drift estimate over the last step / dt"),
)  # fmt: skip


#: Column layout of :func:`bias_values`' one pass: (name, columns) in order, with each
#: column's scale and bound.
_BIAS_COLUMNS = (("accel_bias", 2), ("accel_bias_rate", 2), ("clock_drift", 1), ("clock_drift_rate", 1))
_BIAS_SCALE = np.repeat([BIAS_SCALES[k] for k, _ in _BIAS_COLUMNS], [n for _, n in _BIAS_COLUMNS])
_BIAS_BOUND = np.repeat([BIAS_BOUNDS[k] for k, _ in _BIAS_COLUMNS], [n for _, n in _BIAS_COLUMNS])


def bias_values(m: np.ndarray, previous: np.ndarray, dt: float) -> dict[str, np.ndarray]:
    """The bias features of the filter's means ``m (B, 8)`` and the previous estimates ``(B, 3)``.

    ``previous`` is ``m`` itself at reset (``(B, 8)``: rates 0). The six columns are scaled,
    cleaned (NaN to 0) and clipped in one pass.
    """
    now = m[:, BIAS_STATES]
    before = previous[:, BIAS_STATES] if previous.shape[1] == m.shape[1] else previous
    rate = (now - before) / dt
    v = np.concatenate([now[:, 0:2], rate[:, 0:2], now[:, 2:3], rate[:, 2:3]], axis=1) / _BIAS_SCALE
    v = np.clip(np.nan_to_num(v), -_BIAS_BOUND, _BIAS_BOUND)
    return {
        "accel_bias": v[:, 0:2],
        "accel_bias_rate": v[:, 2:4],
        "clock_drift": v[:, 4],
        "clock_drift_rate": v[:, 5],
    }
