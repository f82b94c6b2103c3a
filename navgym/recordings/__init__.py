"""Real recordings (IMU CSV + RTKLIB ``.pos`` + TOML sidecar) and their replay as environments.

* :mod:`navgym.recordings.loader`: the format, :func:`load_recording` and its checks;
* :mod:`navgym.recordings.platform`: the replay platform (the real IMU through the Quadrotor's
  strapdown transition, the real fixes with injected v2 degradations, RTK-fixed truth);
* :mod:`navgym.recordings.env_v2`: the registered ids ``navgym/Replay{Fading,NoiseScale}-v2``
  (their entries: :mod:`navgym.recordings.env_ids`).

The loader's names are imported on first use, so that the registry can read the package's ids
without the loader's imports.
"""

from __future__ import annotations

from typing import Any

__all__ = ["PACKAGED", "GnssLog", "ImuLog", "Recording", "load_recording", "read_imu_csv", "read_rtklib_pos"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from navgym.recordings import loader

        return getattr(loader, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
