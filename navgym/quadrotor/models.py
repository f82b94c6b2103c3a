"""Quadrotor filter models: Benzerrouk 2014's direct INS/GNSS filter on "return to home" triangle flights.

**Truth** (Benzerrouk 2014, §2.7a): an AR.Drone-class quadrotor flies a closed triangle with legs of
100-500 m, climbs, hovers and turns at the vertices (:mod:`navgym.quadrotor.flight`). An
episode covers ``T dt`` seconds of the flight starting at a time drawn uniformly in
``[0, t_landed - T dt]`` (clipped at 0), so episodes see take-off, legs, turns, hovers and the
landing. The IMU samples the exact kinematics (``f_ib^b``, ``omega_ib^b`` on the rotating
ellipsoid) at ``imu_rate_hz = 200`` Hz (Benzerrouk 2014: dt = 0.005 s) at the sample midpoints, with the
errors of :class:`navgym.ins.ImuErrorSpec` (Benzerrouk 2014, eq. 2 and 5: measured = true + bias + white
noise; consumer MEMS by default): turn-on biases, white noise per sample, and a bias random walk
advanced once per GNSS epoch (so the bias is constant over a filter step, as the filter assumes).
With ``imu_mismatch = (lo, hi)`` (Fading's default ``(0.5, 4)``) the true IMU's error parameters
are those of the grade times a factor drawn log-uniformly per episode, while the filter keeps
the grade's model: the model mismatch a fading factor exists to absorb.

**Filter state** (Benzerrouk 2014, eq. 11, *direct* filtering: the filter estimates the navigation
states themselves, not INS errors)::

    x = [p (3), v (3), (roll, pitch, yaw) (3), b_a (3), b_g (3)]        n = 15

position and velocity in the home's NED tangent frame [m, m/s], 3-2-1 Euler angles of
``C_b^t = R_z(yaw) R_y(pitch) R_x(roll)`` [rad] (yaw is not wrapped, so sigma points never
straddle +-pi), accelerometer [m/s^2] and gyro [rad/s] biases (measured = true + bias).

**Mechanization** (Benzerrouk 2014, eq. 3-7). The tangent frame is Earth-fixed, so the transport rate
of eq. 3-7's local-level frame vanishes; Benzerrouk 2014 further neglects the Earth rate. Here it is
kept because it is cheap and makes the model exact at these distances (15 deg/h is below the
consumer gyro bias but not below a tactical one)::

    dC/dt = C [omega x] - [Omega x] C,   dv/dt = C f + g(p) - 2 Omega x v,   dp/dt = v

with ``Omega`` the Earth rate in the home frame and ``g(p) = g0 + diag(Gamma) p`` normal gravity
at home plus its linear variation (the ellipsoid normal tilts by ``p_n / (R_M + h)`` and
``p_e / (R_N + h)``; free-air gradient ``dgamma/dh``); neglected terms are below 1e-5 m/s^2
within 1 km of home.

**Transition** (one GNSS epoch ``T = dt = 0.1`` s, ``n_sub = 20`` IMU samples). The 20 samples are
integrated with Benzerrouk 2014, eq. 4 (Rodrigues, per sample), eq. 6 (velocity, at the mid-sample
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

**Measurements** (Benzerrouk 2014, eq. 12 and 14, loosely coupled): a GNSS receiver's position and
velocity fix at 10 Hz in the home NED frame, ``z = [p, v] + noise``, ``m_max = 6`` rows, all six
present or absent together (the mask). Nominal noise (u-blox M8-class receiver, datasheet
2.5 m CEP and 0.05 m/s): ``sigma_pos = 2`` m and ``sigma_vel = 0.1`` m/s per horizontal axis,
1.5 times that vertically; white, which is the assumption of Benzerrouk 2014, eq. 16. Degradations come from
the scenario (:mod:`navgym.scenarios`): outages (no fix); jamming (extra noise ``jam_sigma`` on
each position row and ``jam_sigma sigma_vel / sigma_pos`` on each velocity row, and the fix lost
with probability ``loss_prob`` per epoch); impulsive noise (Benzerrouk 2014, eq. 71), one mixture draw
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

from typing import NamedTuple

import numpy as np

from filters.core.compiled import compiled_enabled
from filters.core.models import ElementwiseModel
from navgym.ins.attitude import cross_components, rotation_matrix_components, wrap_angle
from navgym.quadrotor.preintegration_kernel import preintegrate_rows
from navgym.quadrotor.strapdown_kernel import strapdown_pass

#: State dimension: position, velocity, Euler angles, accelerometer and gyro biases.
N_STATE = 15
#: Measurement rows: GNSS position (3) and velocity (3), NED.
M_ROWS = 6
_I3 = np.eye(3)
_H_FIX = np.eye(M_ROWS, N_STATE)


# ---------------------------------------------------------------------------------------------
# Rotation algebra, component-first ("SoA"): vectors (3, ...), matrices (3, 3, ...) with M[i, j]
# the row-i, column-j entry over any trailing axes. NumPy's stacked 3x3 matmul costs one BLAS call
# per matrix; five ufunc calls over the trailing axes are 5-10x faster here. Rodrigues' formula and
# the cross product in this layout live in navgym.ins.attitude (rotation_matrix_components,
# cross_components); the products below are the quadrotor model's own.
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


def _cross_rows(M: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``M [u x]`` for ``M (3, 3, ...)`` and ``u (3, ...)``: each row ``r_i`` becomes ``r_i x u``."""
    out = np.empty(np.broadcast_shapes(M.shape, (3,) + u.shape))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(M[:, j], u[k], out=out[:, i, ...])
        out[:, i] -= M[:, k] * u[j]
    return out


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
    return np.stack([ref[0] + wrap_angle(roll - ref[0]), pitch, ref[2] + wrap_angle(yaw - ref[2])])


