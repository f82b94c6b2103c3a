"""Compiled (Numba) twin of the Robot2d process noise ``Q = G diag(s^2) G^T + diag(q)``.

:func:`process_noise_pass` forms, one episode per loop iteration, the control Jacobian
``G = df/d(v_e, alpha)`` of eq. 77's arc (Benzerrouk 2014; the chain rule of
:func:`navgym.robot2d.models.control_jacobian`, whose NumPy form stays the reference) and
``Q = (G S) (G S)^T + diag(q_slip, q_slip, q_yaw)`` with ``S = diag(sigma_e, sigma_alpha)``
(:meth:`navgym.robot2d.platform.Robot2dPlatform.process_noise`).

Why: the NumPy form is about sixty passes over ``(B,)`` arrays per step (400 us at B = 1024,
a tenth of a Robot2dRowScale-v3 step in the tuning runs); one compiled pass costs a few
microseconds. ``tests/navgym/robot2d/test_noise_kernel.py`` holds the two equal to rounding.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["process_noise_pass"]


@njit(cache=True, error_model="numpy")
def process_noise_pass(
    phi, v_e, alpha, dt, wheelbase, a, b, encoder_offset, sigma_e, sigma_alpha, q_slip, q_yaw, Q
):  # pragma: no cover - compiled  # fmt: skip
    """``Q (B, 3, 3)`` of every episode from its heading ``phi``, encoder speed and steering ``(B,)``."""
    L = wheelbase
    for i in range(phi.shape[0]):
        t = np.tan(alpha[i])
        sec2 = 1.0 + t * t
        kappa = 1.0 - encoder_offset * t / L
        v = v_e[i] / kappa
        w = v * t / L
        th = 0.5 * w * dt
        sc = np.sin(th) / th if th != 0.0 else 1.0
        if abs(th) < 1e-3:  # d/dth sin(th)/th, series where the quotient cancels
            ds = -th / 3.0 + th * th * th / 30.0
        else:
            ds = (th * np.cos(th) - np.sin(th)) / (th * th)
        d = v * dt * sc
        mid = phi[i] + th
        cm, sm = np.cos(mid), np.sin(mid)
        p2 = phi[i] + 2.0 * th
        c2, s2 = np.cos(p2), np.sin(p2)
        # dp+/dv_c and dp+/dw
        dpv0, dpv1 = dt * sc * cm, dt * sc * sm
        k1, k2 = v * dt * dt / 2.0 * ds, d * dt / 2.0
        dpw0 = k1 * cm - k2 * sm + dt * (-a * s2 - b * c2)
        dpw1 = k1 * sm + k2 * cm + dt * (a * c2 - b * s2)
        dv0, dv1 = 1.0 / kappa, v * encoder_offset * sec2 / (L * kappa)
        dw0, dw1 = t / L * dv0, t / L * dv1 + v * sec2 / L
        g00 = (dpv0 * dv0 + dpw0 * dw0) * sigma_e
        g01 = (dpv0 * dv1 + dpw0 * dw1) * sigma_alpha
        g10 = (dpv1 * dv0 + dpw1 * dw0) * sigma_e
        g11 = (dpv1 * dv1 + dpw1 * dw1) * sigma_alpha
        g20 = dt * dw0 * sigma_e
        g21 = dt * dw1 * sigma_alpha
        q = Q[i]
        q[0, 0] = g00 * g00 + g01 * g01 + q_slip
        q[1, 1] = g10 * g10 + g11 * g11 + q_slip
        q[2, 2] = g20 * g20 + g21 * g21 + q_yaw
        q[0, 1] = q[1, 0] = g00 * g10 + g01 * g11
        q[0, 2] = q[2, 0] = g00 * g20 + g01 * g21
        q[1, 2] = q[2, 1] = g10 * g20 + g11 * g21
