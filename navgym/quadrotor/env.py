"""Quadrotor: seed 001's direct INS/GNSS filter on "return to home" triangle flights.

**Truth** (seed 001 §2.7a): an AR.Drone-class quadrotor flies a closed triangle with legs of
100-500 m, climbs, hovers and turns at the vertices (:mod:`navgym.quadrotor.flight`). An
episode covers ``T dt`` seconds of the flight starting at a time drawn uniformly in
``[0, t_landed - T dt]`` (clipped at 0), so episodes see take-off, legs, turns, hovers and the
landing. The IMU samples the exact kinematics (``f_ib^b``, ``omega_ib^b`` on the rotating
ellipsoid) at ``imu_rate_hz = 200`` Hz (seed 001: dt = 0.005 s) at the sample midpoints, with the
errors of :class:`navgym.ins.ImuErrorSpec` (seed 001 eq. 2 and 5: measured = true + bias + white
noise; consumer MEMS by default): turn-on biases, white noise per sample, and a bias random walk
advanced once per GNSS epoch (so the bias is constant over a filter step, as the filter assumes).
With ``imu_mismatch = (lo, hi)`` (Fading's default ``(0.5, 4)``) the true IMU's error parameters
are those of the grade times a factor drawn log-uniformly per episode, while the filter keeps
the grade's model: the model mismatch a fading factor exists to absorb.

**Filter state** (seed 001 eq. 11, *direct* filtering: the filter estimates the navigation
states themselves, not INS errors)::

    x = [p (3), v (3), (roll, pitch, yaw) (3), b_a (3), b_g (3)]        n = 15

position and velocity in the home's NED tangent frame [m, m/s], 3-2-1 Euler angles of
``C_b^t = R_z(yaw) R_y(pitch) R_x(roll)`` [rad] (yaw is not wrapped, so sigma points never
straddle +-pi), accelerometer [m/s^2] and gyro [rad/s] biases (measured = true + bias).

**Mechanization** (seed 001 eq. 3-7). The tangent frame is Earth-fixed, so the transport rate
of eq. 3-7's local-level frame vanishes; seed 001 further neglects the Earth rate. Here it is
kept because it is cheap and makes the model exact at these distances (15 deg/h is below the
consumer gyro bias but not below a tactical one)::

    dC/dt = C [omega x] - [Omega x] C,   dv/dt = C f + g(p) - 2 Omega x v,   dp/dt = v

with ``Omega`` the Earth rate in the home frame and ``g(p) = g0 + diag(Gamma) p`` normal gravity
at home plus its linear variation (the ellipsoid normal tilts by ``p_n / (R_M + h)`` and
``p_e / (R_N + h)``; free-air gradient ``dgamma/dh``); neglected terms are below 1e-5 m/s^2
within 1 km of home.

**Transition** (one GNSS epoch ``T = dt = 0.1`` s, ``n_sub = 20`` IMU samples). The 20 samples are
integrated with seed 001 eq. 4 (Rodrigues, per sample), eq. 6 (velocity, at the mid-sample
attitude) and eq. 7 (position, trapezoid) in the body frame of the step start -- the IMU
*preintegration* of Forster et al. (IEEE T-RO 33(1), 2017, eq. 33-44): ``dR``, ``dv^b``, ``dp^b``
and their Jacobians with respect to the biases (``Phi``, ``J_va``, ``J_vg``, ``J_pa``,
``J_pg``). They depend only on the measured samples, so they are computed at reset for the
whole episode, together with the samples themselves, by the compiled kernel
:mod:`navgym.quadrotor.imu_kernel` (:func:`preintegrate_components` is the NumPy
reference). The step then is the exact closed form::

    C1 = E C0 dR Exp(-Phi b_g)                     E = I - [Omega T x], E_h = I - [Omega T / 2 x]
    v1 = v0 + E_h C0 (dv^b - J_va b_a + J_vg b_g) + a T
    p1 = p0 + v0 T + E_h C0 (dp^b - J_pa b_a + J_pg b_g) + a T^2 / 2
    a  = g(p0 + v0 T / 2) - 2 Omega x v0

which is the 20-sample integration exactly for zero bias and to second order in ``b_g T``
(1e-8 rad for a consumer gyro) otherwise (``Exp(-Phi b_g)`` to second order; the Earth's
rotation over a step, 7e-6 rad, to first order; Coriolis from ``v0``: below 1e-5 m/s per step
in all); its EKF Jacobian ``F`` is analytic and exact for this ``f``. The same ``f`` broadcasts
over sigma points ``(B, S, n)``, so a CKF pays one 3x3 chain per point instead of 20 sub-steps.
Process noise ``Q`` per step: velocity random walk ``sigma_a^2 T`` (with the integrated
position terms ``T^3/3``, ``T^2/2``), angle random walk ``sigma_g^2 T`` on the Euler angles
(exact when level, 1 + tan^2(tilt) off level: the quadrotor's tilt stays below ~15 deg), bias
random walks ``sigma_w^2 T``.

**Measurements** (seed 001 eq. 12 and 14, loosely coupled): a GNSS receiver's position and
velocity fix at 10 Hz in the home NED frame, ``z = [p, v] + noise``, ``m_max = 6`` rows, all six
present or absent together (the mask). Nominal noise (u-blox M8-class receiver, datasheet
2.5 m CEP and 0.05 m/s): ``sigma_pos = 2`` m and ``sigma_vel = 0.1`` m/s per horizontal axis,
1.5 times that vertically; white, which is seed 001's eq. 16 assumption. Degradations come from
the scenario (:mod:`navgym.scenarios`): outages (no fix); jamming (extra noise ``jam_sigma`` on
each position row and ``jam_sigma sigma_vel / sigma_pos`` on each velocity row, and the fix lost
with probability ``loss_prob`` per epoch); impulsive noise (seed 001 eq. 71), one mixture draw
**per epoch**: with probability ``eps`` the whole fix has ``var_ratio`` times the nominal
variance, which is exactly the two-component model the Gaussian-sum filter assumes; outlier
periods (a gross error ``N(0, outlier_scale^2)`` on each position row, scaled on the velocity
rows, with probability ``outlier_prob`` per epoch). Partial outages have no meaning for a
position fix and are ignored.

Everything the filter uses (preintegrated IMU, fixes, the home's gravity and Earth rate) is
estimator-side; the true states live in ``Episodes.truth`` and reach ``info`` only.

**Divergence.** Besides the core's rules (health flag, horizontal error beyond ``divergence_m``,
horizontal sigma beyond ``SIGMA_DIVERGENCE x divergence_m``), a runaway covariance (any state
variance beyond ``RUNAWAY_VARIANCE = 1e12`` or non-finite; the yaw and biases are weakly
observable from fixes, so fading inflates them while the position stays pinned) ends the episode:
:meth:`QuadrotorPlatform.position_error` reports ``cov_ne`` as infinite, before the covariance
can overflow.

**Speed.** Small 3x3 algebra is written component-first (``(3, 3, B, S)`` arrays, five ufunc calls
per product) because NumPy's stacked 3x3 ``matmul`` costs one BLAS call per matrix.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels
from navgym.geo import gravity, meridian_radius, normal_radius
from navgym.ins import CONSUMER_MEMS, PERFECT, TACTICAL, ImuErrorSpec, earth_rate_ned
from navgym.quadrotor.flight import (
    QuadrotorParams,
    home_gravity,
    quadrotor_home_truth,
    quadrotor_positions,
    sample_quadrotor_plans,
)
from navgym.scenarios import (
    Scenario,
    ScenarioDistribution,
    default_rngs,
    gnss_available,
    noise_regime,
    stack_scenarios,
)

__all__ = [
    "QuadrotorPlatform",
    "QuadrotorEpisodes",
    "StrapdownTransition",
    "GnssFixModel",
    "QuadrotorEnv",
    "QuadrotorVectorEnv",
    "make_platform",
    "preintegrate",
    "exp_so3",
    "euler_dcm",
    "N_STATE",
    "M_ROWS",
]

#: State dimension: position, velocity, Euler angles, accelerometer and gyro biases.
N_STATE = 15
#: Measurement rows: GNSS position (3) and velocity (3), NED.
M_ROWS = 6
#: GNSS position noise per horizontal axis [m] (u-blox M8 class: 2.5 m CEP ~ 2.1 m per axis).
SIGMA_POS_M = 2.0
#: GNSS velocity noise per horizontal axis [m/s] (datasheet 0.05 m/s, taken conservatively).
SIGMA_VEL_MS = 0.1
#: Vertical-to-horizontal noise ratio of a GNSS fix (VDOP / HDOP of a typical sky).
VERTICAL_FACTOR = 1.5
#: Prior of a start mid-flight: velocity [m/s], roll/pitch [rad], yaw [rad] 1-sigma.
SIGMA_VEL0 = 0.2
SIGMA_TILT0 = np.deg2rad(1.0)
SIGMA_YAW0 = np.deg2rad(5.0)
#: Floors of the prior bias sigmas (so the "perfect" grade keeps a positive definite prior).
BIAS0_FLOOR = (1e-4, 1e-6)
#: IMU grades accepted by ``imu_grade`` ("perfect" is meant for tests).
IMU_GRADES: dict[str, ImuErrorSpec] = {"consumer": CONSUMER_MEMS, "tactical": TACTICAL, "perfect": PERFECT}
#: A state variance beyond this (any unit) is a runaway covariance: the episode ends as diverged.
RUNAWAY_VARIANCE = 1e12
#: IMU samples (over all episodes) per chunk when simulating at reset: bounds the buffer of their
#: normals (6 per sample, 25 MB).
_CHUNK_SAMPLES = 1 << 19

_I3 = np.eye(3)
_H_FIX = np.eye(M_ROWS, N_STATE)


# ---------------------------------------------------------------------------------------------
# Rotation algebra, component-first ("SoA"): vectors (3, ...), matrices (3, 3, ...) with M[i, j]
# the row-i, column-j entry over any trailing axes. NumPy's stacked 3x3 matmul costs one BLAS call
# per matrix; five ufunc calls over the trailing axes are 5-10x faster here.
# ---------------------------------------------------------------------------------------------
def _mm(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``A X`` for ``A (3, 3, ...)`` and ``X (3, m, ...)``."""
    return A[:, 0, None] * X[0] + A[:, 1, None] * X[1] + A[:, 2, None] * X[2]