def _euler_rate_soa(e: np.ndarray, inverse: bool = False) -> np.ndarray:
    """``N(e)`` (or ``N^-1``), ``(3, 3, ...)``: tangent-frame rotation of an Euler increment.

    ``C(e + de) = Exp(N de) C(e)`` with ``N = [R_z R_y e_x, R_z e_y, e_z]``; its inverse is the
    ``E_b^n`` of Benzerrouk 2014, eq. 11, in tangent-frame form. ``cos(pitch)`` is kept above 1e-6 (the Euler
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
    """Integrate ``n_sub`` IMU samples per step (Benzerrouk 2014, eq. 4, 6, 7; Forster et al. 2017).

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
    if compiled_enabled():  # the compiled twin on the rows as they are (its module docstring)
        rows = preintegrate_rows(gyro.reshape(N, n_sub, 3), accel.reshape(N, n_sub, 3), delta)
        return Preintegrated(*(a.reshape(lead + a.shape[1:]) for a in rows))
    w = np.ascontiguousarray(gyro.reshape(N, n_sub, 3).transpose(1, 2, 0))  # (n_sub, 3, N)
    f = np.ascontiguousarray(accel.reshape(N, n_sub, 3).transpose(1, 2, 0))

    def out(a: np.ndarray) -> np.ndarray:
        return np.moveaxis(a, -1, 0).reshape(lead + a.shape[:-1])

    return Preintegrated(*(out(a) for a in preintegrate_components(w, f, delta)))


