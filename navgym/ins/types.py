"""State and measurement containers of the strapdown INS (immutable NamedTuples)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["NavState", "ImuSample"]


class NavState(NamedTuple):
    """Navigation state of a batch of strapdown INS, batch axes first.

    Attributes:
        lat: Geodetic latitude [rad], shape ``(B,)``.
        lon: Longitude [rad], shape ``(B,)``.
        h: Height above the WGS-84 ellipsoid [m], shape ``(B,)``.
        v_ned: Velocity over the Earth in NED axes [m/s], shape ``(B, 3)``.
        C_b_n: Body-to-NED direction cosine matrix, shape ``(B, 3, 3)``.

    """

    lat: NDArray[np.float64]
    lon: NDArray[np.float64]
    h: NDArray[np.float64]
    v_ned: NDArray[np.float64]
    C_b_n: NDArray[np.float64]


class ImuSample(NamedTuple):
    """IMU output for one sampling interval ``[t_k, t_k + dt]`` (or a sequence of them).

    The values are the interval's mean specific force and angular rate (increment / dt), which
    is what :func:`navgym.ins.strapdown_step` integrates.

    Attributes:
        specific_force: Specific force f_ib^b [m/s^2], shape ``(B, 3)`` (or ``(B, T, 3)``).
        angular_rate: Angular rate omega_ib^b [rad/s], same shape.

    """

    specific_force: NDArray[np.float64]
    angular_rate: NDArray[np.float64]