def _mtm(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``A^T X`` for ``A (3, 3, ...)`` and ``X (3, m, ...)``."""
    return A[0, :, None] * X[0] + A[1, :, None] * X[1] + A[2, :, None] * X[2]


def _mv(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``A v`` for ``A (3, 3, ...)`` and ``v (3, ...)``."""
    return A[:, 0] * v[0] + A[:, 1] * v[1] + A[:, 2] * v[2]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` along axis 0 (``a`` broadcast against ``b``; for matrices: ``[a x] B`` by columns)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(a[j], b[k], out=out[i, ...])
        out[i] -= a[k] * b[j]
    return out


def _cross_rows(M: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``M [u x]`` for ``M (3, 3, ...)`` and ``u (3, ...)``: each row ``r_i`` becomes ``r_i x u``."""
    out = np.empty(np.broadcast_shapes(M.shape, (3,) + u.shape))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(M[:, j], u[k], out=out[:, i, ...])
        out[:, i] -= M[:, k] * u[j]
    return out


def _exp_soa(th: np.ndarray) -> np.ndarray:
    """Rodrigues (seed 001 eq. 4): ``Exp(th) = cos|th| I + sinc [th x] + (1 - cos)/|th|^2 th th^T``.

    ``(1 - cos x) / x^2 = sinc(x / 2)^2 / 2`` keeps small angles free of cancellation.
    """
    x = np.sqrt(th[0] * th[0] + th[1] * th[1] + th[2] * th[2])
    a = np.sinc(x / np.pi)
    b = 0.5 * np.sinc(x / (2.0 * np.pi)) ** 2
    bt = b * th
    H = bt[:, None] * th[None]
    c = np.cos(x)
    at = a * th
    H[0, 0] += c
    H[1, 1] += c
    H[2, 2] += c
    H[0, 1] -= at[2]
    H[1, 0] += at[2]
    H[0, 2] += at[1]
    H[2, 0] -= at[1]
    H[1, 2] -= at[0]
    H[2, 1] += at[0]
    return H


def exp_so3(u: np.ndarray) -> np.ndarray:
    """Rotation matrices ``Exp(u)`` ``(..., 3, 3)`` of rotation vectors ``u (..., 3)`` (seed 001 eq. 4)."""
    H = _exp_soa(np.moveaxis(np.asarray(u, np.float64), -1, 0))
    return np.moveaxis(H, (0, 1), (-2, -1))


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped into [-pi, pi)."""
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _euler_dcm_soa(e: np.ndarray) -> np.ndarray:
    """``C = R_z(yaw) R_y(pitch) R_x(roll)`` ``(3, 3, ...)`` of Euler angles ``(3, ...)``."""
    sr, cr = np.sin(e[0]), np.cos(e[0])
    sp, cp = np.sin(e[1]), np.cos(e[1])
    sy, cy = np.sin(e[2]), np.cos(e[2])
    C = np.empty((3, 3) + e.shape[1:])
    srsp, crsp = sr * sp, cr * sp
    np.multiply(cp, cy, out=C[0, 0, ...])
    np.multiply(cp, sy, out=C[1, 0, ...])
    np.negative(sp, out=C[2, 0, ...])
    np.multiply(srsp, cy, out=C[0, 1, ...])
    C[0, 1] -= cr * sy
    np.multiply(srsp, sy, out=C[1, 1, ...])
    C[1, 1] += cr * cy
    np.multiply(sr, cp, out=C[2, 1, ...])
    np.multiply(crsp, cy, out=C[0, 2, ...])
    C[0, 2] += sr * sy
    np.multiply(crsp, sy, out=C[1, 2, ...])
    C[1, 2] -= sr * cy
    np.multiply(cr, cp, out=C[2, 2, ...])
    return C


def euler_dcm(e: np.ndarray) -> np.ndarray:
    """``C_b^t = R_z(yaw) R_y(pitch) R_x(roll)`` ``(..., 3, 3)`` of Euler angles ``(..., 3)``."""
    return np.moveaxis(_euler_dcm_soa(np.moveaxis(e, -1, 0)), (0, 1), (-2, -1))


def _euler_of(
    c20: np.ndarray, c21: np.ndarray, c22: np.ndarray, c10: np.ndarray, c00: np.ndarray, ref: np.ndarray
) -> np.ndarray:
    """Euler angles (3, ...) from five DCM entries; roll and yaw unwrapped within pi of ``ref``."""
    roll = np.arctan2(c21, c22)
    pitch = -np.arcsin(np.clip(c20, -1.0, 1.0))
    yaw = np.arctan2(c10, c00)
    return np.stack([ref[0] + _wrap(roll - ref[0]), pitch, ref[2] + _wrap(yaw - ref[2])])


def _euler_rate_soa(e: np.ndarray, inverse: bool = False) -> np.ndarray:
    """``N(e)`` (or ``N^-1``), ``(3, 3, ...)``: tangent-frame rotation of an Euler increment.

    ``C(e + de) = Exp(N de) C(e)`` with ``N = [R_z R_y e_x, R_z e_y, e_z]``; its inverse is seed 001
    eq. 11's ``E_b^n`` in tangent-frame form. ``cos(pitch)`` is kept above 1e-6 (the Euler
    parametrization is singular at +-90 deg, which a quadrotor never reaches).
    """
    sp, cp = np.sin(e[1]), np.cos(e[1])
    cp = np.where(np.abs(cp) < 1e-6, np.copysign(1e-6, cp), cp)
    sy, cy = np.sin(e[2]), np.cos(e[2])
    N = np.zeros((3, 3) + e.shape[1:])
    N[1, 0] = N[0, 1] = sy
    N[1, 1] = cy
    N[2, 2] = 1.0
    if not inverse:
        np.multiply(cy, cp, out=N[0, 0, ...])
        np.negative(sy, out=N[0, 1, ...])
        np.multiply(sy, cp, out=N[1, 0, ...])
        np.negative(sp, out=N[2, 0, ...])
    else:
        np.divide(cy, cp, out=N[0, 0, ...])
        np.divide(sy, cp, out=N[0, 1, ...])
        np.negative(sy, out=N[1, 0, ...])
        tp = sp / cp
        np.multiply(cy, tp, out=N[2, 0, ...])
        np.multiply(sy, tp, out=N[2, 1, ...])
    return N


# ---------------------------------------------------------------------------------------------
# IMU preintegration (at reset)
# ---------------------------------------------------------------------------------------------
class Preintegrated(NamedTuple):
    """Preintegrated IMU of one filter step (leading axes of the inputs, then the shapes below).

    ``dR (3, 3)``, ``phi (3, 3)`` (``dR(b_g) = dR Exp(-phi b_g)``), ``dv (3)``, ``dp (3)`` in the
    body frame of the step start, and the bias Jacobians ``jva, jvg, jpa, jpg (3, 3)`` with
    ``dv(b) = dv - jva b_a + jvg b_g``, ``dp(b) = dp - jpa b_a + jpg b_g``.
    """

    dR: np.ndarray
    phi: np.ndarray
    dv: np.ndarray
    dp: np.ndarray
    jva: np.ndarray
    jvg: np.ndarray
    jpa: np.ndarray
    jpg: np.ndarray


def preintegrate(gyro: np.ndarray, accel: np.ndarray, delta: float) -> Preintegrated:
    """Integrate ``n_sub`` IMU samples per step (seed 001 eq. 4, 6, 7; Forster et al. 2017).

    Per sample ``j`` (rate ``w_j``, specific force ``f_j``, interval ``delta``), with
    ``H = Exp(w_j delta / 2)`` (eq. 4):

    * ``R_mid = R_j H``, ``R_{j+1} = R_mid H``;
    * ``dv += R_mid f_j delta`` (eq. 6 at the mid-sample attitude),
      ``dp += dv_j delta + R_mid f_j delta^2 / 2`` (eq. 7, exact for a constant sample);
    * bias Jacobian of the rotation, ``dR_j(b_g) = dR_j Exp(-phi_j b_g)`` with
      ``phi_{j+1} = Exp(w_j delta)^T phi_j + Jr(w_j delta) delta`` (Forster eq. 44 in two
      half-samples, ``Jr(w h) ~ (I + H^T) / 2``); carried as ``psi_j = R_j phi_j``, which is then
      the trapezoidal integral of ``R``: ``psi_{j+1} = psi_j + (R_j + 2 R_mid + R_{j+1}) delta / 4``;
    * ``jva += R_mid delta``, ``jvg += [a_j x] psi_mid delta`` (``a_j = R_mid f_j``, since
      ``R [f x] phi = [R f x] R phi``), and the position Jacobians as ``dp``.

    Args:
        gyro: measured rates ``(..., n_sub, 3)`` [rad/s].
        accel: measured specific forces ``(..., n_sub, 3)`` [m/s^2].
        delta: sample interval [s].

    Returns:
        :class:`Preintegrated` over the leading axes.
    """
    lead = gyro.shape[:-2]
    n_sub = gyro.shape[-2]
    N = int(np.prod(lead))
    w = np.ascontiguousarray(gyro.reshape(N, n_sub, 3).transpose(1, 2, 0))  # (n_sub, 3, N)
    f = np.ascontiguousarray(accel.reshape(N, n_sub, 3).transpose(1, 2, 0))

    def out(a: np.ndarray) -> np.ndarray:
        return np.moveaxis(a, -1, 0).reshape(lead + a.shape[:-1])

    return Preintegrated(*(out(a) for a in preintegrate_components(w, f, delta)))


def preintegrate_components(w: np.ndarray, f: np.ndarray, delta: float) -> Preintegrated:
    """:func:`preintegrate` on component slabs: samples ``w, f (n_sub, 3, N)``.

    Returns:
        :class:`Preintegrated` with the N steps last: ``dR (3, 3, N)``, ``dv (3, N)``, ...
    """
    n_sub, _, N = w.shape
    R = np.zeros((3, 3, N))
    R[0, 0] = R[1, 1] = R[2, 2] = 1.0
    psi = np.zeros((3, 3, N))
    dv = np.zeros((3, N))
    dp = np.zeros((3, N))
    jva, jvg, jpa, jpg = (np.zeros((3, 3, N)) for _ in range(4))
    h = 0.5 * delta
    q = 0.25 * delta
    d2 = 0.5 * delta * delta
    for j in range(n_sub):
        H = _exp_soa(w[j] * h)
        R_mid = _mm(R, H)
        a = _mv(R_mid, f[j])
        psi_mid = psi + (R + R_mid) * q
        G = _cross(a[:, None], psi_mid)
        dp += dv * delta + a * d2
        jpa += jva * delta + R_mid * d2
        jpg += jvg * delta + G * d2
        dv += a * delta
        jva += R_mid * delta
        jvg += G * delta
        R_next = _mm(R_mid, H)
        psi = psi_mid + (R_mid + R_next) * q
        R = R_next
    return Preintegrated(R, _mtm(R, psi), dv, dp, jva, jvg, jpa, jpg)


# ---------------------------------------------------------------------------------------------
# Models
# ---------------------------------------------------------------------------------------------
class StrapdownTransition(NamedTuple):
    """Strapdown transition of one GNSS epoch (module docstring), batched over B episodes.

    The step's preintegrated IMU and the home's gravity and Earth rate are parameters batched on
    axis 0 (aligned with the filters' batch axis); ``f`` broadcasts over ``(B, n)`` and
    ``(B, S, n)``. The Earth's rotation over a step (3.6e-6 rad per half step) enters to first
    order, ``E_h = I - [Omega T / 2 x]``, ``E = I - [Omega T x]`` (errors below 1e-11).

    ``memo`` holds the last ``(x, f(x), intermediates)``: the EKF asks for ``F(m)`` then ``f(m)``
    with the same array ``m``, which is then propagated once.
    """

    dR: np.ndarray  # (B, 3, 3)
    phi: np.ndarray  # (B, 3, 3)
    d6: np.ndarray  # (B, 6) [dv^b, dp^b]
    J6: np.ndarray  # (B, 6, 6) [[-jva, jvg], [-jpa, jpg]]: d6(b) = d6 + J6 [b_a, b_g]
    gravity: np.ndarray  # (B, 3) g0 at home, tangent frame [m/s^2]
    gradient: np.ndarray  # (B, 3) diag(Gamma) [1/s^2]
    earth_rate: np.ndarray  # (B, 3) Omega in the tangent frame [rad/s]
    T: float  # step [s]
    Q: np.ndarray  # (n, n)
    memo: list | None = None

    def repeat_batch(self, K: int) -> StrapdownTransition:
        """Each episode's parameters repeated K times (Gaussian-sum filters stack components)."""
        return StrapdownTransition(*(np.repeat(a, K, axis=0) for a in self[:7]), self.T, self.Q, [None])

    def _propagate(self, x: np.ndarray) -> tuple[np.ndarray, tuple]:
        memo = self.memo
        if memo is not None and memo[0] is not None and memo[0][0] is x:
            return memo[0][1], memo[0][2]
        B, n = x.shape[0], x.shape[-1]
        X = x.reshape(B, -1, n)  # (B, K, n)
        K = X.shape[1]
        T = self.T
        xs = np.ascontiguousarray(X.transpose(2, 0, 1))  # (n, B, K), component first
        p0, v0, e0, bg = xs[0:3], xs[3:6], xs[6:9], xs[12:15]
        prm = np.ascontiguousarray(np.concatenate([self.dR.reshape(B, 9), self.phi.reshape(B, 9)], axis=1).T)
        dR, phi = prm[:9].reshape(3, 3, B, 1), prm[9:].reshape(3, 3, B, 1)
        vec = np.ascontiguousarray(np.concatenate([self.earth_rate, self.gravity, self.gradient], axis=1).T)
        om, g, gr = vec[0:3, :, None], vec[3:6, :, None], vec[6:9, :, None]
        # [dv^b, dp^b] with the bias corrections: one small GEMM per episode.
        if K == 1:  # EKF: elementwise beats B tiny GEMMs
            inc = ((self.J6 * X[:, 0, None, 9:15]).sum(-1) + self.d6)[:, None]  # (B, 1, 6)
        else:
            inc = X[..., 9:15] @ self.J6.transpose(0, 2, 1) + self.d6[:, None]  # (B, K, 6)
        inc = np.ascontiguousarray(inc.transpose(2, 0, 1)).reshape(2, 3, B, K).transpose(1, 0, 2, 3)
        C0 = _euler_dcm_soa(e0)  # (3, 3, B, K)
        wh = (0.5 * T) * om  # (3, B, 1)
        y = _mm(C0, inc)  # C0 [dv^b, dp^b]
        y -= _cross(wh[:, None], y)  # E_h C0 [dv^b, dp^b]
        dv_t, dp_t = y[:, 0], y[:, 1]
        acc = p0 + (0.5 * T) * v0
        acc *= gr
        acc += g
        acc -= 2.0 * _cross(om, v0)
        out = np.empty((n, B, K))
        p1, v1 = out[0:3], out[3:6]
        np.multiply(acc, T, out=v1)
        v1 += v0
        v1 += dv_t
        np.multiply(acc, 0.5 * T * T, out=p1)
        p1 += p0
        p1 += T * v0
        p1 += dp_t
        u = _mv(phi, bg)
        np.negative(u, out=u)  # u = -Phi b_g, (3, B, K)
        A = _mm(C0, dR)  # C0 dR
        m1 = _cross_rows(A, u)
        A += m1
        A += 0.5 * _cross_rows(m1, u)  # C0 dR Exp(u), second order
        w2 = 2.0 * wh
        # Entries of C1 = E A = A - [2 w_h x] A needed for the Euler angles.
        c20 = A[2, 0] - (w2[0] * A[1, 0] - w2[1] * A[0, 0])
        c21 = A[2, 1] - (w2[0] * A[1, 1] - w2[1] * A[0, 1])
        c22 = A[2, 2] - (w2[0] * A[1, 2] - w2[1] * A[0, 2])
        c10 = A[1, 0] - (w2[2] * A[0, 0] - w2[0] * A[2, 0])
        c00 = A[0, 0] - (w2[1] * A[2, 0] - w2[2] * A[1, 0])
        out[6:9] = _euler_of(c20, c21, c22, c10, c00, e0)
        out[9:15] = xs[9:15]
        res = np.ascontiguousarray(out.transpose(1, 2, 0)).reshape(x.shape)
        aux = (e0, out[6:9], C0, A, wh, dv_t, dp_t, u)
        if memo is not None:
            memo[0] = (x, res, aux)
        return res, aux

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        """Propagate states ``(B, n)`` or ``(B, S, n)`` over one step (module docstring)."""
        return self._propagate(x)[0]

    def F(self, x: np.ndarray, u: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        """Exact Jacobian ``df/dx`` at ``x (B, n)``, ``(B, n, n)``.

        With ``N(e)`` the Euler-rate matrix (``C(e + de) = Exp(N de) C``), ``W = [Omega x]``,
        ``D = diag(Gamma)``, ``J = I - [u x]/2`` (``u = -Phi b_g``)::

            dp/dp = I + D T^2/2      dp/dv = T I + (D T/2 - 2W) T^2/2    dp/de = -[dp_t x] E_h N0
            dv/dp = D T              dv/dv = I + (D T/2 - 2W) T          dv/de = -[dv_t x] E_h N0
            d[v, p]/db = E_h C0 J6 (rows dv, dp)
            de/de = N1^-1 E N0       de/db_g = -N1^-1 C1 J Phi
        """
        B, n = x.shape
        T = self.T
        _, (e0, e1, C0, A, wh, dv_t, dp_t, u) = self._propagate(x)
        e0, e1, C0, A, wh, dv_t, dp_t, u = (a[..., 0] for a in (e0, e1, C0, A, wh, dv_t, dp_t, u))
        wcol = wh[:, None]  # (3, 1, B)
        N0 = _euler_rate_soa(e0)
        wN0 = _cross(wcol, N0)
        C1 = A - _cross(2.0 * wcol, A)
        C0h = C0 - _cross(wcol, C0)
        N1i = _euler_rate_soa(e1, inverse=True)
        phi = np.ascontiguousarray(self.phi.transpose(1, 2, 0))
        C1Jphi = _mm(C1, phi - 0.5 * _cross(u[:, None], phi))
        Fm = np.zeros((B, n, n))
        # Position/velocity blocks: constant per episode (gravity gradient, Earth rate).
        Fm[:, 0:6, 0:6] = _pv_block(self.gradient, self.earth_rate, T)
        Fm[:, _BIAS, _BIAS] = 1.0
        # d(p, v)/de = -[(dp_t, dv_t) x] E_h N0
        y = np.stack([dp_t, dv_t], axis=1)[:, :, None]  # (3, 2, 1, B)
        Fm[:, 0:6, 6:9] = (-_cross(y, (N0 - wN0)[:, None])).transpose(3, 1, 0, 2).reshape(B, 6, 3)
        # d(v, p)/db = E_h C0 J6
        J6 = self.J6.transpose(1, 2, 0).reshape(2, 3, 6, B)  # [v rows, p rows]
        Ch = C0h[:, :, None, None]  # (3, 3, 1, 1, B)
        CJ = Ch[:, 0] * J6[:, 0] + Ch[:, 1] * J6[:, 1] + Ch[:, 2] * J6[:, 2]  # (3, 2, 6, B)
        Fm[:, 3:6, 9:15] = CJ[:, 0].transpose(2, 0, 1)
        Fm[:, 0:3, 9:15] = CJ[:, 1].transpose(2, 0, 1)
        # de/de = N1^-1 E N0, de/db_g = -N1^-1 C1 J Phi
        Fm[:, 6:9, 6:9] = _mm(N1i, N0 - 2.0 * wN0).transpose(2, 0, 1)
        Fm[:, 6:9, 12:15] = (-_mm(N1i, C1Jphi)).transpose(2, 0, 1)
        return Fm


def _pv_basis(T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Constant part and the gradient / Earth-rate bases of the (p, v) block of ``F``."""
    I3 = np.eye(3)
    c = np.block([[I3, T * I3], [np.zeros((3, 3)), I3]])
    G = np.zeros((3, 6, 6))
    W = np.zeros((3, 6, 6))
    for i in range(3):
        G[i, i, i] = G[i, i + 3, i + 3] = 0.5 * T * T  # D T^2 / 2 in dp/dp, D T^2 / 2 in dv/dv
        G[i, i, i + 3] = 0.25 * T**3  # D T^3 / 4 in dp/dv
        G[i, i + 3, i] = T  # D T in dv/dp
        j, k = (i + 1) % 3, (i + 2) % 3  # -2 [Omega x]: +2 w_i at (j, k), -2 w_i at (k, j)
        W[i, 3 + j, 3 + k], W[i, 3 + k, 3 + j] = 2.0 * T, -2.0 * T
        W[i, j, 3 + k], W[i, k, 3 + j] = T * T, -T * T
    return c, G.reshape(3, 36), W.reshape(3, 36)


def _pv_block(gradient: np.ndarray, earth_rate: np.ndarray, T: float) -> np.ndarray:
    """``[[dp/dp, dp/dv], [dv/dp, dv/dv]]`` ``(B, 6, 6)`` (see :meth:`StrapdownTransition.F`)."""
    c, G, W = _PV_BASIS.get(T) or _PV_BASIS.setdefault(T, _pv_basis(T))
    return (gradient @ G + earth_rate @ W).reshape(-1, 6, 6) + c


_PV_BASIS: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
_BIAS = np.arange(9, 15)


class GnssFixModel(NamedTuple):
    """GNSS position and velocity fix in the home NED frame (seed 001 eq. 12, 14): ``h(x) = [p, v]``.

    Linear with a shared ``H`` ``(6, n)``; no batched parameters (``repeat_batch`` is the identity).
    """

    R: np.ndarray  # (6, 6) nominal noise

    def h(self, x: np.ndarray) -> np.ndarray:
        """Predicted fix ``(..., 6)`` of states ``(..., n)``."""
        return x[..., :M_ROWS]

    def H(self, x: np.ndarray) -> np.ndarray:
        """Jacobian ``(6, n)`` (shared by every filter of the batch)."""
        return _H_FIX

    def repeat_batch(self, K: int) -> GnssFixModel:
        """Nothing is batched: the model itself."""
        return self


# ---------------------------------------------------------------------------------------------
# Episodes and platform
# ---------------------------------------------------------------------------------------------
class QuadrotorEpisodes(NamedTuple):
    """Precomputed sensor data and truth of B episodes of T steps (episode axis first).

    Estimator-side (what a real filter has): the prior mean, the home's gravity, gravity gradient
    and Earth rate, the preintegrated IMU of every step and the GNSS fixes. Truth (evaluation
    only, never seen by the filter): ``truth``, ``t_start``, ``origin``.
    """

    m0: np.ndarray  # (B, n) prior mean
    gravity: np.ndarray  # (B, 3)
    gradient: np.ndarray  # (B, 3)
    earth_rate: np.ndarray  # (B, 3)
    dR: np.ndarray  # (B, T, 3, 3) preintegrated IMU of step k (epoch k -> k + 1)
    phi: np.ndarray  # (B, T, 3, 3)
    d6: np.ndarray  # (B, T, 6) [dv^b, dp^b]
    J6: np.ndarray  # (B, T, 6, 6) [[-jva, jvg], [-jpa, jpg]]
    z: np.ndarray  # (B, T + 1, 6) GNSS fixes at the epochs (row 0 unused)
    fix: np.ndarray  # (B, T + 1) a fix was delivered
    truth: np.ndarray  # (B, T + 1, n) true states at the epochs (evaluation only)
    t_start: np.ndarray  # (B,) flight time at the episode start [s] (evaluation only)
    imu_scale: np.ndarray  # (B,) true IMU errors / the filter's model (evaluation only)
    origin: np.ndarray  # (B, 3) home lat [rad], lon [rad], h [m]


@dataclass(frozen=True)
class QuadrotorPlatform:
    """Seed 001's quadrotor INS/GNSS estimation problem (module docstring and the env card)."""

    dt: float = 0.1
    imu_rate_hz: float = 200.0
    sigma_pos: float = SIGMA_POS_M
    sigma_vel: float = SIGMA_VEL_MS
    imu: ImuErrorSpec = CONSUMER_MEMS
    imu_mismatch: tuple[float, float] | None = None
    scenarios: ScenarioDistribution = field(default_factory=ScenarioDistribution)
    flight: QuadrotorParams = field(default_factory=QuadrotorParams)
    error_scale_m: float = 5.0
    divergence_m: float = 500.0
    name: str = "Quadrotor"
    n: int = N_STATE
    m_max: int = M_ROWS

    def __post_init__(self) -> None:
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be > 0; got {self.dt}")
        if not (np.isfinite(self.imu_rate_hz) and self.imu_rate_hz > 0):
            raise ValueError(f"imu_rate_hz must be > 0; got {self.imu_rate_hz}")
        k = self.dt * self.imu_rate_hz
        if abs(k - round(k)) > 1e-9 * max(1.0, k) or round(k) < 1:
            raise ValueError(f"dt * imu_rate_hz must be a positive integer (IMU samples per epoch); got {k}")
        if not self.sigma_pos > 0:
            raise ValueError(f"sigma_pos must be > 0; got {self.sigma_pos}")
        if not self.sigma_vel > 0:
            raise ValueError(f"sigma_vel must be > 0; got {self.sigma_vel}")
        if self.imu_mismatch is not None:
            lo, hi = (float(v) for v in self.imu_mismatch)
            if not (np.isfinite(hi) and 0 < lo <= hi):
                raise ValueError(f"imu_mismatch must be (low, high), 0 < low <= high: {self.imu_mismatch!r}")
            object.__setattr__(self, "imu_mismatch", (lo, hi))
        if not self.error_scale_m > 0:
            raise ValueError(f"error_scale_m must be > 0; got {self.error_scale_m}")
        if not self.divergence_m > 0:
            raise ValueError(f"divergence_m must be > 0; got {self.divergence_m}")

    # --------------------------------------------------------------------------------- setup
    @property
    def n_sub(self) -> int:
        """IMU samples per GNSS epoch."""
        return int(round(self.dt * self.imu_rate_hz))

    @cached_property
    def row_sigma(self) -> np.ndarray:
        """Nominal 1-sigma of the six fix rows (N, E, D position; N, E, D velocity)."""
        p, v = self.sigma_pos, self.sigma_vel
        return np.array([p, p, VERTICAL_FACTOR * p, v, v, VERTICAL_FACTOR * v])

    @cached_property
    def R(self) -> np.ndarray:
        """Nominal measurement noise ``(6, 6)`` assumed by the filter."""
        return np.diag(self.row_sigma**2)

    @cached_property
    def Q(self) -> np.ndarray:
        """Process noise of one step ``(n, n)`` (module docstring)."""
        s, T = self.imu, self.dt
        qa, qg = s.accel_noise**2, s.gyro_noise**2
        Q = np.zeros((N_STATE, N_STATE))
        i = np.arange(3)
        Q[i, i] = qa * T**3 / 3.0
        Q[i, i + 3] = Q[i + 3, i] = qa * T**2 / 2.0
        Q[i + 3, i + 3] = qa * T
        Q[i + 6, i + 6] = qg * T
        Q[i + 9, i + 9] = s.accel_bias_walk**2 * T
        Q[i + 12, i + 12] = s.gyro_bias_walk**2 * T
        return Q

    @cached_property
    def P0_sigma(self) -> np.ndarray:
        """Prior 1-sigma ``(n,)``: a GNSS fix, levelled attitude, coarse heading, turn-on biases."""
        s = self.imu
        ba = max(s.accel_bias, BIAS0_FLOOR[0])
        bg = max(s.gyro_bias, BIAS0_FLOOR[1])
        return np.concatenate(
            [
                self.row_sigma[:3],
                [SIGMA_VEL0] * 3,
                [SIGMA_TILT0, SIGMA_TILT0, SIGMA_YAW0],
                [ba] * 3,
                [bg] * 3,
            ]
        )

    def sample_scenario(self, rng: np.random.Generator) -> Scenario:
        """Draw one scenario from the platform's distribution."""
        return self.scenarios.sample(rng)

    def sample_scenarios(self, rngs: Sequence[np.random.Generator]) -> list[Scenario]:
        return list(self.scenarios.sample_many(list(rngs)))

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> QuadrotorEpisodes:
        """Truth, IMU (preintegrated) and GNSS fixes of ``len(rngs)`` episodes of ``T`` steps.

        Every episode draws from four child generators of its own generator (flight plan and
        start time, IMU errors, GNSS noise, prior), each a fixed amount whatever B, so B
        episodes at once equal B single ones.
        """
        from navgym.quadrotor.imu_kernel import preintegrated_imu  # numba: on first use

        B = len(rngs)
        dt, n_sub = self.dt, self.n_sub
        delta = dt / n_sub
        seeds = np.array([r.integers(0, 2**63 - 1, size=4) for r in rngs])
        g_plan = default_rngs(seeds[:, 0])
        g_imu = default_rngs(seeds[:, 1])
        g_gnss = default_rngs(seeds[:, 2])
        g_init = default_rngs(seeds[:, 3])
        plans = sample_quadrotor_plans(g_plan, self.flight)
        u_start = np.array([g.random() for g in g_plan])
        t_start = u_start * np.maximum(plans.t_landed - T * dt, 0.0)

        # Truth at the GNSS epochs, in the home tangent frame (flat outputs, attitude by flatness).
        epochs = t_start[:, None] + np.arange(T + 1) * dt
        pos_t, vel_t, (roll, pitch, yaw) = quadrotor_home_truth(plans, epochs)
        euler = np.stack([np.unwrap(roll, axis=1), pitch, np.unwrap(yaw, axis=1)], axis=-1)
        lat0, h0 = plans.origin[:, 0], plans.origin[:, 2]

        # Home: gravity, its gradient, Earth rate (estimator-side: the take-off point is known).
        g0 = gravity(lat0, h0)
        dg_dh = (gravity(lat0, h0 + 1.0) - gravity(lat0, h0 - 1.0)) / 2.0
        grav = np.zeros((B, 3))
        grav[:, 2] = g0
        grad = np.stack(
            [-g0 / (meridian_radius(lat0) + h0), -g0 / (normal_radius(lat0) + h0), -dg_dh], axis=-1
        )
        omega = earth_rate_ned(lat0)

        # IMU errors: the true IMU's scale (model mismatch), turn-on biases, walk once per epoch,
        # white noise per sample.
        s = self.imu
        u_scale = np.array([g.random() for g in g_imu])
        if self.imu_mismatch is None:
            scale = np.ones(B)
        else:
            lo, hi = np.log(self.imu_mismatch[0]), np.log(self.imu_mismatch[1])
            scale = np.exp(lo + (hi - lo) * u_scale)
        sig0 = np.repeat([s.accel_bias, s.gyro_bias], 3)
        walk = np.repeat([s.accel_bias_walk, s.gyro_bias_walk], 3) * np.sqrt(dt)
        bias = np.empty((B, T + 1, 6))
        for i, g in enumerate(g_imu):
            bias[i, 0] = scale[i] * sig0 * g.standard_normal(6)
            bias[i, 1:] = bias[i, 0] + np.cumsum(scale[i] * walk * g.standard_normal((T, 6)), axis=0)
        dR, phi = np.empty((B, T, 3, 3)), np.empty((B, T, 3, 3))
        d6, J6 = np.empty((B, T, 6)), np.empty((B, T, 6, 6))
        # normal gravity in the home frame at the epochs and step mid-points (the kernel's nodes)
        mid = quadrotor_positions(plans, t_start[:, None] + (np.arange(T) + 0.5) * dt)
        nodes = []
        for c in range(3):
            node = np.empty((B, 2 * T + 1))
            node[:, 0::2], node[:, 1::2] = pos_t[c], mid[c]
            nodes.append(node)
        gamma_nodes = home_gravity(plans.origin, tuple(nodes))
        na = scale * s.accel_noise / np.sqrt(delta)
        ng = scale * s.gyro_noise / np.sqrt(delta)
        chunk = max(1, _CHUNK_SAMPLES // (B * n_sub))
        noise = np.empty((B, min(chunk, T), n_sub, 6))
        for c0 in range(0, T, chunk):
            nc = min(T, c0 + chunk) - c0
            block = noise[:, :nc]
            for i, g in enumerate(g_imu):  # each episode's block drawn in place (as a (nc n_sub, 6) draw)
                g.standard_normal(out=block[i].reshape(nc * n_sub, 6))
            preintegrated_imu(
                plans, t_start, c0, dt, n_sub, omega, gamma_nodes, bias, block, na, ng, (dR, phi, d6, J6)
            )

        truth = np.concatenate([np.stack(pos_t, axis=-1), np.stack(vel_t, axis=-1), euler, bias], axis=-1)

        # GNSS fixes at the epochs (episode-relative times of the scenario).
        normals = np.stack([g.standard_normal((T + 1, 12)) for g in g_gnss])
        uniforms = np.stack([g.random((T + 1, 3)) for g in g_gnss])
        batch = stack_scenarios(list(scenarios))
        tt = np.broadcast_to(np.arange(T + 1) * dt, (B, T + 1))
        reg = noise_regime(batch, tt)
        fix = gnss_available(batch, tt) & (uniforms[..., 0] >= reg.loss_prob)
        ratio = np.where(uniforms[..., 1] < reg.eps, reg.var_ratio, 1.0)[..., None]
        row_scale = np.array([1.0, 1.0, 1.0] + [self.sigma_vel / self.sigma_pos] * 3)
        var = self.row_sigma**2 * ratio + (reg.jam_sigma[..., None] * row_scale) ** 2
        gross = np.where(uniforms[..., 2] < reg.outlier_prob, reg.outlier_scale, 0.0)[..., None] * row_scale
        z = truth[..., :M_ROWS] + np.sqrt(var) * normals[..., :6] + gross * normals[..., 6:]

        # Prior: truth + N(0, P0) for position, velocity, attitude; zero biases (the turn-on
        # biases above are drawn from the same N(0, sigma_b^2) the prior assumes).
        zi = np.stack([g.standard_normal(9) for g in g_init])
        m0 = np.zeros((B, N_STATE))
        m0[:, :9] = truth[:, 0, :9] + zi * self.P0_sigma[:9]
        return QuadrotorEpisodes(
            m0, grav, grad, omega, dR, phi, d6, J6, z, fix, truth, t_start, scale, plans.origin.copy()
        )

    def initial_belief(self, ep: QuadrotorEpisodes) -> GaussianState:
        """The prior ``N(m0, diag(P0_sigma^2))``."""
        B = ep.m0.shape[0]
        P0 = np.broadcast_to(np.diag(self.P0_sigma**2), (B, N_STATE, N_STATE)).copy()
        return GaussianState(ep.m0.copy(), P0)

    # ---------------------------------------------------------------------------------- step
    def step_models(self, ep: QuadrotorEpisodes, t: np.ndarray) -> StepModels:
        """Strapdown transition of step ``t`` and the fix of epoch ``t + 1``."""
        t = np.asarray(t)
        if t.size and (t == t[0]).all():  # every episode at the same step: views, no gathers
            k = int(t[0])

            def at(a: np.ndarray, i: int) -> np.ndarray:
                return a[:, i]
        else:
            rows = np.arange(t.shape[0])
            k = t

            def at(a: np.ndarray, i: Any) -> np.ndarray:
                return a[rows, i]

        trans = StrapdownTransition(
            at(ep.dR, k), at(ep.phi, k), at(ep.d6, k), at(ep.J6, k),
            ep.gravity, ep.gradient, ep.earth_rate, self.dt, self.Q, [None],
        )  # fmt: skip
        fix = at(ep.fix, k + 1)
        mask = np.repeat(fix[:, None], M_ROWS, axis=1)
        z = np.where(mask, at(ep.z, k + 1), np.nan)
        return StepModels(trans, GnssFixModel(self.R), z, mask, self.dt)

    def position_error(
        self, mean: np.ndarray, ep: QuadrotorEpisodes, t: np.ndarray, P: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Horizontal error, north/east truth and estimate, their covariance, the state error.

        A runaway covariance (any state variance beyond :data:`RUNAWAY_VARIANCE` or non-finite,
        e.g. extreme fading of the yaw and biases, which GNSS fixes observe weakly while the
        position stays pinned) is reported as an infinite ``cov_ne``: the core's covariance bound
        then ends the episode as diverged before the covariance can overflow.
        """
        rows = np.arange(t.shape[0])
        truth = ep.truth[rows, t]
        d = mean - truth
        d[:, 6:9] = _wrap(d[:, 6:9])
        cov_ne = P[:, :2, :2].copy()
        diag = np.diagonal(P, axis1=1, axis2=2)
        runaway = ~(diag <= RUNAWAY_VARIANCE).all(axis=1)
        cov_ne[runaway] = np.inf
        return {
            "pos_err_m": np.hypot(d[:, 0], d[:, 1]),
            "truth_pos": truth[:, :2],
            "est_pos": mean[:, :2].copy(),
            "state_err": d,
            "cov_ne": cov_ne,
        }

    # ------------------------------------------------------------------------------ features
    def features(self) -> list[Feature]:
        """Estimator-side observation features of the platform."""
        return [
            Feature("innovation", -10.0, 10.0, "-", "innovations (p, v NED) / sqrt(S_ii); 0: no fix", M_ROWS),
            Feature("log_nis", 0.0, 10.0, "-", "log(1 + NIS / rows used)"),
            Feature("rows_used", 0.0, 1.0, "-", "fix rows used / 6 (0 or 1: the fix is all or nothing)"),
            Feature("log_sigma_pos", -3.0, 5.0, "log10 m", "log10 sqrt(tr P_pp)"),
            Feature("log_sigma_vel", -4.0, 3.0, "log10 m/s", "log10 sqrt(tr P_vv)"),
            Feature("log_sigma_att", -6.0, 1.0, "log10 rad", "log10 sqrt of the Euler-angle variances"),
            Feature("log_sigma_accel_bias", -6.0, 1.0, "log10 m/s^2", "log10 sqrt(tr P_ba)"),
            Feature("log_sigma_gyro_bias", -8.0, 0.0, "log10 rad/s", "log10 sqrt(tr P_bg)"),
        ]  # fmt: skip

    @staticmethod
    def _cov_features(P: np.ndarray) -> dict[str, np.ndarray]:
        d = np.maximum(np.diagonal(P, axis1=1, axis2=2), 1e-300)
        blocks = d.reshape(d.shape[0], 5, 3).sum(axis=2)
        lg = 0.5 * np.log10(blocks)
        return {
            "log_sigma_pos": lg[:, 0],
            "log_sigma_vel": lg[:, 1],
            "log_sigma_att": lg[:, 2],
            "log_sigma_accel_bias": lg[:, 3],
            "log_sigma_gyro_bias": lg[:, 4],
        }

    def initial_feature_values(self, belief: GaussianState, ep: QuadrotorEpisodes) -> dict[str, np.ndarray]:
        """Features of the prior (no fix processed yet)."""
        B = belief.m.shape[0]
        cols = {"innovation": np.zeros((B, M_ROWS)), "log_nis": np.zeros(B), "rows_used": np.zeros(B)}
        cols.update(self._cov_features(belief.P))
        return cols

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: QuadrotorEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Features from the filter's belief and update diagnostics (no truth)."""
        S_diag = np.maximum(np.diagonal(info.S, axis1=1, axis2=2), 1e-12)
        n_used = np.maximum(info.n_meas, 1)
        cols = {
            "innovation": np.where(models.mask, info.innovation / np.sqrt(S_diag), 0.0),
            "log_nis": np.log1p(np.maximum(info.nis, 0.0) / n_used),
            "rows_used": info.n_meas / M_ROWS,
        }
        cols.update(self._cov_features(belief.P))
        return cols


# ---------------------------------------------------------------------------------------------
# Environments
# ---------------------------------------------------------------------------------------------
from navgym.envs.base import NavEnv, NavVectorEnv  # noqa: E402
from navgym.envs.core import NavCore  # noqa: E402
from navgym.envs.factory import build_core  # noqa: E402
from navgym.envs.registration import fill_card  # noqa: E402

#: Scenario defaults per task (60 s episodes): the degradations that make the task's knob matter.
TASK_SCENARIOS: dict[str, dict[str, Any]] = {
    "fading": {
        "outage_probability": 0.6,
        "outage_duration": (5.0, 30.0),
        "jamming_probability": 0.3,
        "jamming_duration": (5.0, 20.0),
    },
    "mixture": {
        "outage_probability": 0.2,
        "outage_duration": (5.0, 20.0),
        "impulsive_probability": 0.8,
        "impulsive_eps": (0.05, 0.3),
        "impulsive_duration": (10.0, 45.0),
    },
}
#: Largest fading per second (as Robot2d, also 10 Hz): ``lambda_max = LAMBDA_MAX_PER_SECOND ** dt``
#: per step, 1.122 at 10 Hz. Ten per 0.1 s step would inflate the weakly observable yaw and biases
#: by 1e10 per second, a runaway covariance within seconds.
LAMBDA_MAX_PER_SECOND = 10.0**0.5
#: Per-task model mismatch: range of the true IMU's error scale (biases, walks, noise densities),
#: log-uniform per episode, while the filter assumes ``imu_grade`` (fading exists to absorb it).
TASK_MISMATCH: dict[str, tuple[float, float] | None] = {"fading": (0.5, 4.0), "mixture": None}
SCENARIO_KWARGS = (
    "outage_probability",
    "outage_count",
    "outage_duration",
    "outage_duration_choices",
    "impulsive_probability",
    "impulsive_eps",
    "impulsive_var_ratio",
    "impulsive_var_ratio_choices",
    "impulsive_duration",
    "jamming_probability",
    "jamming_sigma",
    "jamming_loss",
    "jamming_duration",
    "outlier_probability",
    "outlier_rate",
    "outlier_scale",
    "outlier_duration",
    "start_margin",
)


def make_platform(task: str, kwargs: dict[str, Any], steps: int) -> QuadrotorPlatform:
    """A :class:`QuadrotorPlatform` from the env keyword arguments it owns (popped from ``kwargs``)."""
    if task not in TASK_SCENARIOS:
        raise ValueError(f"Quadrotor supports the tasks {sorted(TASK_SCENARIOS)}; got {task!r}")
    scen = dict(TASK_SCENARIOS[task])
    scen.update({k: kwargs.pop(k) for k in SCENARIO_KWARGS if k in kwargs})
    dt = float(kwargs.pop("dt", 0.1))
    scen["duration"] = steps * dt
    scen.setdefault("start_margin", min(10.0, 0.1 * steps * dt))
    grade = kwargs.pop("imu_grade", "consumer")
    if grade not in IMU_GRADES:
        raise ValueError(f"imu_grade must be one of {sorted(IMU_GRADES)}; got {grade!r}")
    extra = {"flight": kwargs.pop("flight")} if "flight" in kwargs else {}
    mismatch = kwargs.pop("imu_mismatch", TASK_MISMATCH[task])
    return QuadrotorPlatform(
        dt=dt,
        imu_rate_hz=float(kwargs.pop("imu_rate_hz", 200.0)),
        sigma_pos=float(kwargs.pop("sigma_pos", SIGMA_POS_M)),
        sigma_vel=float(kwargs.pop("sigma_vel", SIGMA_VEL_MS)),
        imu=IMU_GRADES[grade],
        imu_mismatch=None if mismatch is None else tuple(mismatch),
        scenarios=ScenarioDistribution(**scen),
        error_scale_m=float(kwargs.pop("error_scale_m", 5.0)),
        divergence_m=float(kwargs.pop("divergence_m", 500.0)),
        **extra,
    )


def _core(task: str, num_envs: int, kwargs: dict[str, Any]) -> NavCore:
    """The batched core: ``episode_steps`` is the simulated horizon, ``max_episode_steps`` truncates."""
    kwargs = dict(kwargs)
    steps = int(kwargs.pop("episode_steps", 600))
    if steps < 1:
        raise ValueError(f"episode_steps must be >= 1; got {steps}")
    platform = make_platform(task, kwargs, steps)
    if task == "fading":
        kwargs.setdefault("lambda_max", LAMBDA_MAX_PER_SECOND**platform.dt)
    return build_core(platform, task, num_envs, kwargs, steps)


class QuadrotorEnv(NavEnv):
    """Seed 001's quadrotor "return to home" INS/GNSS navigation, with an agent steering the filter.

    ## Description
    A quadrotor flies closed triangles with legs of 100-500 m, climbing, hovering and turning at
    the vertices (Benzerrouk 2014, seed 001 §2.7a, "return to home" of an AR.Drone 2.0), through
    GNSS outages, jamming and impulsive noise. A 15-state *direct* filter (seed 001 eq. 11:
    position, velocity, Euler angles, accelerometer and gyro biases) integrates a consumer-MEMS
    IMU at 200 Hz through the strapdown equations (eq. 3-7; Earth rate and Coriolis kept, in the
    home's Earth-fixed NED frame) and fuses a GNSS position/velocity fix at 10 Hz (eq. 12, 14)
    whenever one is delivered. One step is one GNSS epoch (0.1 s, 20 IMU samples). The agent
    controls the filter, not the vehicle: the fading factor of an EKF (``QuadrotorFading``,
    seed 001 eq. 63-70) or the outlier weight of a Gaussian-sum CKF (``QuadrotorMixture``,
    eq. 71-76). See :mod:`navgym.quadrotor.env` for the models.

    ## Action Space
    ``Box(-1, 1, (1,), float32)``. ``Fading``: ``lambda = lambda_max ** ((a + 1) / 2)`` applied
    as ``P- = lambda F P F^T + Q`` at every 0.1 s step (``a = -1``: the plain filter);
    ``lambda_max`` defaults to ``10 ** 0.05 = 1.122`` per step, i.e. up to 3.16-fold per second
    (``LAMBDA_MAX_PER_SECOND``, as Robot2d): ten per step would inflate the weakly observable yaw
    and biases by 1e10 per second. ``Mixture``: ``eps = eps_max (a + 1) / 2`` (``eps_max = 0.5``),
    measurement noise ``(1 - eps) N(0, R) + eps N(0, variance_ratio R)`` on the whole fix
    (``variance_ratio = 100``). Non-finite
    actions raise ``ValueError``; actions outside [-1, 1] are clipped and counted in
    ``info["action_clipped"]``.

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter (innovations, NIS, covariances, whether a fix arrived, the previous action);
    no truth.

    {observation_table}

    ## Rewards
    ``r = -min(pos_err_m / error_scale_m, reward_clip)`` with the horizontal position error
    ``pos_err_m``, ``error_scale_m = 5`` m (about twice the nominal fix noise: a GNSS-aided
    filter stays well inside it, a 30 s outage on consumer MEMS does not) and
    ``reward_clip = 10``: 0 is perfect, -1 is a 5 m error. The terms are in
    ``info["reward_terms"]``. Divergence (see Episode End) ends the episode with an extra
    ``-divergence_penalty = -100``.

    ## Starting State
    A time drawn uniformly within the flight (take-off to landing minus the episode length);
    the filter starts from ``N(truth, P0)`` for position (fix noise: 2, 2, 3 m), velocity
    (0.2 m/s), roll/pitch (1 deg), yaw (5 deg), and zero biases with the IMU grade's turn-on
    sigmas (the true turn-on biases are drawn from them). ``QuadrotorFading``'s true IMU errors
    are the grade's times a factor drawn log-uniformly in ``imu_mismatch = (0.5, 4)`` per episode
    (the filter keeps the grade's model); ``QuadrotorMixture``'s match it. Home within 43-61 N,
    5 W-40 E.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 600 steps of 0.1 s = 60 s) or at the
    simulated horizon ``episode_steps`` (600). Termination on divergence: the filter's health
    flag is False, the horizontal error exceeds ``divergence_m = 500`` m, the filter's horizontal
    sigma ``sqrt(tr P_ne)`` exceeds ``SIGMA_DIVERGENCE x divergence_m``
    (``navgym.envs.core.SIGMA_DIVERGENCE = {SIGMA_DIVERGENCE}``), or the covariance runs away (any
    state variance beyond ``RUNAWAY_VARIANCE = 1e12`` or non-finite, reported as an infinite
    ``info["cov_ne"]``). ``episode_steps`` sets the simulated episode (flight window,
    IMU, scenario timing); ``max_episode_steps`` only cuts it short, so a single env and a vector
    env built with the same keyword arguments simulate the same episodes.

    ## Arguments
    ``gym.make("navgym/QuadrotorFading-v0", filter="ekf", lambda_max=1.122,
    max_episode_steps=600, episode_steps=600, dt=0.1, imu_rate_hz=200.0,
    imu_grade="consumer"|"tactical", imu_mismatch=(0.5, 4.0) or None, sigma_pos=2.0,
    sigma_vel=0.1, outage_probability=0.6, outage_count=(1, 1),
    outage_duration=(5, 30), jamming_probability=0.3, jamming_sigma=(10, 50),
    jamming_loss=(0, 0.5), jamming_duration=(5, 20), impulsive_probability=0.0,
    impulsive_eps=(lo, hi), impulsive_var_ratio=(50, 2000), impulsive_duration=(lo, hi),
    outlier_probability=0.0, outlier_rate=(lo, hi), outlier_scale=(lo, hi), start_margin=6.0,
    error_scale_m=5.0, divergence_m=500.0, reward_clip=10.0, divergence_penalty=100.0,
    eval_info=True, render_mode=None)``. ``QuadrotorMixture`` takes ``filter="ckf"``,
    ``eps_max=0.5``, ``variance_ratio=100`` and defaults to ``outage_probability=0.2``,
    ``outage_duration=(5, 20)``, ``impulsive_probability=0.8``, ``impulsive_eps=(0.05, 0.3)``,
    ``impulsive_duration=(10, 45)``, ``imu_mismatch=None``. ``filter`` is any Gaussian filter of
    :mod:`filters.registry` (``"ekf"``, ``"ukf"``, ``"ckf"``, ``"ghkf"``, ...).
    Every env takes ``penalize_remaining_steps=False`` (v1: True): the divergence penalty becomes
    ``divergence_penalty + reward_clip x steps not played`` (of the simulated
    ``episode_steps``, also where ``max_episode_steps`` truncates earlier: a single env cannot see
    gym.make's ``TimeLimit``, and single and vector envs give the same reward).
    ``reset(options={"scenario": navgym.scenarios.Scenario(...)})`` pins a scenario.

    ## Version History
    {version_history}
    """

    def __init__(self, task: str = "fading", render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(_core(task, 1, kwargs), render_mode=render_mode)


class QuadrotorVectorEnv(NavVectorEnv):
    """Native batched Quadrotor environment (see :class:`QuadrotorEnv` for the card)."""

    def __init__(self, num_envs: int = 1, task: str = "fading", **kwargs: Any) -> None:
        kwargs.pop("render_mode", None)
        super().__init__(_core(task, num_envs, kwargs))


def _card() -> None:
    """Fill the card's observation tables (every registered id) and its version history."""
    QuadrotorEnv.__doc__ = fill_card(QuadrotorEnv.__doc__, __name__, _core, resample=False)


_card()