def preintegrate_components(w: np.ndarray, f: np.ndarray, delta: float) -> Preintegrated:
    """:func:`preintegrate` on component slabs, in NumPy passes: samples ``w, f (n_sub, 3, N)``.

    The reference of the compiled twin (:mod:`navgym.quadrotor.preintegration_kernel`), which
    :func:`preintegrate` runs on the samples' rows unless :func:`filters.core.compiled.numpy_only`
    forces these passes.

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
        H = rotation_matrix_components(w[j] * h)
        R_mid = _mm(R, H)
        a = _mv(R_mid, f[j])
        psi_mid = psi + (R + R_mid) * q
        G = cross_components(a[:, None], psi_mid)
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
    with the same array ``m``, which is then propagated once. For one state per episode ``(B, 15)``
    both come from the compiled twin (:mod:`navgym.quadrotor.strapdown_kernel`) unless
    :func:`filters.core.compiled.numpy_only` forces these NumPy passes.
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
        y -= cross_components(wh[:, None], y)  # E_h C0 [dv^b, dp^b]
        dv_t, dp_t = y[:, 0], y[:, 1]
        acc = p0 + (0.5 * T) * v0
        acc *= gr
        acc += g
        acc -= 2.0 * cross_components(om, v0)
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

    def _compiled(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(f(x), F(x))`` of ``x (B, 15)`` by the compiled twin (``strapdown_kernel``)."""
        memo = self.memo
        if memo is not None and memo[0] is not None and memo[0][0] is _COMPILED and memo[0][1] is x:
            return memo[0][2], memo[0][3]
        B, T = x.shape[0], self.T
        c, G, W = _PV_BASIS.get(T) or _PV_BASIS.setdefault(T, _pv_basis(T))
        out, F = np.empty((B, 15)), np.empty((B, 15, 15))
        f64 = np.float64
        strapdown_pass(*(np.ascontiguousarray(a, f64) for a in (x, *self[:7])), c, G, W, float(T), out, F)
        if memo is not None:
            memo[0] = (_COMPILED, x, out, F)
        return out, F

    def _takes_kernel(self, x: np.ndarray) -> bool:
        """One 15-state per episode (the EKF's mean) and the compiled path on."""
        return x.ndim == 2 and x.shape[1] == 15 and compiled_enabled()

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        """Propagate states ``(B, n)`` or ``(B, S, n)`` over one step (module docstring)."""
        if self._takes_kernel(x):
            return self._compiled(x)[0]
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
        if self._takes_kernel(x):
            return self._compiled(x)[1]
        B, n = x.shape
        T = self.T
        _, (e0, e1, C0, A, wh, dv_t, dp_t, u) = self._propagate(x)
        e0, e1, C0, A, wh, dv_t, dp_t, u = (a[..., 0] for a in (e0, e1, C0, A, wh, dv_t, dp_t, u))
        wcol = wh[:, None]  # (3, 1, B)
        N0 = _euler_rate_soa(e0)
        wN0 = cross_components(wcol, N0)
        C1 = A - cross_components(2.0 * wcol, A)
        C0h = C0 - cross_components(wcol, C0)
        N1i = _euler_rate_soa(e1, inverse=True)
        phi = np.ascontiguousarray(self.phi.transpose(1, 2, 0))
        C1Jphi = _mm(C1, phi - 0.5 * cross_components(u[:, None], phi))
        Fm = np.zeros((B, n, n))
        # Position/velocity blocks: constant per episode (gravity gradient, Earth rate).
        Fm[:, 0:6, 0:6] = _pv_block(self.gradient, self.earth_rate, T)
        Fm[:, _BIAS, _BIAS] = 1.0
        # d(p, v)/de = -[(dp_t, dv_t) x] E_h N0
        y = np.stack([dp_t, dv_t], axis=1)[:, :, None]  # (3, 2, 1, B)
        Fm[:, 0:6, 6:9] = (-cross_components(y, (N0 - wN0)[:, None])).transpose(3, 1, 0, 2).reshape(B, 6, 3)
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
#: Marks a memo entry of the compiled twin (``(_COMPILED, x, f(x), F(x))``).
_COMPILED = object()
_BIAS = np.arange(9, 15)


class GnssFixModel(NamedTuple):
    """GNSS position and velocity fix in the home NED frame (Benzerrouk 2014, eq. 12, 14): ``h(x) = [p, v]``.

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


# h selects state components: the sigma-point kernels may hand it their points without a copy
ElementwiseModel.register(GnssFixModel)


# ---------------------------------------------------------------------------------------------
# Episodes and platform
# ---------------------------------------------------------------------------------------------
