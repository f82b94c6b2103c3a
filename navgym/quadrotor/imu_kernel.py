"""Compiled reset kernel of the Quadrotor env: IMU samples along the flight, errors, preintegration.

At reset the Quadrotor env simulates, for every episode, ``T x n_sub`` IMU samples (600 x 20 at
the defaults) and preintegrates each step's ``n_sub`` samples (:mod:`navgym.quadrotor.env`). The
NumPy path (:func:`navgym.quadrotor.flight.quadrotor_imu`, then
:func:`navgym.quadrotor.models.preintegrate_components`) runs some 200 array passes over all the
samples, more than twice the cost of the EKF that consumes them (``docs/performance.md``,
"Figures behind the code"). This module fuses the whole chain per sample in loops compiled by
Numba, so nothing of size ``B T n_sub`` is ever stored but the normals; speed is the reason it
is hand-written (the NumPy functions stay the reference, and
``tests/navgym/quadrotor/test_imu_kernel.py`` holds the two to rounding).

Per sample at time ``t`` (mid-point of the IMU interval) of episode ``b``:

1. **Flat outputs** (:func:`navgym.quadrotor.flight._design`): the active phase
   ``i = max{i : t_start_i <= t}``, ``tau = (t - t_start_i) / d_i`` and the septic smootherstep
   ``s(tau)`` and its derivatives give ``v = dp s' / d``, ``a = dp s'' / d^2``,
   ``j = dp s''' / d^3``, ``psi = psi_0 + dpsi s`` and ``dpsi/dt = dpsi s' / d``.
2. **Attitude and body rate** by differential flatness
   (:func:`navgym.quadrotor.flight._attitude_and_rate`, Mellinger & Kumar 2011): the columns
   ``x_b, y_b, z_b`` of ``C_b^{n0}`` and ``omega_{n0 b}^b``.
3. **Ideal IMU in the home tangent frame n0.** The mechanization solved for the sensed
   quantities (:mod:`navgym.ins.inverse_mechanization`),
   ``f_ib^b = C_n^b (dv^n/dt - g^n + (omega_en^n + 2 omega_ie^n) x v^n)`` and
   ``omega_ib^b = omega_nb^b + C_n^b (omega_ie^n + omega_en^n)``, with the quadrotor's
   ``v^n = M v^{n0}``, ``dv^n/dt = M a^{n0} - omega_en^n x v^n``, ``C_b^n = M C_b^{n0}`` and
   ``omega_nb^b = omega_{n0 b}^b - C_n^b omega_en^n`` (``M = C_e^n C_e^{n0 T}``), is the same as::

       f_ib^b     = C_b^{n0 T} (a^{n0} + 2 Omega x v^{n0} - gamma^{n0})
       omega_ib^b = omega_{n0 b}^b + C_b^{n0 T} Omega

   exactly: the transport rate cancels, and ``Omega = M^T omega_ie^n`` is the Earth rate in the
   home frame, a constant per episode. Only the normal gravity vector
   ``gamma^{n0} = M^T (0, 0, gamma(lat, h))`` still depends on where the quadrotor is; it is
   computed exactly in NumPy (:func:`navgym.quadrotor.flight.home_gravity`) at the GNSS
   epochs and the step mid-points, and the kernel interpolates it quadratically through those
   three nodes per step. Over
   0.1 s the vector turns by about 1e-7 rad, so the interpolation error is below 1e-10 m/s^2
   (the test measures it), 1e-7 of a consumer accelerometer's bias.
4. **Errors** (Benzerrouk 2014, eq. 2 and 5): ``f = f_ib + b_a + n_a e``, ``omega = omega_ib + b_g +
   n_g e`` with the step's bias, the step's noise sigmas ``n_a, n_g`` (constant per episode, or
   raised during the v2 episodes' vibration bursts) and the sample's normals ``e``.
5. **Preintegration** (Forster et al. 2017 eq. 33-44, as
   :func:`navgym.quadrotor.models.preintegrate_components`): Rodrigues' formula (Benzerrouk 2014, eq. 4)
   per half sample, mid-sample attitude for the velocity (eq. 6), trapezoid for the position
   (eq. 7), and the bias Jacobians.
6. **Sample statistics** (optional ``stats``, the v3 context's IMU window features,
   :mod:`navgym.quadrotor.context`): per step the sums over its samples of the measured ``f``,
   ``|f|^2``, ``omega`` and ``|omega|^2``; accumulated beside the chain, they change none of its
   outputs.

**Loop organisation: SIMD across episodes.** Within an episode the samples form a recurrence
(every preintegration update needs the previous one), but the episodes are independent, so the
kernel runs ``LANES`` episodes side by side, one per SIMD lane. A block of episodes keeps its
state as a structure of arrays: the scratch array ``S`` has one row per scalar quantity (the nine
elements of ``Delta R``, of ``Psi``, of each bias Jacobian, ``Delta v``, the sample's specific
force, the active phase's data, ...) and one column per lane. Per sample, items 1-4
(:func:`_flat_imu`) and item 5 (:func:`preintegrate_lanes`) are loops ``for l in range(LANES)`` of
branch-free arithmetic on the rows of ``S``, whose shape is a compile-time constant, so LLVM turns
them into packed AVX-512 (or AVX2) instructions, 8 (4) episodes per instruction; this and
software prefetching (below) make the kernel some 5 x faster on one core than the same chain
taken one episode at a time. What does not vectorise is done per lane in small scalar passes,
each touching only the lanes that need it:

* the active phase: a test ``t >= t_start`` of the next phase for all lanes, and only for the
  lanes that cross a boundary (a few times per flight) the search and the load of the phase's data
  (:func:`_enter_phase`, which also computes the cosine and sine of a constant yaw);
* the cosine and sine of the yaw, only for the lanes in a turn (some 5 % of the samples);
* the Rodrigues coefficients: :func:`_flat_imu` computes the Taylor-series ones for every lane and
  counts the lanes with ``|theta| >= 0.01`` rad, and only when there are any
  :func:`_large_angles` replaces theirs by the trigonometric ones before they are used;
* the episode-major inputs and outputs (normals, biases, gravity nodes; ``dR, phi, d6, J6``) move
  between their arrays and ``S`` per sample or per step, and the next step's lines of those
  arrays are prefetched (:func:`_prefetch`) while this step computes, which hides most of the
  memory latency of these 7 x LANES interleaved streams.

Each quantity is computed by the same expression as in the one-episode-at-a-time form (divisions
by the phase duration and by ``|w|`` became products with the reciprocal), so the outputs equal
that form's to a few units of rounding (< 1e-15).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from navgym.ins.imu_grades import G0

__all__ = ["LANES", "N_STATS", "preintegrate_lanes", "preintegrated_imu"]

#: Per-step sample statistics of ``preintegrated_imu(..., stats=...)``: sums over the step's
#: samples of the measured specific force f (3) [m/s^2], of |f|^2, of the measured angular rate
#: omega (3) [rad/s] and of |omega|^2.
N_STATS = 8

#: Episodes processed side by side, one per SIMD lane (two AVX-512 vectors of doubles).
LANES = 16

# Rows of the scratch array S (one row per scalar quantity, one column per lane). Per episode:
# Earth rate Omega in the home frame, the step's white-noise standard deviations n_a, n_g, time of
# epoch 0.
_OX, _OY, _OZ, _NA, _NG, _T0 = 0, 1, 2, 3, 4, 5
# per phase: start, 1 / duration, displacement dp (3), yaw at the start and its change, cos and
# sin of the yaw (per sample in a turn), start of the next phase
_TS, _INVD, _DPX, _DPY, _DPZ, _Y0, _DY, _CY, _SY, _TNEXT = 6, 7, 8, 9, 10, 11, 12, 13, 14, 15
# per step: bias [b_a, b_g] (6); gravity nodes gamma(k), gamma(k + 1/2), gamma(k + 1) (3 x 3)
_BIAS, _GAM = 16, 22
# per sample: time, normals e (6), measured specific force f (3), half-sample rotation vector
# theta (3) with its Rodrigues coefficients sinc|th|, (1 - cos|th|)/|th|^2, cos|th| and |th|^2
_T, _E, _F, _TH, _CA, _CB, _CC, _X2 = 31, 32, 38, 41, 44, 45, 46, 47
# preintegration state: Delta R, Psi (3 x 3 each, row-major), d(Delta v)/db_a, d(Delta v)/db_g,
# d(Delta p)/db_a, d(Delta p)/db_g (3 x 3 each), Delta v, Delta p
_R, _PSI, _JVA, _JVG, _JPA, _JPG, _DV, _DP = 48, 57, 66, 75, 84, 93, 102, 105
# the sample's mid-sample R_m, Psi_m (3 x 3) and acceleration a = R_m f, between the two loops
# of preintegrate_lanes
_RM, _PSIM, _ACC = 108, 117, 126
# the step's sample statistics (``stats``): sums of f (3), |f|^2, theta (3), |theta|^2
_SF, _SF2, _STH, _STH2 = 129, 132, 133, 136
_NROWS = 137

#: Start of the phase after the last (never reached).
_NEVER = 1e300


@intrinsic
def _prefetch(typingctx, a, i):
    """Hint the CPU to load the cache line of ``a.ravel()[i]`` into L2 (LLVM ``llvm.prefetch``).

    Only a hint: it never faults and changes no result, whatever ``i`` is.
    """
    sig = types.void(a, i)

    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        ptr = builder.gep(ary.data, [args[1]])
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [ptr.type, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0")
        builder.call(fn, [ptr, i32(0), i32(2), i32(1)])  # read, locality 2 (L2), data cache
        return context.get_dummy_value()

    return sig, codegen


@njit(cache=True, error_model="numpy", inline="always")
def _prefetch_run(a, start: int, n: int) -> None:
    """Prefetch the cache lines of ``a.ravel()[start : start + n]``."""
    for i in range(0, n + 7, 8):
        _prefetch(a, start + min(i, n - 1))


@njit(cache=True, error_model="numpy")
def _smooth(tau: float) -> tuple[float, float, float, float]:
    """Septic smootherstep and its first three derivatives (``navgym.motion.profiles.smootherstep``)."""
    t = tau if tau > 0.0 else 0.0  # clip to [0, 1] by selects, which vectorise
    t = t if t < 1.0 else 1.0
    u = 1.0 - t
    t2 = t * t
    tu = t * u
    s0 = t2 * t2 * (35.0 + t * (-84.0 + t * (70.0 - 20.0 * t)))
    s1 = 140.0 * tu * tu * tu
    s2 = 420.0 * tu * tu * (1.0 - 2.0 * t)
    s3 = 840.0 * t * u * (1.0 - 5.0 * t + 5.0 * t * t)
    return s0, s1, s2, s3


@njit(cache=True, error_model="numpy")
def _enter_phase(S, l, b, i, plan) -> None:
    """Load phase ``i`` of episode ``b`` into lane ``l``; cos and sin of its yaw if constant."""
    t_seg, dur, p_start, p_end, yaw_start, yaw_end = plan
    S[_TS, l] = t_seg[b, i]
    S[_INVD, l] = 1.0 / dur[b, i]
    S[_DPX, l] = p_end[b, i, 0] - p_start[b, i, 0]
    S[_DPY, l] = p_end[b, i, 1] - p_start[b, i, 1]
    S[_DPZ, l] = p_end[b, i, 2] - p_start[b, i, 2]
    y0 = yaw_start[b, i]
    dy = yaw_end[b, i] - y0
    S[_Y0, l] = y0
    S[_DY, l] = dy
    if dy == 0.0:
        S[_CY, l] = math.cos(y0)
        S[_SY, l] = math.sin(y0)
    S[_TNEXT, l] = t_seg[b, i + 1] if i + 1 < t_seg.shape[1] else _NEVER


@njit(cache=True, error_model="numpy", inline="always")
def _flat_imu(S, l0: float, lm: float, l1: float, h: float) -> int:
    """Items 1-4 for all lanes: measured ``f`` and ``omega``, and the Rodrigues coefficients.

    Writes ``f``, ``theta = omega h`` (the half sample's rotation vector) and the Taylor-series
    coefficients of ``Exp(theta)``, exact to rounding below 0.01 rad (the first omitted terms are
    ``x^8 / 9!`` and ``x^8 / 8!`` < 3e-21 relative, ``x = |theta|``)::

        sinc x = 1 - x^2/6 (1 - x^2/20 (1 - x^2/42))
        (1 - cos x) / x^2 = 1/2 - x^2/24 (1 - x^2/30 (1 - x^2/56)) = b,    cos x = 1 - x^2 b

    ``l0, lm, l1`` are the sample's Lagrange weights of the step's three gravity nodes. Returns
    the number of lanes with ``|theta| >= 0.01`` rad, whose coefficients :func:`_large_angles`
    must replace.
    """
    n_large = 0
    for l in range(LANES):
        # 1. flat outputs of the active phase
        inv = S[_INVD, l]
        s0, s1, s2, s3 = _smooth((S[_T, l] - S[_TS, l]) * inv)
        s1 *= inv
        s2 *= inv * inv
        s3 *= inv * inv * inv
        dpx, dpy, dpz = S[_DPX, l], S[_DPY, l], S[_DPZ, l]
        cy, sy = S[_CY, l], S[_SY, l]
        vx, vy, vz = dpx * s1, dpy * s1, dpz * s1
        ax, ay, az = dpx * s2, dpy * s2, dpz * s2
        jx, jy, jz = dpx * s3, dpy * s3, dpz * s3
        r_ = S[_DY, l] * s1
        # 2. attitude and body rate (differential flatness)
        fx, fy, fz = ax, ay, az - G0
        inv_nf = 1.0 / math.sqrt(fx * fx + fy * fy + fz * fz)
        zx, zy, zz = -fx * inv_nf, -fy * inv_nf, -fz * inv_nf
        uj = -(zx * jx + zy * jy + zz * jz)
        dzx = -(jx + uj * zx) * inv_nf
        dzy = -(jy + uj * zy) * inv_nf
        dzz = -(jz + uj * zz) * inv_nf
        wx, wy, wz = -zz * sy, zz * cy, zx * sy - zy * cy
        inv_nw = 1.0 / math.sqrt(wx * wx + wy * wy + wz * wz)
        yx, yy, yz = wx * inv_nw, wy * inv_nw, wz * inv_nw
        xx = yy * zz - yz * zy
        xy = yz * zx - yx * zz
        xz = yx * zy - yy * zx
        dwx = -dzz * sy - zz * r_ * cy
        dwy = dzz * cy - zz * r_ * sy
        dwz = dzx * sy - dzy * cy + r_ * (zx * cy + zy * sy)
        p_ = -(yx * dzx + yy * dzy + yz * dzz)
        q_ = xx * dzx + xy * dzy + xz * dzz
        rr = -(xx * dwx + xy * dwy + xz * dwz) * inv_nw
        # 3. ideal IMU in the home frame; gravity through the step's three nodes
        gx = l0 * S[_GAM, l] + lm * S[_GAM + 3, l] + l1 * S[_GAM + 6, l]
        gy = l0 * S[_GAM + 1, l] + lm * S[_GAM + 4, l] + l1 * S[_GAM + 7, l]
        gz = l0 * S[_GAM + 2, l] + lm * S[_GAM + 5, l] + l1 * S[_GAM + 8, l]
        Ox, Oy, Oz = S[_OX, l], S[_OY, l], S[_OZ, l]
        cx = ax + 2.0 * (Oy * vz - Oz * vy) - gx
        cyy = ay + 2.0 * (Oz * vx - Ox * vz) - gy
        cz = az + 2.0 * (Ox * vy - Oy * vx) - gz
        # 4. errors: measured = true + bias + white noise (bias constant over the step)
        na, ng = S[_NA, l], S[_NG, l]
        S[_F, l] = (xx * cx + xy * cyy + xz * cz) + S[_BIAS, l] + na * S[_E, l]
        S[_F + 1, l] = (yx * cx + yy * cyy + yz * cz) + S[_BIAS + 1, l] + na * S[_E + 1, l]
        S[_F + 2, l] = (zx * cx + zy * cyy + zz * cz) + S[_BIAS + 2, l] + na * S[_E + 2, l]
        wm0 = (p_ + xx * Ox + xy * Oy + xz * Oz) + S[_BIAS + 3, l] + ng * S[_E + 3, l]
        wm1 = (q_ + yx * Ox + yy * Oy + yz * Oz) + S[_BIAS + 4, l] + ng * S[_E + 4, l]
        wm2 = (rr + zx * Ox + zy * Oy + zz * Oz) + S[_BIAS + 5, l] + ng * S[_E + 5, l]
        # 5a. the half sample's rotation and its Rodrigues coefficients (Taylor series)
        tx, ty, tz = wm0 * h, wm1 * h, wm2 * h
        x2 = tx * tx + ty * ty + tz * tz
        b = 0.5 - x2 * (1.0 / 24.0) * (1.0 - x2 * (1.0 / 30.0) * (1.0 - x2 * (1.0 / 56.0)))
        S[_TH, l], S[_TH + 1, l], S[_TH + 2, l] = tx, ty, tz
        S[_CA, l] = 1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0) * (1.0 - x2 * (1.0 / 42.0)))
        S[_CB, l] = b
        S[_CC, l] = 1.0 - x2 * b
        S[_X2, l] = x2
        n_large += x2 >= 1e-4
    return n_large


@njit(cache=True, error_model="numpy")
def _large_angles(S) -> None:
    """Trigonometric Rodrigues coefficients for the lanes with ``|theta| >= 0.01`` rad.

    ``(1 - cos x) / x^2 = sinc(x/2)^2 / 2`` keeps them free of cancellation.
    """
    for l in range(LANES):
        x2 = S[_X2, l]
        if x2 >= 1e-4:
            x = math.sqrt(x2)
            sh = math.sin(0.5 * x) / (0.5 * x)
            S[_CA, l] = math.sin(x) / x
            S[_CB, l] = 0.5 * sh * sh
            S[_CC, l] = math.cos(x)


@njit(cache=True, error_model="numpy", inline="always")
def _accumulate(S) -> None:
    """Add the sample's measured ``f``, ``theta = omega h`` and their squared norms to the step's sums."""
    for l in range(LANES):
        f0, f1, f2 = S[_F, l], S[_F + 1, l], S[_F + 2, l]
        t0, t1, t2 = S[_TH, l], S[_TH + 1, l], S[_TH + 2, l]
        S[_SF, l] += f0
        S[_SF + 1, l] += f1
        S[_SF + 2, l] += f2
        S[_SF2, l] += f0 * f0 + f1 * f1 + f2 * f2
        S[_STH, l] += t0
        S[_STH + 1, l] += t1
        S[_STH + 2, l] += t2
        S[_STH2, l] += t0 * t0 + t1 * t1 + t2 * t2


# One lane's 3 x 3 matrices as row-major 9-tuples, so that LLVM keeps them in registers.
@njit(cache=True, error_model="numpy", inline="always")
def _load9(S, row: int, l: int):
    """The 3 x 3 matrix in rows ``row .. row + 8`` of ``S``, lane ``l``."""
    return (
        S[row, l], S[row + 1, l], S[row + 2, l],
        S[row + 3, l], S[row + 4, l], S[row + 5, l],
        S[row + 6, l], S[row + 7, l], S[row + 8, l],
    )  # fmt: skip


@njit(cache=True, error_model="numpy", inline="always")
def _store9(S, row: int, l: int, A) -> None:
    for i in range(9):
        S[row + i, l] = A[i]


@njit(cache=True, error_model="numpy", inline="always")
def _matmul(A, B):
    """``A B``: ``(A B)_rc = A_r0 B_0c + A_r1 B_1c + A_r2 B_2c``."""
    return (
        A[0] * B[0] + A[1] * B[3] + A[2] * B[6],
        A[0] * B[1] + A[1] * B[4] + A[2] * B[7],
        A[0] * B[2] + A[1] * B[5] + A[2] * B[8],
        A[3] * B[0] + A[4] * B[3] + A[5] * B[6],
        A[3] * B[1] + A[4] * B[4] + A[5] * B[7],
        A[3] * B[2] + A[4] * B[5] + A[5] * B[8],
        A[6] * B[0] + A[7] * B[3] + A[8] * B[6],
        A[6] * B[1] + A[7] * B[4] + A[8] * B[7],
        A[6] * B[2] + A[7] * B[5] + A[8] * B[8],
    )


@njit(cache=True, error_model="numpy", inline="always")
def _skew_mul(a, M):
    """``[a x] M``: rows ``a_1 M_2 - a_2 M_1``, ``a_2 M_0 - a_0 M_2``, ``a_0 M_1 - a_1 M_0``."""
    return (
        a[1] * M[6] - a[2] * M[3], a[1] * M[7] - a[2] * M[4], a[1] * M[8] - a[2] * M[5],
        a[2] * M[0] - a[0] * M[6], a[2] * M[1] - a[0] * M[7], a[2] * M[2] - a[0] * M[8],
        a[0] * M[3] - a[1] * M[0], a[0] * M[4] - a[1] * M[1], a[0] * M[5] - a[1] * M[2],
    )  # fmt: skip


@njit(cache=True, error_model="numpy", inline="always")
def _trapezoid(P, A, B, q: float):
    """``P + (A + B) q`` elementwise: ``P`` plus the trapezoid of ``A, B`` over the interval ``2 q``."""
    return (
        P[0] + (A[0] + B[0]) * q, P[1] + (A[1] + B[1]) * q, P[2] + (A[2] + B[2]) * q,
        P[3] + (A[3] + B[3]) * q, P[4] + (A[4] + B[4]) * q, P[5] + (A[5] + B[5]) * q,
        P[6] + (A[6] + B[6]) * q, P[7] + (A[7] + B[7]) * q, P[8] + (A[8] + B[8]) * q,
    )  # fmt: skip


@njit(cache=True, error_model="numpy", inline="always")
def preintegrate_lanes(S, delta: float, q: float, d2: float) -> None:
    """Item 5 for all lanes: one sample of Forster's preintegration with the bias Jacobians.

    ``H = Exp(theta) = cos|th| I + sinc|th| [th x] + (1 - cos|th|)/|th|^2 th th^T`` (Benzerrouk 2014,
    eq. 4) per half sample; mid-sample attitude ``R_m = R H`` for the velocity (eq. 6),
    ``a = R_m f``, trapezoid for the position (eq. 7); with ``q = delta / 4``, ``d2 = delta^2 / 2``::

        Psi_m = Psi + (R + R_m) q                 G = [a x] Psi_m
        Delta p += Delta v delta + a d2           Delta v += a delta
        J_pa += J_va delta + R_m d2               J_va += R_m delta
        J_pg += J_vg delta + G d2                 J_vg += G delta
        R' = R_m H                                Psi' = Psi_m + (R_m + R') q

    Two loops over the lanes (attitude, then velocity, position and Jacobians) rather than one,
    so that the live values fit the 32 vector registers. Also the step of
    :func:`navgym.quadrotor.preintegration_kernel.preintegrate_rows_pass` (the Pedestrian and
    Replay resets), which fills the same rows of ``S``.
    """
    for l in range(LANES):
        tx, ty, tz = S[_TH, l], S[_TH + 1, l], S[_TH + 2, l]
        ca, cb, cc = S[_CA, l], S[_CB, l], S[_CC, l]
        H = (
            cb * tx * tx + cc, cb * tx * ty - ca * tz, cb * tx * tz + ca * ty,
            cb * ty * tx + ca * tz, cb * ty * ty + cc, cb * ty * tz - ca * tx,
            cb * tz * tx - ca * ty, cb * tz * ty + ca * tx, cb * tz * tz + cc,
        )  # fmt: skip
        R = _load9(S, _R, l)
        Rm = _matmul(R, H)
        f0, f1, f2 = S[_F, l], S[_F + 1, l], S[_F + 2, l]
        S[_ACC, l] = Rm[0] * f0 + Rm[1] * f1 + Rm[2] * f2
        S[_ACC + 1, l] = Rm[3] * f0 + Rm[4] * f1 + Rm[5] * f2
        S[_ACC + 2, l] = Rm[6] * f0 + Rm[7] * f1 + Rm[8] * f2
        psim = _trapezoid(_load9(S, _PSI, l), R, Rm, q)
        Rn = _matmul(Rm, H)
        _store9(S, _RM, l, Rm)
        _store9(S, _PSIM, l, psim)
        _store9(S, _PSI, l, _trapezoid(psim, Rm, Rn, q))
        _store9(S, _R, l, Rn)
    for l in range(LANES):
        acc = (S[_ACC, l], S[_ACC + 1, l], S[_ACC + 2, l])
        G = _skew_mul(acc, _load9(S, _PSIM, l))
        for i in range(3):
            S[_DP + i, l] += S[_DV + i, l] * delta + acc[i] * d2
            S[_DV + i, l] += acc[i] * delta
        for i in range(9):
            rm, jva, jvg = S[_RM + i, l], S[_JVA + i, l], S[_JVG + i, l]
            S[_JPA + i, l] += jva * delta + rm * d2
            S[_JPG + i, l] += jvg * delta + G[i] * d2
            S[_JVA + i, l] = jva + rm * delta
            S[_JVG + i, l] = jvg + G[i] * delta


@njit(cache=True, error_model="numpy")
def _kernel(
    t_seg, dur, p_start, p_end, yaw_start, yaw_end,
    t0, k0, nc, dt, n_sub,
    omega, gamma_nodes, bias, noise, na, ng,
    dR, phi, d6, J6, stats,
):  # fmt: skip  # pragma: no cover - compiled; exercised through preintegrated_imu
    """Blocks of LANES episodes; per block, steps; per step, samples (module docstring).

    ``stats`` ``(B, T, N_STATS)`` receives the steps' sample sums, or is empty ``(0, 0, N_STATS)``
    for none.
    """
    B = t_seg.shape[0]
    want = stats.shape[0] > 0
    plan = (t_seg, dur, p_start, p_end, yaw_start, yaw_end)
    delta = dt / n_sub
    h = 0.5 * delta
    q = 0.25 * delta
    d2 = 0.5 * delta * delta
    S = np.zeros((_NROWS, LANES))  # constant shape: the lane loops compile to vector code
    ep = np.zeros(LANES, dtype=np.int64)  # episode of each lane
    seg = np.zeros(LANES, dtype=np.int64)  # its active phase
    turning = np.zeros(LANES, dtype=np.int64)  # lanes in a yaw turn: turning[:n_turning]
    for b0 in range(0, B, LANES):
        n_lanes = min(LANES, B - b0)
        for l in range(LANES):
            b = min(b0 + l, B - 1)  # spare lanes of the last block repeat its last episode
            ep[l] = b
            S[_OX, l], S[_OY, l], S[_OZ, l] = omega[b, 0], omega[b, 1], omega[b, 2]
            S[_T0, l] = t0[b]
            seg[l] = 0
            _enter_phase(S, l, b, 0, plan)
        n_turning = -1  # to be listed
        for kk in range(nc):
            k = k0 + kk
            # the step's inputs and the initial state; prefetch the next step's lines
            for l in range(LANES):
                b = ep[l]
                S[_NA, l], S[_NG, l] = na[b, k], ng[b, k]
                for i in range(6):
                    S[_BIAS + i, l] = bias[b, k, i]
                for i in range(3):
                    for c in range(3):
                        S[_GAM + 3 * i + c, l] = gamma_nodes[b, 2 * k + i, c]
                for i in range(9):
                    S[_R + i, l] = 1.0 if i % 4 == 0 else 0.0
                    S[_PSI + i, l] = 0.0
                    S[_JVA + i, l] = S[_JVG + i, l] = S[_JPA + i, l] = S[_JPG + i, l] = 0.0
                for i in range(3):
                    S[_DV + i, l] = S[_DP + i, l] = 0.0
                for i in range(8):
                    S[_SF + i, l] = 0.0
                if kk + 1 < nc:
                    _prefetch_run(noise, (b * nc + kk + 1) * n_sub * 6, n_sub * 6)
                    _prefetch_run(bias, (b * bias.shape[1] + k + 1) * 6, 6)
                    _prefetch_run(gamma_nodes, (b * gamma_nodes.shape[1] + 2 * k + 2) * 3, 9)
                    _prefetch_run(dR, (b * dR.shape[1] + k + 1) * 9, 9)
                    _prefetch_run(phi, (b * phi.shape[1] + k + 1) * 9, 9)
                    _prefetch_run(d6, (b * d6.shape[1] + k + 1) * 6, 6)
                    _prefetch_run(J6, (b * J6.shape[1] + k + 1) * 36, 36)
            for j in range(n_sub):
                # the sample's time, and the active phase of the lanes that cross a boundary
                n_cross = 0
                for l in range(LANES):
                    t = S[_T0, l] + k * dt + (j + 0.5) * delta
                    S[_T, l] = t
                    n_cross += t >= S[_TNEXT, l]
                if n_cross > 0:
                    for l in range(LANES):
                        t = S[_T, l]
                        if t >= S[_TNEXT, l]:
                            b = ep[l]
                            while seg[l] + 1 < t_seg.shape[1] and t_seg[b, seg[l] + 1] <= t:
                                seg[l] += 1
                            _enter_phase(S, l, b, seg[l], plan)
                    n_turning = -1
                if n_turning < 0:
                    n_turning = 0
                    for l in range(LANES):
                        if S[_DY, l] != 0.0:
                            turning[n_turning] = l
                            n_turning += 1
                # yaw of the lanes in a turn: psi = psi_0 + dpsi s(tau)
                for i in range(n_turning):
                    l = turning[i]
                    yaw = S[_Y0, l] + S[_DY, l] * _smooth((S[_T, l] - S[_TS, l]) * S[_INVD, l])[0]
                    S[_CY, l] = math.cos(yaw)
                    S[_SY, l] = math.sin(yaw)
                for c in range(6):
                    for l in range(LANES):
                        S[_E + c, l] = noise[ep[l], kk, j, c]
                # gravity: Lagrange weights of the nodes at s = (j + 1/2) / n_sub of the step
                sf = (j + 0.5) / n_sub
                l0 = 2.0 * (sf - 0.5) * (sf - 1.0)
                lm = -4.0 * sf * (sf - 1.0)
                l1 = 2.0 * sf * (sf - 0.5)
                if _flat_imu(S, l0, lm, l1, h) > 0:
                    _large_angles(S)
                if want:
                    _accumulate(S)
                preintegrate_lanes(S, delta, q, d2)
            for l in range(n_lanes):
                b = b0 + l
                for r in range(3):
                    for c in range(3):
                        dR[b, k, r, c] = S[_R + 3 * r + c, l]
                        phi[b, k, r, c] = (
                            S[_R + r, l] * S[_PSI + c, l] + S[_R + 3 + r, l] * S[_PSI + 3 + c, l]
                            + S[_R + 6 + r, l] * S[_PSI + 6 + c, l]
                        )  # fmt: skip
                        J6[b, k, r, c] = -S[_JVA + 3 * r + c, l]
                        J6[b, k, r, 3 + c] = S[_JVG + 3 * r + c, l]
                        J6[b, k, 3 + r, c] = -S[_JPA + 3 * r + c, l]
                        J6[b, k, 3 + r, 3 + c] = S[_JPG + 3 * r + c, l]
                    d6[b, k, r] = S[_DV + r, l]
                    d6[b, k, 3 + r] = S[_DP + r, l]
                if want:
                    inv_h = 1.0 / h
                    for i in range(3):
                        stats[b, k, i] = S[_SF + i, l]
                        stats[b, k, 4 + i] = S[_STH + i, l] * inv_h
                    stats[b, k, 3] = S[_SF2, l]
                    stats[b, k, 7] = S[_STH2, l] * inv_h * inv_h


def preintegrated_imu(
    plans,
    t0: np.ndarray,
    k0: int,
    dt: float,
    n_sub: int,
    omega: np.ndarray,
    gamma_nodes: np.ndarray,
    bias: np.ndarray,
    noise: np.ndarray,
    na: np.ndarray,
    ng: np.ndarray,
    out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    stats: np.ndarray | None = None,
) -> None:
    """Preintegrate steps ``k0 .. k0 + nc - 1`` of B episodes from their measured IMU samples.

    Step ``k`` of episode ``b`` integrates the ``n_sub`` samples at
    ``t0[b] + k dt + (j + 1/2) dt / n_sub`` (module docstring, items 1-5).

    Args:
        plans: :class:`~navgym.quadrotor.flight.QuadrotorPlan` of the B episodes.
        t0: Flight time of each episode's epoch 0 [s], ``(B,)``.
        k0: First step of the chunk.
        dt: Step (GNSS epoch) [s].
        n_sub: IMU samples per step.
        omega: Earth rate in the home frame [rad/s], ``(B, 3)``.
        gamma_nodes: :func:`~navgym.quadrotor.flight.home_gravity` at the epochs and step
            mid-points, ``t0 + i dt / 2``, ``(B, 2 T + 1, 3)``.
        bias: IMU biases ``[b_a, b_g]`` per epoch, ``(B, T + 1, 6)`` (step ``k`` uses epoch ``k``).
        noise: Standard normals of the chunk's samples, ``(B, nc, n_sub, 6)``.
        na: Accelerometer white-noise standard deviation per sample [m/s^2], ``(B,)`` (one per
            episode) or ``(B, T)`` (one per step ``k``, for the vibration bursts of the v2 episodes;
            at least ``k0 + nc`` steps).
        ng: Gyro white-noise standard deviation per sample [rad/s], ``(B,)`` or ``(B, T)`` as ``na``.
        out: ``(dR, phi, d6, J6)`` of shapes ``(B, T, 3, 3)``, ``(B, T, 3, 3)``, ``(B, T, 6)``,
            ``(B, T, 6, 6)``, written at steps ``k0 .. k0 + nc - 1``.
        stats: ``(B, T, N_STATS)``, C-contiguous float64, or None: the steps' sums over their
            samples of the measured ``f`` (3), ``|f|^2``, ``omega`` (3) and ``|omega|^2`` (the
            Quadrotor's v3 IMU context), written at the same steps. The other outputs do not
            depend on it.
    """
    nc = noise.shape[1]
    if noise.shape[2] != n_sub or noise.shape[3] != 6:
        raise ValueError(f"noise must be (B, nc, {n_sub}, 6); got {noise.shape}")
    if gamma_nodes.shape[1] < 2 * (k0 + nc) + 1:
        raise ValueError(f"gamma_nodes must cover epoch {k0 + nc}; got {gamma_nodes.shape[1]} nodes")

    if stats is not None and (
        stats.dtype != np.float64
        or not stats.flags.c_contiguous
        or stats.ndim != 3
        or stats.shape[0] != noise.shape[0]
        or stats.shape[1] < k0 + nc
        or stats.shape[2] != N_STATS
    ):
        raise ValueError(
            f"stats must be C-contiguous float64 (B, >= {k0 + nc}, {N_STATS}); got {stats.shape}"
        )

    def f64(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a, dtype=np.float64)

    def per_step(name: str, a: np.ndarray) -> np.ndarray:
        a = np.asarray(a, dtype=np.float64)
        if a.ndim == 1:  # one value per episode: the same at every step
            return np.broadcast_to(a[:, None], (a.shape[0], k0 + nc))
        if a.ndim != 2 or a.shape[1] < k0 + nc:
            raise ValueError(f"{name} must be (B,) or (B, T) with T >= {k0 + nc}; got {a.shape}")
        return a

    _kernel(
        f64(plans.t_start), f64(plans.duration), f64(plans.p_start), f64(plans.p_end),
        f64(plans.yaw_start), f64(plans.yaw_end),
        f64(t0), int(k0), int(nc), float(dt), int(n_sub),
        f64(omega), f64(gamma_nodes), f64(bias), f64(noise), f64(per_step("na", na)), f64(per_step("ng", ng)),
        *out, np.empty((0, 0, N_STATS)) if stats is None else stats,
    )  # fmt: skip
