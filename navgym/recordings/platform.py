"""The replay platform: a real IMU + GNSS recording as the Quadrotor's loosely coupled problem.

:class:`ReplayPlatform` is :class:`~navgym.quadrotor.platform.QuadrotorPlatform` with
:meth:`~ReplayPlatform.simulate` replaced: nothing is simulated but the injected degradations.
Everything the filter runs is the Quadrotor's (Benzerrouk 2014, eq. 3-7, 11, 12, 14; see
:mod:`navgym.quadrotor.models`): the 15-state direct filter ``[p, v, (roll, pitch, yaw), b_a,
b_g]`` in an Earth-fixed NED frame at the recording's first fix, the strapdown transition of one
GNSS epoch from the preintegrated IMU (Forster et al. 2017, eq. 33-44), the position/velocity
fix as the measurement, the same features (so the observation has the Quadrotor v2 layout, which
lets a simulation-trained agent run on the recording untouched).

**An episode** is a window of ``T`` epochs of the recording (``T dt`` seconds), its first epoch
drawn uniformly by the episode's generator among the windows that lie inside the truth span
(first to last truth epoch), inside the IMU's time span and that start on a delivered fix.
Per step ``k -> k + 1`` (GNSS epochs ``t_k``, ``t_k + dt``) the recorded body-frame samples are
interpolated linearly to ``n_sub = round(dt / median IMU interval)`` sample mid-points
``t_k + (j + 1/2) dt / n_sub`` and preintegrated by
:func:`navgym.quadrotor.models.preintegrate` (the NumPy reference of the Quadrotor's kernel).

**Measurements** are the recording's fixes (epochs whose Q is in the sidecar's ``fix_q``):
antenna position in the NED frame and velocity (``vn, ve, -vu``), with the v2 degradations of
the episode's scenario injected exactly as the Quadrotor platform injects them into its simulated
fixes (:mod:`navgym.quadrotor.platform`; the scenario processes of :mod:`navgym.scenarios`):
outages withhold fixes (still scored), jamming (with its ramps) adds noise of ``jam_sigma`` per
position row (``jam_sigma sigma_vel / sigma_pos`` per velocity row) and loses fixes, multipath
adds its bias (and noise) to a row, urban canyons lose fixes and multiply the nominal noise,
impulsive noise and gross outliers as there. Where the Quadrotor draws a fix with variance
``v = sigma^2 ratio + jam^2 + ...`` the replay adds ``v - sigma^2`` to the recorded fix (its own
error is the nominal part). Vibration bursts add white noise to the recorded IMU samples
(densities ``velocity_sigma``, ``yaw_rate_sigma``, as the Quadrotor). ``StepModels.truth``
(the clairvoyant's) is the filter's nominal ``Q`` plus the bursts' terms and the nominal ``R``
times the drawn ratios plus the injected variances and biases: the injected part is exact, the
recording's own noise is taken as nominal (unknown).

**Lever arm** (Groves 2013, §14.2, the loosely coupled measurement model with the lever arm):
with the sidecar's ``l^b`` nonzero the filter's measurement model is :class:`LeverArmFixModel`,
``h(x) = [p + C_b^n l^b, v + C_b^n (omega x l^b)]`` with ``omega`` the last gyro sample of the
step (bias not removed).

**Context** (v3, ``context=True``; :mod:`navgym.quadrotor.context`): the IMU statistics come from
the *recorded* samples of the step (after the vibration bursts' noise), summed per step by
:func:`imu_sums` and windowed by :func:`~navgym.quadrotor.context.imu_window` over the last 1 s,
as the Quadrotor's from its simulated samples. The recording has no receiver report of the
satellites (RTKLIB's solution file carries no C/N0), and the injected events are simulated, so the
receiver's report is the Quadrotor's receiver chain (:func:`~navgym.quadrotor.context.receiver_physics`:
satellites, DOP, per-satellite C/N0 under the canyons, multipath and jammers of the episode's
scenario) and, as on the Quadrotor v3, it sets the injected fix noise: the fix variance
``sigma^2 ratio HDOP^2 u`` replaces v2's ``sigma^2 ratio + jam^2`` (canyons and jamming act
through C/N0; the recording's own error stays the nominal part).

**Truth** (evaluation only): the antenna positions of the truth epochs (``truth_q``, RTK fixed),
linearly interpolated in time over the other epochs of the truth span (``ReplayEpisodes.exact``
marks the truth epochs; :mod:`experiments.replay` scores those only). ``info["pos_err_m"]`` is
the horizontal distance of the filter's antenna estimate ``p + C_b^n l^b`` from it. Attitude and
IMU biases have no truth: ``info["nees"]`` is the NEES of position (antenna) and velocity, 6
degrees of freedom (:func:`_marginal_error`).

**Prior** (estimator side): position from the first fix (minus the lever arm), velocity from it,
roll and pitch by levelling the mean specific force of the first step (coarse levelling,
Groves 2013, §5.6.2: ``roll = atan2(-f_y, -f_z)``, ``pitch = atan(f_x / sqrt(f_y^2 + f_z^2))``),
yaw from the fix's velocity heading where the speed exceeds :data:`HEADING_SPEED_MS`, else the
sidecar's ``initial_yaw_deg`` with :data:`SIGMA_YAW_STILL`.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from navgym.envs.protocols import PositionError, StepModels
from navgym.geo import ecef_to_ned, geodetic_to_ecef
from navgym.gnss.receiver_report import fix_variance_factor
from navgym.ins import CONSUMER_MEMS, ImuErrorSpec, home_frame
from navgym.quadrotor.context import QuadrotorContext, context_reports, imu_window, receiver_physics
from navgym.quadrotor.models import M_ROWS, N_STATE, euler_dcm, preintegrate
from navgym.quadrotor.platform import (
    MIN_FIX_SATELLITES,
    RUNAWAY_VARIANCE,
    SIGMA_TILT0,
    QuadrotorPlatform,
    _canyon_satellites,
    sky_satellites,
)
from navgym.recordings.loader import PACKAGED, Recording, load_recording
from navgym.scenarios import (
    Scenario,
    canyon_regime,
    default_rngs,
    gnss_available,
    motion_burst,
    multipath_error,
    noise_regime,
    stack_scenarios,
)

#: Speed [m/s] above which the prior's yaw is the fix's velocity heading.
HEADING_SPEED_MS = 0.5
#: Prior yaw sigma when moving (heading from the velocity; a walker's body may point off it) and
#: when still (``initial_yaw_deg`` is a guess).
SIGMA_YAW_MOVING = np.deg2rad(20.0)
SIGMA_YAW_STILL = np.deg2rad(60.0)
#: Prior tilt sigma: levelling on one step of a walk's accelerations.
SIGMA_TILT_REPLAY = max(SIGMA_TILT0, np.deg2rad(3.0))
#: Nominal fix noise the filter assumes on a recording [m], [m/s] per horizontal axis (vertical 1.5
#: times): RTK float-level, above the fixed solutions' centimetres.
SIGMA_POS_REPLAY_M = 0.1
SIGMA_VEL_REPLAY_MS = 0.05
#: Tolerance [s] when placing GNSS epochs on the regular grid.
EPOCH_TOLERANCE_S = 1e-3


class ReplayData(NamedTuple):
    """A recording on the grid of GNSS epochs (what every episode window is cut from)."""

    t: np.ndarray  #: (K,) GPST of the epochs [s]
    z: np.ndarray  #: (K, 6) fix: antenna position NED [m], velocity NED [m/s] (NaN: none)
    fix: np.ndarray  #: (K,) a fix (Q in fix_q) exists at the epoch
    truth: np.ndarray  #: (K, 6) antenna position and velocity: truth epochs, interpolated between
    exact: np.ndarray  #: (K,) the epoch is a truth epoch
    samples: np.ndarray  #: (K - 1, n_sub, 6) body-frame [gyro, accel] at the step's sample mid-points
    step_ok: np.ndarray  #: (K - 1,) the IMU covers step k
    in_truth: np.ndarray  #: (K,) the epoch lies in the truth span
    origin: np.ndarray  #: (3,) lat [rad], lon [rad], h [m] of the NED frame's origin
    lever: np.ndarray  #: (3,) antenna relative to the IMU, body [m]
    n_sub: int
    dt: float


class ReplayEpisodes(NamedTuple):
    """The Quadrotor's episode fields (same names, same meaning) and the replay's own at the end."""

    m0: np.ndarray
    gravity: np.ndarray
    gradient: np.ndarray
    earth_rate: np.ndarray
    dR: np.ndarray
    phi: np.ndarray
    d6: np.ndarray
    J6: np.ndarray
    z: np.ndarray
    fix: np.ndarray
    truth: np.ndarray  #: (B, T + 1, n): antenna position, velocity; NaN for attitude and biases
    t_start: np.ndarray  #: (B,) the window's start, seconds after the recording's first epoch
    imu_scale: np.ndarray
    origin: np.ndarray
    true_q: np.ndarray | None = None
    true_r: np.ndarray | None = None
    true_bias: np.ndarray | None = None
    bias_prev: np.ndarray | None = None
    omega: np.ndarray | None = None  #: (B, T, 3) last gyro sample of each step (lever-arm velocity)
    exact: np.ndarray | None = None  #: (B, T + 1) the epoch is a truth epoch (evaluation only)
    #: The v3 context (``context=True``: the receiver's report of the injected events, the recorded
    #: IMU's window statistics; sensor-side), or None
    context: QuadrotorContext | None = None


@functools.lru_cache(maxsize=8)
def _load(directory: str, mtimes: tuple[float, ...]) -> Recording:
    return load_recording(directory)


def cached_recording(directory: str | Path | None) -> Recording:
    """:func:`load_recording`, cached per directory (reloaded when a file's mtime changes)."""
    d = Path(PACKAGED if directory is None else directory).resolve()
    mt = tuple(p.stat().st_mtime for p in sorted(d.glob("*")) if p.is_file()) if d.is_dir() else ()
    return _load(str(d), mt)


def replay_data(rec: Recording, dt: float) -> ReplayData:
    """The recording on its epoch grid (module docstring); ``dt`` must be the epoch interval.

    Raises:
        ValueError: ``dt`` is not the recording's GNSS epoch interval, or the epochs are not on a
            regular grid of it.
    """
    g = rec.gnss
    step = float(np.median(np.diff(g.t))) if g.t.size > 1 else dt
    if abs(step - dt) > EPOCH_TOLERANCE_S:
        raise ValueError(
            f"dt must be the recording {rec.name!r}'s GNSS epoch interval, {step:g} s; got dt={dt:g}"
        )
    idx = np.rint((g.t - g.t[0]) / dt).astype(np.int64)
    if np.abs(g.t - g.t[0] - idx * dt).max() > EPOCH_TOLERANCE_S * 10 or np.unique(idx).size != idx.size:
        raise ValueError(f"the GNSS epochs of {rec.name!r} are not on a regular {dt:g} s grid")
    K = int(idx[-1]) + 1
    t = g.t[0] + np.arange(K) * dt
    fix_rows = rec.fix_epochs
    origin = g.lla[np.flatnonzero(fix_rows)[0]]
    ecef = geodetic_to_ecef(g.lla[:, 0], g.lla[:, 1], g.lla[:, 2])
    ned = ecef_to_ned(ecef, origin[0], origin[1], origin[2])
    z = np.full((K, 6), np.nan)
    z[idx, :3], z[idx, 3:] = ned, g.vel_ned
    fix = np.zeros(K, dtype=bool)
    fix[idx] = fix_rows
    z[~fix] = np.nan
    exact = np.zeros(K, dtype=bool)
    exact[idx] = rec.truth_epochs
    te = np.flatnonzero(exact)
    in_truth = np.zeros(K, dtype=bool)
    in_truth[te[0] : te[-1] + 1] = True
    truth = np.full((K, 6), np.nan)
    full = np.full((K, 6), np.nan)
    full[idx, :3], full[idx, 3:] = ned, g.vel_ned
    for c in range(6):
        truth[in_truth, c] = np.interp(t[in_truth], t[te], full[te, c])
    # IMU at the sample mid-points of every step
    imu = rec.imu
    n_sub = max(1, int(round(dt / float(np.median(np.diff(imu.t))))))
    delta = dt / n_sub
    tm = t[:-1, None] + (np.arange(n_sub) + 0.5) * delta
    data = np.concatenate([imu.gyro, imu.accel], axis=1)
    samples = np.stack([np.interp(tm, imu.t, data[:, c]) for c in range(6)], axis=-1)
    step_ok = (t[:-1] >= imu.t[0]) & (t[1:] <= imu.t[-1])
    return ReplayData(t, z, fix, truth, exact, samples, step_ok, in_truth, origin, rec.lever_arm, n_sub, dt)


def rotate(C: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``C a`` for ``C (..., 3, 3)``, ``a (..., 3)`` as three products and two sums.

    Not ``C @ a``: matmul may take BLAS for some batch sizes and not others, which rounds
    differently, and a vector env's rows must equal single envs bit for bit.
    """
    return C[..., 0] * a[..., 0, None] + C[..., 1] * a[..., 1, None] + C[..., 2] * a[..., 2, None]


class LeverArmFixModel(NamedTuple):
    """Fix of an antenna at ``l^b`` from the IMU (Groves 2013, §14.2; module docstring).

    ``h(x) = [p + C l, v + C (omega x l)]`` with ``C = C_b^n(roll, pitch, yaw)``; ``H`` with the
    Euler-angle columns by central differences (step 1e-6 rad), the rest exact.
    """

    R: np.ndarray  #: (6, 6) nominal noise
    lever: np.ndarray  #: (3,) l^b [m]
    omega: np.ndarray  #: (B, 3) body rate [rad/s] of the epoch

    def _offsets(self, e: np.ndarray) -> np.ndarray:
        C = euler_dcm(e)  # (..., 3, 3)
        om = self.omega.reshape(self.omega.shape[:1] + (1,) * (e.ndim - 2) + (3,))
        return np.concatenate([rotate(C, self.lever), rotate(C, np.cross(om, self.lever))], axis=-1)

    def h(self, x: np.ndarray) -> np.ndarray:
        """Predicted fix ``(..., 6)`` of states ``(B, ..., n)``."""
        return x[..., :M_ROWS] + self._offsets(x[..., 6:9])

    def H(self, x: np.ndarray) -> np.ndarray:
        """Jacobian ``(B, 6, n)``.

        The six perturbed attitudes ``e +- eps u_i`` of the central differences are evaluated
        in one call of ``_offsets`` on ``(B, 6, 3)`` (element-wise passes: the numbers of six
        separate calls, in a sixth of the calls).
        """
        B = x.shape[0]
        H = np.zeros((B, M_ROWS, N_STATE))
        H[:, np.arange(6), np.arange(6)] = 1.0
        eps = 1e-6
        d = np.concatenate([np.eye(3) * eps, -np.eye(3) * eps])  # (6, 3): +eps u_i, then -eps u_i
        off = self._offsets(x[:, None, 6:9] + d)  # (B, 6, 6): the offsets of each perturbation
        H[:, :, 6:9] = np.swapaxes((off[:, :3] - off[:, 3:]) / (2 * eps), 1, 2)
        return H

    def repeat_batch(self, K: int) -> LeverArmFixModel:
        """Each episode's rate repeated K times (Gaussian-sum filters stack components)."""
        return LeverArmFixModel(self.R, self.lever, np.repeat(self.omega, K, axis=0))


@dataclass(frozen=True)
class ReplayPlatform(QuadrotorPlatform):
    """A recording replayed as the Quadrotor's estimation problem (module docstring).

    ``recording``: the recording directory (None: the packaged walk_0827). ``imu`` and
    ``imu_rate_hz`` are set from the recording by :func:`replay_platform`.
    """

    recording: str | None = None
    name: str = "Replay"

    @cached_property
    def data(self) -> ReplayData:
        """The recording on its epoch grid (loaded on first use)."""
        return replay_data(cached_recording(self.recording), self.dt)

    @cached_property
    def P0_sigma(self) -> np.ndarray:
        """Prior 1-sigma: the nominal fix, 0.2 m/s, levelled tilt, yaw still (moving: per episode)."""
        s = QuadrotorPlatform.P0_sigma.func(self).copy()
        s[6:8] = SIGMA_TILT_REPLAY
        s[8] = SIGMA_YAW_STILL
        return s

    def window_starts(self, T: int) -> np.ndarray:
        """First epochs of the windows of ``T`` steps an episode may start at (module docstring)."""
        d = self.data
        K = d.t.size
        if T + 1 > K:
            return np.zeros(0, dtype=np.int64)
        ok = d.step_ok.astype(np.int64)
        cs = np.concatenate([[0], np.cumsum(ok)])
        starts = np.arange(K - T)
        steps_ok = cs[starts + T] - cs[starts] == T
        tr = d.in_truth
        return starts[steps_ok & tr[starts] & tr[starts + T] & d.fix[starts]]

    def check_horizon(self, T: int) -> None:
        """Refuse a horizon with no window in the recording (``ValueError``)."""
        if self.window_starts(T).size == 0:
            d = self.data
            span = float(d.in_truth.sum() - 1) * self.dt
            raise ValueError(
                f"episode_steps={T} (x dt {self.dt:g} s = {T * self.dt:g} s) is longer than the "
                f"recording's truth span covered by the IMU (about {span:g} s): lower episode_steps"
            )

    def episode_bytes(self, T: int) -> int:
        """The Quadrotor's estimate plus the replay's own per-step arrays."""
        return super().episode_bytes(T) + (int(T) + 1) * 8 * 4 * (3 + 1)

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> ReplayEpisodes:
        """The windows of ``len(rngs)`` episodes with their injected degradations (module docstring).

        Each episode draws from three child generators of its own (window, IMU noise, GNSS
        noise), a fixed amount whatever B, so B episodes at once equal B single ones.
        """
        d = self.data
        B = len(rngs)
        dt, n_sub = self.dt, d.n_sub
        delta = dt / n_sub
        seeds = np.array([r.integers(0, 2**63 - 1, size=3) for r in rngs])
        g_win, g_imu, g_gnss = (default_rngs(seeds[:, i]) for i in range(3))
        starts_ok = self.window_starts(T)
        if starts_ok.size == 0:
            self.check_horizon(T)
        s0 = np.array([starts_ok[g.integers(starts_ok.size)] for g in g_win])
        steps = s0[:, None] + np.arange(T)
        epochs = s0[:, None] + np.arange(T + 1)
        batch = stack_scenarios(list(scenarios))
        tt = np.broadcast_to(np.arange(T + 1) * dt, (B, T + 1))

        # IMU: the recorded samples, plus the vibration bursts' white noise (densities / sqrt(delta))
        samples = d.samples[steps]  # (B, T, n_sub, 6), a copy
        true_q = np.zeros((B, T, 2))
        if np.isfinite(batch.burst_start).any():
            v_sig, y_sig = motion_burst(batch, tt[:, :T])
            true_q = np.stack([v_sig**2, y_sig**2], axis=-1)
            for i, g in enumerate(g_imu):
                e = g.standard_normal((T, n_sub, 6))
                samples[i, :, :, :3] += e[..., :3] * (y_sig[i] / np.sqrt(delta))[:, None, None]
                samples[i, :, :, 3:] += e[..., 3:] * (v_sig[i] / np.sqrt(delta))[:, None, None]
        pre = preintegrate(samples[..., :3], samples[..., 3:], delta)
        J6 = np.empty((B, T, 6, 6))
        J6[..., :3, :3], J6[..., :3, 3:] = -pre.jva, pre.jvg
        J6[..., 3:, :3], J6[..., 3:, 3:] = -pre.jpa, pre.jpg
        d6 = np.concatenate([pre.dv, pre.dp], axis=-1)
        omega = samples[:, :, -1, :3].copy()

        # The frame: gravity, its gradient and the Earth rate at the origin (as the Quadrotor's home).
        lat0, h0 = d.origin[0], d.origin[2]
        grav, grad, om_e = (np.tile(a, (B, 1)) for a in home_frame(lat0, h0))

        # GNSS: the recorded fixes with the scenario's degradations (as the Quadrotor injects them)
        z0, fix0 = d.z[epochs], d.fix[epochs]
        normals = np.stack([g.standard_normal((T + 1, 12)) for g in g_gnss])
        uniforms = np.stack([g.random((T + 1, 3)) for g in g_gnss])
        reg = noise_regime(batch, tt)
        loss = reg.loss_prob
        canyon = np.isfinite(batch.canyon_start).any()
        multipath = np.isfinite(batch.multipath_start).any()
        if canyon:
            c_scale, c_loss = canyon_regime(batch, tt)
            loss = loss + c_loss - loss * c_loss
        fix = fix0 & gnss_available(batch, tt) & (uniforms[..., 0] >= loss)
        if canyon:
            fix &= _canyon_satellites(batch, tt) >= MIN_FIX_SATELLITES
        ratio = np.where(uniforms[..., 1] < reg.eps, reg.var_ratio, 1.0)[..., None]
        row_scale = np.array([1.0, 1.0, 1.0] + [self.sigma_vel / self.sigma_pos] * 3)
        phys = None
        if self.context:  # v3: the Quadrotor's receiver chain (DOP, C/N0) carries canyon and jamming
            cap = sky_satellites(batch, tt)
            phys = receiver_physics(seeds[:, 2], batch, tt, cap, self.sigma_pos, self.cn0_offset_db)
            fix &= phys.n_sv >= MIN_FIX_SATELLITES
            var = self.row_sigma**2 * ratio * fix_variance_factor(phys)[..., None]
        else:
            if canyon:
                ratio = ratio * c_scale[..., None] ** 2
            var = self.row_sigma**2 * ratio + (reg.jam_sigma[..., None] * row_scale) ** 2
        bias_r = np.zeros((B, T + 1, M_ROWS))
        if multipath:
            bias_r, mp_var = multipath_error(batch, tt, M_ROWS)
            var = var + mp_var
        gross = np.where(uniforms[..., 2] < reg.outlier_prob, reg.outlier_scale, 0.0)[..., None] * row_scale
        added = np.sqrt(np.maximum(var - self.row_sigma**2, 0.0))
        z = z0 + added * normals[..., :6] + gross * normals[..., 6:] + bias_r

        truth = np.full((B, T + 1, N_STATE), np.nan)
        truth[..., :6] = d.truth[epochs]

        # Prior (estimator side): first fix, levelled tilt, heading from the fix's velocity.
        f = samples[:, 0, :, 3:].mean(axis=1)
        roll = np.arctan2(-f[:, 1], -f[:, 2])
        pitch = np.arctan(f[:, 0] / np.hypot(f[:, 1], f[:, 2]))
        v0 = z[:, 0, 3:6]
        moving = np.hypot(v0[:, 0], v0[:, 1]) > HEADING_SPEED_MS
        yaw = np.where(
            moving,
            np.arctan2(v0[:, 1], v0[:, 0]),
            np.deg2rad(cached_recording(self.recording).initial_yaw_deg),
        )
        m0 = np.zeros((B, N_STATE))
        m0[:, 6:9] = np.stack([roll, pitch, yaw], axis=-1)
        arm = rotate(euler_dcm(m0[:, 6:9]), d.lever)
        m0[:, :3] = z[:, 0, :3] - arm
        m0[:, 3:6] = v0
        extra: dict[str, Any] = {}
        if self.true_noise:
            extra["true_q"] = true_q
            extra["true_r"] = var + gross**2
            extra["true_bias"] = bias_r
        if self.bias_features:
            extra["bias_prev"] = m0[:, 9:15].copy()
        if phys is not None:
            imu = imu_window(imu_sums(samples), n_sub, dt)
            extra["context"] = context_reports(phys, fix, self.row_sigma, imu, dt)
        t_start = d.t[s0] - d.t[0]
        return ReplayEpisodes(
            m0, grav, grad, om_e, pre.dR, pre.phi, d6, J6, z, fix, truth, t_start, np.ones(B),
            np.tile(d.origin, (B, 1)), omega=omega, exact=d.exact[epochs], **extra,
        )  # fmt: skip

    def initial_belief(self, ep: ReplayEpisodes) -> GaussianState:
        """``N(m0, diag(P0_sigma^2))``, the yaw sigma :data:`SIGMA_YAW_MOVING` where moving at the start."""
        belief = super().initial_belief(ep)
        moving = np.hypot(ep.m0[:, 3], ep.m0[:, 4]) > HEADING_SPEED_MS
        belief.P[moving, 8, 8] = SIGMA_YAW_MOVING**2
        return belief

    def step_models(self, ep: ReplayEpisodes, t: np.ndarray) -> StepModels:
        """The Quadrotor's models, the fix model with the lever arm where the sidecar gives one."""
        models = super().step_models(ep, t)
        lever = self.data.lever
        if not np.any(lever):
            return models
        t = np.asarray(t)
        omega = ep.omega[np.arange(t.shape[0]), t]
        return models._replace(observation=LeverArmFixModel(self.R, lever, omega))

    def position_error(
        self, mean: np.ndarray, ep: ReplayEpisodes, t: np.ndarray, P: np.ndarray
    ) -> PositionError:
        """Horizontal error of the antenna estimate ``p + C_b^n l^b`` against the truth (module docstring).

        A runaway covariance is reported as an infinite ``cov_ne`` (as the Quadrotor's).
        """
        rows = np.arange(t.shape[0])
        truth = ep.truth[rows, t]
        est = mean[:, :3] + rotate(euler_dcm(mean[:, 6:9]), self.data.lever)
        d = est - truth[:, :3]
        cov_ne = P[:, :2, :2].copy()
        diag = np.diagonal(P, axis1=1, axis2=2)
        cov_ne[~(diag <= RUNAWAY_VARIANCE).all(axis=1)] = np.inf
        e = np.zeros_like(mean)
        e[:, :3], e[:, 3:6] = d, mean[:, 3:6] - truth[:, 3:6]
        return PositionError(
            np.hypot(d[:, 0], d[:, 1]), truth[:, :2], est[:, :2].copy(), cov_ne, _marginal_error(e, P)
        )


def imu_sums(samples: np.ndarray) -> np.ndarray:
    """Per-step sums of the IMU samples, the layout of the Quadrotor kernel's ``stats``.

    ``samples (B, T, n_sub, 6)`` body-frame ``[gyro, accel]``; returns ``(B, T, 8)``: the sums over
    the step's samples of ``f`` (3), ``|f|^2``, ``omega`` (3), ``|omega|^2``
    (:data:`navgym.quadrotor.imu_kernel.N_STATS`), for :func:`navgym.quadrotor.context.imu_window`.
    """
    w, f = samples[..., :3], samples[..., 3:]
    out = np.empty((*samples.shape[:2], 8))
    out[..., 0:3] = f.sum(axis=2)
    out[..., 3] = (f**2).sum(axis=(2, 3))
    out[..., 4:7] = w.sum(axis=2)
    out[..., 7] = (w**2).sum(axis=(2, 3))
    return out


def _marginal_error(e: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``e`` with its rows 6: (no truth) set to ``P_rk P_kk^-1 e_k`` over the known rows ``k = :6``.

    Then ``e^T P^-1 e = e_k^T P_kk^-1 e_k`` (Schur complement: ``P [P_kk^-1 e_k; 0] = e``), so the
    core's NEES is the marginal NEES of position and velocity. Rows whose ``P_kk`` is singular or
    not finite keep zeros there (their NEES is then what the core makes of it).
    """
    out = e.copy()
    Pkk, Prk = P[:, :6, :6], P[:, 6:, :6]
    ok = np.isfinite(P).all(axis=(1, 2)) & np.isfinite(e).all(axis=1)
    if ok.any():
        try:
            y = np.linalg.solve(Pkk[ok], e[ok, :6, None])
            out[ok, 6:] = (Prk[ok] @ y)[..., 0]
        except np.linalg.LinAlgError:
            pass
    return out


def replay_platform(recording: str | Path | None = None, **kwargs: Any) -> ReplayPlatform:
    """A :class:`ReplayPlatform` of ``recording`` with its IMU's noise figures and rate.

    The sidecar gives the noise densities and turn-on bias sigmas; the bias random walks are
    consumer MEMS' (:data:`navgym.ins.CONSUMER_MEMS`). ``imu_rate_hz`` is ``n_sub / dt``.

    ``kwargs`` go to :class:`ReplayPlatform` (``dt``, ``sigma_pos``, ``scenarios``, ...).
    """
    rec = cached_recording(recording)
    dt = float(kwargs.pop("dt", 0.25))
    data = replay_data(rec, dt)
    imu = ImuErrorSpec(
        name=f"{rec.name} sidecar",
        accel_bias=rec.accel_bias,
        accel_noise=rec.accel_noise,
        accel_bias_walk=CONSUMER_MEMS.accel_bias_walk,
        gyro_bias=rec.gyro_bias,
        gyro_noise=rec.gyro_noise,
        gyro_bias_walk=CONSUMER_MEMS.gyro_bias_walk,
    )
    path = None if recording is None else str(Path(recording).resolve())
    kwargs.setdefault("sigma_pos", SIGMA_POS_REPLAY_M)
    kwargs.setdefault("sigma_vel", SIGMA_VEL_REPLAY_MS)
    return ReplayPlatform(dt=dt, imu_rate_hz=data.n_sub / dt, imu=imu, recording=path, **kwargs)
