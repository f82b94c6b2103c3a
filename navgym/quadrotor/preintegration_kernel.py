"""Compiled (Numba) twin of :func:`navgym.quadrotor.models.preintegrate_components`.

:func:`preintegrate_rows` integrates ``n_sub`` IMU samples per step (Benzerrouk 2014, eq. 4, 6,
7; Forster et al. 2017, eq. 33-44) with the recursion and order of the NumPy form (which stays
the reference): per sample ``j``, ``H = Exp(w_j delta / 2)`` (Rodrigues), ``R_mid = R_j H``,
``a = R_mid f_j``, ``psi_mid = psi + (R + R_mid) delta / 4``, ``G = [a x] psi_mid``;
``dp += dv delta + a delta^2 / 2``, ``jpa += jva delta + R_mid delta^2 / 2``,
``jpg += jvg delta + G delta^2 / 2``, ``dv += a delta``, ``jva += R_mid delta``,
``jvg += G delta``, ``R_{j+1} = R_mid H``, ``psi_{j+1} = psi_mid + (R_mid + R_{j+1}) delta / 4``;
at the end ``phi = R^T psi``.

Why: the NumPy form runs about 25 passes over ``(3, 3, N)`` slabs per sample, and the Pedestrian
and Replay platforms preintegrate at reset (the Pedestrian's 100 samples a stride); one compiled
pass keeps each step's matrices in registers. The Quadrotor's reset has its own fused kernel
(:mod:`navgym.quadrotor.imu_kernel`).

Two passes around NumPy's transcendentals, so that the results are the NumPy form's **bit for
bit**: :func:`rodrigues_arguments_pass` forms each sample's angle ``x = |w delta / 2|`` and the
arguments of its two ``np.sinc`` (``pi (x / pi)`` and ``pi (x / 2 pi)``, the machine epsilon for
0, as ``np.sinc`` forms them); the caller takes their ``sin`` and ``cos(x)`` with NumPy's SIMD
functions (Numba's scalar ``libm`` calls give other last bits, and cost about half of a scalar
pass); :func:`preintegrate_rows_pass` runs the recursion on them with the reference's operations in
its order (no fast-math contraction). The samples are read in the row layout ``(N, n_sub, 3)`` of
:func:`navgym.quadrotor.models.preintegrate`, each step's samples contiguous.
``tests/navgym/quadrotor/test_strapdown_kernel.py`` holds the twins equal with ``array_equal``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# the rows of the scratch array of the Quadrotor's fused kernel, whose sample step this one shares
from navgym.quadrotor.imu_kernel import (
    _CA,
    _CB,
    _CC,
    _DP,
    _DV,
    _F,
    _JPA,
    _JPG,
    _JVA,
    _JVG,
    _NROWS,
    _PSI,
    _R,
    _TH,
    LANES,
    preintegrate_lanes,
)

__all__ = ["preintegrate_rows", "preintegrate_rows_pass", "rodrigues_arguments_pass"]

_EPS = float(np.finfo(np.float64).eps)  # np.sinc's stand-in for a zero argument


@njit(cache=True, error_model="numpy")
def rodrigues_arguments_pass(w, h, x, y1, y2):  # pragma: no cover - compiled
    """Per sample of ``w (N, n_sub, 3)``: ``x = |w h|``, ``y1 = pi (x / pi)``, ``y2 = pi (x / 2 pi)``.

    The outputs are ``(N, n_sub)``; ``y1``, ``y2`` are the arguments ``np.sinc(x / pi)`` and
    ``np.sinc(x / (2 pi))`` take the sine of (a zero replaced by the machine epsilon, as
    ``np.sinc`` does).
    """
    N, n_sub, _ = w.shape
    for n in range(N):
        for s in range(n_sub):
            t0, t1, t2 = w[n, s, 0] * h, w[n, s, 1] * h, w[n, s, 2] * h
            xs = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            x[n, s] = xs
            u = np.pi * (xs / np.pi)
            y1[n, s] = u if u != 0.0 else _EPS
            u = np.pi * (xs / (2.0 * np.pi))
            y2[n, s] = u if u != 0.0 else _EPS


@njit(cache=True, error_model="numpy")
def preintegrate_rows_pass(
    w, f, delta, y1, s1, y2, s2, cx, dR, phi, dv, dp, jva, jvg, jpa, jpg
):  # pragma: no cover - compiled
    """The recursion (module docstring) of samples ``w, f (N, n_sub, 3)``; outputs ``(N, 3, 3)``, ``(N, 3)``.

    ``y1, s1, y2, s2, cx (N, n_sub)``: the sinc arguments of :func:`rodrigues_arguments_pass`,
    their sines and ``cos(x)``: ``H = (b t) t^T + c I + a [t x]`` with ``t = w delta / 2``,
    ``a = s1 / y1``, ``b = 0.5 (s2 / y2)^2``, ``c = cx``. :data:`~navgym.quadrotor.imu_kernel.LANES`
    steps side by side, one per SIMD lane, through the sample step of the Quadrotor's fused kernel
    (:func:`~navgym.quadrotor.imu_kernel.preintegrate_lanes`, the same expressions as the NumPy
    form); a last block's spare lanes integrate zeros and are not read.
    """
    N, n_sub, _ = w.shape
    h = 0.5 * delta
    q = 0.25 * delta
    d2 = 0.5 * delta * delta
    S = np.zeros((_NROWS, LANES))
    for n0 in range(0, N, LANES):
        G = min(LANES, N - n0)
        for l in range(LANES):
            for i in range(9):
                S[_R + i, l] = 1.0 if i % 4 == 0 else 0.0
                S[_PSI + i, l] = 0.0
                S[_JVA + i, l] = S[_JVG + i, l] = S[_JPA + i, l] = S[_JPG + i, l] = 0.0
            for i in range(3):
                S[_DV + i, l] = S[_DP + i, l] = 0.0
        for s in range(n_sub):
            for l in range(G):  # the sample of each lane's step, and its Rodrigues coefficients
                n = n0 + l
                for i in range(3):
                    S[_TH + i, l] = w[n, s, i] * h
                    S[_F + i, l] = f[n, s, i]
                S[_CA, l] = s1[n, s] / y1[n, s]
                sb = s2[n, s] / y2[n, s]
                S[_CB, l] = 0.5 * (sb * sb)
                S[_CC, l] = cx[n, s]
            preintegrate_lanes(S, delta, q, d2)
        for l in range(G):
            n = n0 + l
            for r in range(3):
                dv[n, r] = S[_DV + r, l]
                dp[n, r] = S[_DP + r, l]
                for c in range(3):
                    dR[n, r, c] = S[_R + 3 * r + c, l]
                    phi[n, r, c] = (
                        S[_R + r, l] * S[_PSI + c, l] + S[_R + 3 + r, l] * S[_PSI + 3 + c, l]
                        + S[_R + 6 + r, l] * S[_PSI + 6 + c, l]
                    )  # fmt: skip
                    jva[n, r, c] = S[_JVA + 3 * r + c, l]
                    jvg[n, r, c] = S[_JVG + 3 * r + c, l]
                    jpa[n, r, c] = S[_JPA + 3 * r + c, l]
                    jpg[n, r, c] = S[_JPG + 3 * r + c, l]


def preintegrate_rows(w: np.ndarray, f: np.ndarray, delta: float) -> tuple[np.ndarray, ...]:
    """The two passes on samples ``w, f (N, n_sub, 3)``: ``dR, phi, dv, dp, jva, jvg, jpa, jpg``, N first."""
    f64 = np.float64
    w, f = np.ascontiguousarray(w, f64), np.ascontiguousarray(f, f64)
    N, n_sub, _ = w.shape
    x, y1, y2 = np.empty((N, n_sub)), np.empty((N, n_sub)), np.empty((N, n_sub))
    rodrigues_arguments_pass(w, 0.5 * delta, x, y1, y2)
    out = [np.empty((N, 3, 3)), np.empty((N, 3, 3)), np.empty((N, 3)), np.empty((N, 3))]
    out += [np.empty((N, 3, 3)) for _ in range(4)]
    preintegrate_rows_pass(w, f, float(delta), y1, np.sin(y1), y2, np.sin(y2), np.cos(x), *out)
    return tuple(out)
