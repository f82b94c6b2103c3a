"""Compiled reduced pseudo-ranges of a particle cloud (the GpsIns Resample envs' ``h``).

A Resample env weighs ``B x N`` particles against up to ``m`` pseudo-ranges every step, in
"observed minus computed" form (:class:`navgym.gps_ins.models.ReducedPseudorangeModel`):

    ``q = 2 d0 . delta + |delta|^2``,  ``h_j(x) - |d0_j| = q / (sqrt(|d0_j|^2 + q) + |d0_j|)
    - w_j . delta + c0_j + b``

with ``delta = e_lambda E + e_phi N`` (Carvalho et al. 1997, eq. 14), ``d0`` the INS point's line
of sight, ``w`` the Sagnac rows and ``b`` the clock bias (eq. 10/15). In NumPy these are ten passes
over the ``(B, m, N)`` array; one loop per episode and satellite over the particles (a
structure-of-arrays cloud is contiguous along N) compiles to AVX vectors of ``sqrt`` and
divisions and is several times faster (``docs/performance.md``, "Figures behind the code").
Speed is the reason it is hand-written; the NumPy form stays as
:meth:`~navgym.gps_ins.models.ReducedPseudorangeModel.h_reference`, and
``tests/navgym/gps_ins/test_pseudorange_kernel.py`` holds the two equal to the particles'
rounding. ``error_model="numpy"`` (no ZeroDivisionError check) is what lets the loop vectorise.

Reproducibility: the loop is compiled without fast-math, so every operation is IEEE-rounded in
the written order on any x86-64 CPU; the NumPy form's linear terms come from a BLAS product
whose kernel (and so its last bits) depends on the CPU. A particle filter's resampling is
discontinuous in such rounding-level differences, so individual particle paths of the Resample
envs differ between the two forms after some tens of steps, while their statistics do not
(GpsInsResample-v0, 16 sub-envs x 250 random steps: 6 of 16 identical throughout, RMS
position error 14.2 m with either form).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from filters.core.threads import over_rows

__all__ = ["reduced_pseudoranges"]


@njit(cache=True, error_model="numpy", nogil=True)
def _kernel(xT, a2, w, rho0_sq, rho0, c0, out):  # pragma: no cover - compiled
    B, _, N = xT.shape
    m = a2.shape[2]
    for b in range(B):
        e0 = xT[b, 0]
        e1 = xT[b, 1]
        clock = xT[b, 6]
        for j in range(m):
            a0, a1 = a2[b, 0, j], a2[b, 1, j]
            w0, w1 = w[b, 0, j], w[b, 1, j]
            r2, r0, cj = rho0_sq[b, j], rho0[b, j], c0[b, j]
            o = out[b, j]
            for i in range(N):
                x0 = e0[i]
                x1 = e1[i]
                q = (a0 * x0 + a1 * x1) + (x0 * x0 + x1 * x1)
                o[i] = q / (np.sqrt(q + r2) + r0) - (w0 * x0 + w1 * x1) + cj + clock[i]


def reduced_pseudoranges(
    xT: np.ndarray, A: np.ndarray, W: np.ndarray, rho0_sq: np.ndarray, rho0: np.ndarray, c0: np.ndarray
) -> np.ndarray:
    """``h(x) - |d0|`` of :class:`~navgym.gps_ins.models.ReducedPseudorangeModel` (module docstring).

    Args:
        xT: particles as a C-contiguous ``(B, n, N)`` buffer (float32 or float64; ``n >= 7``,
            rows 0, 1 the position errors east/north, row 6 the clock bias).
        A: ``(B, 2, m)`` rows ``E . d0``, ``N . d0``.
        W: ``(B, 2, m)`` Sagnac rows.
        rho0_sq: ``(B, m)`` ``|d0|^2``.
        rho0: ``(B, m)`` ``|d0|``.
        c0: ``(B, m)`` constant terms.

    Returns:
        ``(B, m, N)`` in the particles' precision; every coefficient is cast to it first, as
        the NumPy form does.
    """
    if xT.ndim != 3 or xT.shape[1] < 7 or not xT.flags.c_contiguous:
        raise ValueError(f"xT must be a C-contiguous (B, n >= 7, N) buffer; got shape {xT.shape}")
    dt = xT.dtype
    if dt not in (np.float32, np.float64):
        raise ValueError(f"xT must be float32 or float64; got {dt}")
    B, _, N = xT.shape
    m = A.shape[-1]
    if A.shape != (B, 2, m) or W.shape != (B, 2, m):
        raise ValueError(f"A and W must have shape {(B, 2, m)}; got {A.shape} and {W.shape}")
    out = np.empty((B, m, N), dtype=dt)
    a2, w = np.ascontiguousarray(2.0 * A, dtype=dt), np.ascontiguousarray(W, dtype=dt)
    r2, r0 = np.ascontiguousarray(rho0_sq, dtype=dt), np.ascontiguousarray(rho0, dtype=dt)
    c = np.ascontiguousarray(c0, dtype=dt)

    def episodes(s: int, e: int) -> None:  # each episode's ranges from its own cloud alone
        _kernel(xT[s:e], a2[s:e], w[s:e], r2[s:e], r0[s:e], c[s:e], out[s:e])

    over_rows(B, m * N, episodes)
    return out
