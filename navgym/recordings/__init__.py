"""Real recordings (IMU CSV + RTKLIB ``.pos`` + TOML sidecar) and their replay as environments.

* :mod:`navgym.recordings.loader`: the format, :func:`load_recording` and its checks;
* :mod:`navgym.recordings.platform`: the replay platform (the real IMU through the Quadrotor's
  strapdown transition, the real fixes with injected v2 degradations, RTK-fixed truth);
* :mod:`navgym.recordings.env_v2`: the registered ids ``navgym/Replay{Fading,NoiseScale}-v2``.
"""

from navgym.recordings.loader import (
    PACKAGED,
    GnssLog,
    ImuLog,
    Recording,
    load_recording,
    read_imu_csv,
    read_rtklib_pos,
)

__all__ = ["PACKAGED", "GnssLog", "ImuLog", "Recording", "load_recording", "read_imu_csv", "read_rtklib_pos"]
