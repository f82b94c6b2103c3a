"""The Pedestrian estimation problem: walks, foot IMU, ZUPTs and GPS/GLONASS fixes of B episodes.

Benzerrouk 2014, §2.7c (the blind pedestrian's navigation system, patent 89221): a walker in a
city carries a foot-mounted MEMS IMU (the source's shoe-mounted OpenShoe test: a stance
detector and zero-velocity updates) and a GPS/GLONASS receiver. The walk is
:mod:`navgym.pedestrian.gait` (piecewise constant heading and ~1.4 m/s, one stride per
``dt = 1`` s step, the epochs at mid-stance); the IMU samples its exact kinematics at
``imu_rate_hz = 100`` Hz with the errors of :class:`navgym.ins.ImuErrorSpec` (consumer MEMS:
turn-on biases, white noise per sample, bias random walk advanced once per step).

**The filter is the Quadrotor's** (:mod:`navgym.quadrotor.models`; Benzerrouk 2014, eq. 3-7, 11,
12, 14): the 15-state direct filter ``[p, v, (roll, pitch, yaw), b_a, b_g]`` in the home's
NED tangent frame, the strapdown transition of one step from the preintegrated IMU (Forster et
al. 2017, eq. 33-44; :func:`navgym.quadrotor.models.preintegrate`) and the linear
measurement ``h(x) = [p, v]`` (:class:`~navgym.quadrotor.models.GnssFixModel`), whose six rows
here are:

* rows 0-2, the **GPS/GLONASS fix** ``z = p + e`` at the epoch, ``sigma_pos = 5`` m per
  horizontal axis, 1.5 times that vertically (a receiver in a city street; the source's
  smartphone-class GPS/GLONASS receiver);
* rows 3-5, the **zero-velocity update** (Foxlin 2005; Skog et al. 2010) ``z = 0 = v + e`` at
  mid-stance, ``sigma_zupt = 0.02`` m/s per axis: the foot rests at every epoch (stance
  detection is taken as perfect), so these rows are present at every step and never degraded.

**The v2 events** of the scenario (:mod:`navgym.scenarios`) act on the fix rows and the IMU while
the filter's ``Q`` and ``R`` stay nominal, as on the Quadrotor (:mod:`navgym.quadrotor.platform`):
outages (no fix: an underpass, a building), impulsive noise (Benzerrouk 2014, eq. 71: one mixture
draw per fix), jamming ramps (extra fix noise ``jam_sigma`` per position row and lost fixes),
multipath (a bias and noise on one fix row: a reflected signal in a street), urban canyons (at
most a few satellites, below :data:`~navgym.quadrotor.platform.MIN_FIX_SATELLITES` no fix, noise
times ``noise_scale``, lost fixes) and process-noise bursts: **shocks** of the foot (running,
stairs, rough pavement), extra white accelerometer and gyro noise on every IMU sample of the
burst's steps, the Quadrotor's vibration model (densities ``velocity_sigma`` [m/s/sqrt(s)] and
``yaw_rate_sigma`` [rad/sqrt(s)]; :func:`navgym.quadrotor.platform.vibration_q`).

With ``true_noise=True`` (the v2 ids) :meth:`PedestrianPlatform.step_models` hands the evaluation
the noise the simulator used (``StepModels.truth``): the nominal ``Q`` plus the bursts' terms,
``R`` with each row's variance as drawn and each row's bias.

With ``context=True`` (v3, :mod:`navgym.pedestrian.context`) the fix's noise per row is
``HDOP sigma_nom sqrt(u)`` from the receiver's satellites and C/N0 instead: the canyon acts
through fewer satellites and a diffraction loss, the jamming through its J/S, multipath segments
through an NLOS loss (v2's canyon factor and jamming variance are then not added; the impulsive
ratio, multipath bias and noise and outliers are), and the observation gains the receiver's
report and the stance detector's statistics of the foot IMU's samples (a shock shows there).
The walk, the IMU, the fix delivery and the ZUPTs stay as they are; the receiver draws from its
own generator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from filters.core.compiled import compiled_enabled
from navgym.envs.features import (
    Feature,
    covariance_values,
    innovation_features,
    innovation_initial_values,
    innovation_values,
)
from navgym.envs.platform import PlatformBase
from navgym.envs.protocols import PositionError, StepModels, TrueNoise
from navgym.gnss.receiver_report import check_cn0_offset, fix_variance_factor
from navgym.ins import CONSUMER_MEMS, ImuErrorSpec, home_frame, imu_bias_walks
from navgym.ins.attitude import wrap_angle
from navgym.pedestrian.context import (
    PedestrianContext,
    context_feature_values,
    context_features,
    context_reports,
    receiver_physics,
    stance_stats,
    stance_window,
)
from navgym.pedestrian.gait import PLAN_WIDTH, foot_imu, foot_state, phase_tables, stride_plan
from navgym.pedestrian.imu_kernel import sampled_imu
from navgym.quadrotor.models import (
    M_ROWS,
    N_STATE,
    GnssFixModel,
    StrapdownTransition,
    preintegrate,
)
from navgym.quadrotor.platform import (
    BIAS0_FLOOR,
    COVARIANCE_BLOCKS,
    MIN_FIX_SATELLITES,
    RUNAWAY_VARIANCE,
    VERTICAL_FACTOR,
    _canyon_satellites,
    _vibration,
    sky_satellites,
    vibration_q,
)
from navgym.scenarios import (
    Scenario,
    ScenarioDistribution,
    canyon_regime,
    default_rngs,
    gnss_available,
    multipath_error,
    noise_regime,
    stack_scenarios,
)

#: Measurement rows: GPS/GLONASS fix N, E, D [m], then the zero-velocity update N, E, D [m/s].
ROWS = ("fix_N", "fix_E", "fix_D", "zupt_N", "zupt_E", "zupt_D")
#: The fix's rows (the GNSS rows; the Mixture's outlier rows; multipath acts on these).
FIX_ROWS = (0, 1, 2)
#: GPS/GLONASS fix noise per horizontal axis in a city street [m].
SIGMA_POS_M = 5.0
#: Zero-velocity update noise per axis [m/s] (the foot's residual motion at mid-stance).
SIGMA_ZUPT_MS = 0.02
#: Prior 1-sigma: velocity (at rest) [m/s], roll/pitch (levelled at rest) and yaw (an electronic
#: compass in a city, Benzerrouk 2014 §2.7c) [rad].
SIGMA_VEL0 = 0.05
SIGMA_TILT0 = np.deg2rad(1.0)
SIGMA_YAW0 = np.deg2rad(10.0)
#: Home latitude [deg] and height [m] ranges (uniform).
HOME_LAT_DEG = (35.0, 60.0)
HOME_H_M = (0.0, 500.0)
#: IMU samples (over all episodes) per chunk when simulating at reset, and steps of one episode
#: at most per chunk (bounds the temporaries per episode too).
_CHUNK_SAMPLES = 1 << 18
_CHUNK_STEPS = 16


class PedestrianEpisodes(NamedTuple):
    """Precomputed IMU, fixes and truth of B episodes of T strides (episode axis first).

    Estimator-side: the prior mean, the home's gravity, gradient and Earth rate, the preintegrated
    IMU of every step, the fixes and ZUPTs (``z``, ``mask``). Truth (evaluation only): ``truth``
    and, with ``true_noise``, ``true_q``, ``true_r``, ``true_bias``.
    """

    m0: np.ndarray  # (B, n) prior mean
    gravity: np.ndarray  # (B, 3)
    gradient: np.ndarray  # (B, 3)
    earth_rate: np.ndarray  # (B, 3)
    dR: np.ndarray  # (B, T, 3, 3) preintegrated IMU of step k
    phi: np.ndarray  # (B, T, 3, 3)
    d6: np.ndarray  # (B, T, 6) [dv^b, dp^b]
    J6: np.ndarray  # (B, T, 6, 6)
    z: np.ndarray  # (B, T + 1, 6) fix and ZUPT at the epochs (NaN where none; row 0 unused)
    mask: np.ndarray  # (B, T + 1, 6) rows delivered
    truth: np.ndarray  # (B, T + 1, n) true states at the epochs (truth only)
    #: (B, T, 2) the shocks' accelerometer and gyro densities squared of step k (truth only, or None)
    true_q: np.ndarray | None = None
    #: (B, T + 1, 6) variance of each row as drawn (truth only, or None)
    true_r: np.ndarray | None = None
    #: (B, T + 1, 6) mean error of each row (multipath) (truth only, or None)
    true_bias: np.ndarray | None = None
    #: The v3 context (receiver reports, stance detector statistics; sensor-side), or None
    context: PedestrianContext | None = None


@dataclass(frozen=True)
class PedestrianPlatform(PlatformBase):
    """Benzerrouk 2014's pedestrian navigation (§2.7c; module docstring and the env card).

    Attributes:
        dt: Filter step [s], one stride and one GPS/GLONASS epoch.
        imu_rate_hz: IMU sample rate [Hz] (``dt * imu_rate_hz`` samples a step).
        sigma_pos: Fix noise per horizontal axis [m] (1.5 times vertically).
        sigma_zupt: Zero-velocity update noise per axis [m/s].
        imu: IMU error model (truth and the filter's ``Q``).
        true_noise: Keep the noise the simulator used for ``StepModels.truth`` (the v2 ids).
        context: Simulate the v3 context (:mod:`navgym.pedestrian.context`): the fix noise follows
            the receiver's HDOP and C/N0 (jamming as J/S, canyons as fewer satellites and a
            diffraction loss, multipath segments as an NLOS loss; v2's canyon factor and jamming
            variance are then not added, its impulsive ratio, multipath bias and noise and
            outliers are), and the observation gains the receiver's report and the stance
            detector's statistics of the foot IMU's samples. False (v0-v2): nothing of it is
            drawn or stored; the receiver draws from its own generator, so the walk, the IMU,
            the fix delivery and the ZUPTs are the same either way.
        cn0_offset_db: Calibration offset [dB] of the receiver's C/N0 report (another receiver
            model; :func:`navgym.gnss.receiver_report.check_cn0_offset`): the reported C/N0 and
            accuracy figure follow it, the true C/N0 and the fix noise do not. Needs ``context``.
    """

    dt: float = 1.0
    imu_rate_hz: float = 100.0
    sigma_pos: float = SIGMA_POS_M
    sigma_zupt: float = SIGMA_ZUPT_MS
    imu: ImuErrorSpec = CONSUMER_MEMS
    scenarios: ScenarioDistribution = field(default_factory=ScenarioDistribution)
    error_scale_m: float = 5.0
    divergence_m: float = 200.0
    true_noise: bool = False
    context: bool = False
    cn0_offset_db: float = 0.0
    name: str = "Pedestrian"
    n: int = N_STATE
    m_max: int = M_ROWS

    def __post_init__(self) -> None:
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be finite and > 0; got {self.dt!r}")
        k = self.dt * self.imu_rate_hz
        if not np.isfinite(k) or abs(k - round(k)) > 1e-9 * max(1.0, k) or round(k) < 2:
            raise ValueError(f"dt * imu_rate_hz must be an integer >= 2 (IMU samples per stride); got {k!r}")
        for name in ("sigma_pos", "sigma_zupt"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0; got {v!r}")
        check_cn0_offset(self.cn0_offset_db, self.context)
        self.check_reward_scales()

    @property
    def gnss_rows(self) -> tuple[int, ...]:
        """The fix's rows (the ZUPT rows are no GNSS)."""
        return FIX_ROWS

    @property
    def process_noise_states(self) -> tuple[int, ...]:
        """Position, velocity and attitude (states 0-8): where the IMU's white noise enters ``Q``.

        The accelerometer's noise (and a v2 shock's) is preintegrated into the position/velocity
        block, the gyro's (and a shock's) into the Euler angles; a shock raises both together,
        by similar factors (its densities are 30-150 and 15-75 times the consumer grade's), so
        one scale ``s_q`` on these nine states (RowScale's ``Q' = D Q D``) covers it. The bias
        random walks (states 9-14) have no event and stay nominal. Heading (state 8) is what a
        foot INS loses first, ZUPTs do not observe it: scaling velocity alone would leave a
        shock's gyro noise out of ``Q``.
        """
        return tuple(range(9))

    @property
    def n_sub(self) -> int:
        """IMU samples per stride."""
        return int(round(self.dt * self.imu_rate_hz))

    @cached_property
    def row_sigma(self) -> np.ndarray:
        """Nominal 1-sigma of the six rows (fix N, E, D; ZUPT N, E, D)."""
        p, z = self.sigma_pos, self.sigma_zupt
        return np.array([p, p, VERTICAL_FACTOR * p, z, z, z])

    @cached_property
    def R(self) -> np.ndarray:
        """Nominal measurement noise ``(6, 6)`` the filter assumes."""
        return np.diag(self.row_sigma**2)

    @cached_property
    def Q(self) -> np.ndarray:
        """Process noise of one step ``(n, n)``: the Quadrotor's.

        Velocity and angle random walks, bias random walks
        (:attr:`navgym.quadrotor.platform.QuadrotorPlatform.Q`).
        """
        s, T = self.imu, self.dt
        Q = np.zeros((N_STATE, N_STATE))
        i = np.arange(3)
        qa = s.accel_noise**2
        Q[i, i] = qa * T**3 / 3.0
        Q[i, i + 3] = Q[i + 3, i] = qa * T**2 / 2.0
        Q[i + 3, i + 3] = qa * T
        Q[i + 6, i + 6] = s.gyro_noise**2 * T
        Q[i + 9, i + 9] = s.accel_bias_walk**2 * T
        Q[i + 12, i + 12] = s.gyro_bias_walk**2 * T
        return Q

    @cached_property
    def P0_sigma(self) -> np.ndarray:
        """Prior 1-sigma ``(n,)``: a fix, at rest, levelled, a compass heading, turn-on biases."""
        s = self.imu
        return np.concatenate(
            [
                self.row_sigma[:3],
                [SIGMA_VEL0] * 3,
                [SIGMA_TILT0, SIGMA_TILT0, SIGMA_YAW0],
                [max(s.accel_bias, BIAS0_FLOOR[0])] * 3,
                [max(s.gyro_bias, BIAS0_FLOOR[1])] * 3,
            ]
        )

    def chunk_steps(self, B: int, T: int) -> int:
        """Steps of the B episodes whose IMU samples are drawn and preintegrated at once."""
        return max(1, min(int(T), _CHUNK_STEPS, _CHUNK_SAMPLES // (max(1, B) * self.n_sub)))

    def episode_bytes(self, T: int) -> int:
        """Bytes of one episode of ``T`` steps at reset (see the Platform protocol).

        The stored per-step arrays (preintegrated IMU, rows, mask, truth: 654 bytes a step, with
        ``true_noise`` 112 more) two and a half times over, 600 bytes a step of scenario
        evaluations, and 700 bytes per IMU sample of one chunk of at most ``_CHUNK_STEPS`` steps
        of the episode (normals, kinematics, the preintegration's slabs).
        """
        steps = int(T) + 1
        stored = steps * (8 * (9 + 9 + 6 + 36 + 6 + N_STATE) + 6 + (112 if self.true_noise else 0))
        if self.context:  # the context's 17 numbers a step, the receiver's 12 channels (4 arrays)
            stored += steps * 8 * (17 + 4 * 12)
        return int(2.5 * stored) + 600 * steps + 700 * self.n_sub * min(int(T), _CHUNK_STEPS)

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> PedestrianEpisodes:
        """Walks, IMU (preintegrated), fixes and ZUPTs of ``len(rngs)`` episodes of ``T`` strides.

        Each episode draws from four child generators (walk and home, IMU errors, fixes,
        prior), each a fixed amount whatever B, so B episodes at once equal B single ones.
        """
        B = len(rngs)
        dt, n_sub = self.dt, self.n_sub
        delta = dt / n_sub
        seeds = np.array([r.integers(0, 2**63 - 1, size=4) for r in rngs])
        g_walk, g_imu, g_gnss, g_init = (default_rngs(seeds[:, i]) for i in range(4))
        u_walk = np.stack([g.random((T, PLAN_WIDTH)) for g in g_walk])
        home = np.array([g.random(3) for g in g_walk])  # latitude, height, initial heading
        plan = stride_plan(u_walk, 2.0 * np.pi * home[:, 2])
        lat0 = np.deg2rad(HOME_LAT_DEG[0] + (HOME_LAT_DEG[1] - HOME_LAT_DEG[0]) * home[:, 0])
        h0 = HOME_H_M[0] + (HOME_H_M[1] - HOME_H_M[0]) * home[:, 1]
        grav, grad, omega = home_frame(lat0, h0)

        # IMU errors: turn-on biases, a walk once per step, white noise per sample (+ the shocks)
        s = self.imu
        bias = imu_bias_walks(s, g_imu, dt, T)
        batch = stack_scenarios(list(scenarios))
        tt = np.broadcast_to(np.arange(T + 1) * dt, (B, T + 1))
        na = np.full((B, T), s.accel_noise / np.sqrt(delta))
        ng = np.full((B, T), s.gyro_noise / np.sqrt(delta))
        shock = None
        if np.isfinite(batch.burst_start).any():  # shocks: the step's per-sample sigmas
            na, ng, shock = _vibration(batch, tt[:, :T], na[:, 0], ng[:, 0], delta)
        dR, phi = np.empty((B, T, 3, 3)), np.empty((B, T, 3, 3))
        d6, J6 = np.empty((B, T, 6)), np.empty((B, T, 6, 6))
        chunk = self.chunk_steps(B, T)
        frac = (np.arange(n_sub) + 0.5) / n_sub
        if self.context:  # the stance detector's statistics of each stride's last samples
            W = stance_window(n_sub)
            g_abs = np.linalg.norm(grav, axis=-1)
            stance_log_t, stance_act = np.empty((B, T)), np.empty((B, T))
        compiled = compiled_enabled()
        if compiled:  # the foot's IMU in two compiled passes (navgym.pedestrian.imu_kernel), bit for bit
            tables = phase_tables(frac, dt)
            chi = 0.5 * (plan.yaw[:, 1:] + plan.yaw[:, :-1])
            course = (np.cos(chi), np.sin(chi))
        for c0 in range(0, T, chunk):
            nc = min(T, c0 + chunk) - c0
            noise = np.empty((B, nc * n_sub, 6))
            for e, g in enumerate(g_imu):  # each episode's stream, drawn in place (no stacked copy)
                g.standard_normal(out=noise[e])
            sl = slice(c0, c0 + nc)
            if compiled:
                home = (grav, grad, omega)
                gyro, accel = sampled_imu(plan, course, c0, nc, n_sub, dt, tables, home, bias, na, ng, noise)
            else:
                k = np.repeat(np.arange(c0, c0 + nc), n_sub)
                st = foot_state(plan, np.broadcast_to(k, (B, k.size)), np.tile(frac, nc)[None], dt)
                gyro, accel = foot_imu(st, grav, grad, omega)
                b = np.repeat(bias[:, sl], n_sub, axis=1)
                accel = accel + b[..., :3] + np.repeat(na[:, sl], n_sub, axis=1)[..., None] * noise[..., :3]
                gyro = gyro + b[..., 3:] + np.repeat(ng[:, sl], n_sub, axis=1)[..., None] * noise[..., 3:]
            if self.context:
                win = (B, nc, n_sub, 3)
                stance_log_t[:, sl], stance_act[:, sl] = stance_stats(
                    accel.reshape(win)[:, :, -W:], gyro.reshape(win)[:, :, -W:], g_abs,
                    s.accel_noise / np.sqrt(delta), s.gyro_noise / np.sqrt(delta),
                )  # fmt: skip
            # each stride's n_sub samples, (B, nc, n_sub, 3) -> (B, nc, ...)
            pre = preintegrate(gyro.reshape(B, nc, n_sub, 3), accel.reshape(B, nc, n_sub, 3), delta)
            dR[:, sl], phi[:, sl] = pre.dR, pre.phi
            d6[:, sl, :3], d6[:, sl, 3:] = pre.dv, pre.dp
            J6[:, sl, :3, :3], J6[:, sl, :3, 3:] = -pre.jva, pre.jvg
            J6[:, sl, 3:, :3], J6[:, sl, 3:, 3:] = -pre.jpa, pre.jpg

        truth = np.zeros((B, T + 1, N_STATE))
        truth[..., :3] = plan.start
        truth[..., 8] = plan.yaw
        truth[..., 9:] = bias

        # the fix (rows 0-2) with the scenario's degradations; the ZUPT (rows 3-5) at every epoch
        normals = np.stack([g.standard_normal((T + 1, 9)) for g in g_gnss])
        uniforms = np.stack([g.random((T + 1, 3)) for g in g_gnss])
        reg = noise_regime(batch, tt)
        loss = reg.loss_prob
        canyon = np.isfinite(batch.canyon_start).any()
        c_scale = 1.0
        if canyon:  # jamming and blockage lose a fix independently (the same uniform)
            c_scale, c_loss = canyon_regime(batch, tt)
            loss = loss + c_loss - loss * c_loss
        fix = gnss_available(batch, tt) & (uniforms[..., 0] >= loss)
        if canyon:
            fix &= _canyon_satellites(batch, tt) >= MIN_FIX_SATELLITES
        var = np.empty((B, T + 1, M_ROWS))
        phys = None
        if self.context:  # v3: HDOP sigma_UERE(C/N0) carries the canyon and the jamming
            cap = sky_satellites(batch, tt)
            phys = receiver_physics(seeds[:, 2], batch, tt, cap, self.sigma_pos, self.cn0_offset_db)
            fix &= phys.n_sv >= MIN_FIX_SATELLITES  # the same as v2's rule unless max_satellites < 4
            f2 = fix_variance_factor(phys)  # no fix where 0
            ratio = np.where(uniforms[..., 1] < reg.eps, reg.var_ratio, 1.0) * f2
            var[..., :3] = self.row_sigma[:3] ** 2 * ratio[..., None]  # (HDOP sigma_nom sqrt(u))^2
        else:
            ratio = np.where(uniforms[..., 1] < reg.eps, reg.var_ratio, 1.0) * c_scale**2
            var[..., :3] = self.row_sigma[:3] ** 2 * ratio[..., None] + reg.jam_sigma[..., None] ** 2
        var[..., :3] += np.where(uniforms[..., 2] < reg.outlier_prob, reg.outlier_scale, 0.0)[..., None] ** 2
        var[..., 3:] = self.sigma_zupt**2
        bias_r = np.zeros((B, T + 1, M_ROWS))
        if np.isfinite(batch.multipath_start).any():
            bias_r, mp_var = multipath_error(batch, tt, M_ROWS)
            var = var + mp_var
        z = truth[..., :M_ROWS] + bias_r + np.sqrt(var) * normals[..., :M_ROWS]
        mask = np.ones((B, T + 1, M_ROWS), dtype=bool)
        mask[..., :3] = fix[..., None]
        z = np.where(mask, z, np.nan)

        # prior: truth + N(0, P0) for position, velocity, attitude; zero biases
        zi = np.stack([g.standard_normal(9) for g in g_init])
        m0 = np.zeros((B, N_STATE))
        m0[:, :9] = truth[:, 0, :9] + zi * self.P0_sigma[:9]
        extra: dict[str, np.ndarray] = {}
        if self.true_noise:
            extra["true_q"] = np.zeros((B, T, 2)) if shock is None else shock
            extra["true_r"] = var
            extra["true_bias"] = bias_r
        if phys is not None:
            extra["context"] = context_reports(
                phys, fix, self.row_sigma[:3], M_ROWS, (stance_log_t, stance_act), dt
            )
        return PedestrianEpisodes(m0, grav, grad, omega, dR, phi, d6, J6, z, mask, truth, **extra)

    def initial_belief(self, ep: PedestrianEpisodes) -> GaussianState:
        """The prior ``N(m0, diag(P0_sigma^2))``."""
        B = ep.m0.shape[0]
        P0 = np.broadcast_to(np.diag(self.P0_sigma**2), (B, N_STATE, N_STATE)).copy()
        return GaussianState(ep.m0.copy(), P0)

    # ---------------------------------------------------------------------------------- step
    def step_models(self, ep: PedestrianEpisodes, t: np.ndarray) -> StepModels:
        """Strapdown transition of stride ``t`` and the fix and ZUPT of epoch ``t + 1``."""
        t = np.minimum(np.asarray(t), ep.dR.shape[1] - 1)
        rows = np.arange(t.shape[0])
        trans = StrapdownTransition(
            ep.dR[rows, t], ep.phi[rows, t], ep.d6[rows, t], ep.J6[rows, t],
            ep.gravity, ep.gradient, ep.earth_rate, self.dt, self.Q, [None],
        )  # fmt: skip
        k = t + 1
        truth = None
        if ep.true_r is not None:  # the v2 ids: what the simulator used (evaluation only)
            B = t.shape[0]
            extra = ep.true_q[rows, t]
            Q_true = self.Q + extra[:, 0, None, None] * vibration_q(self.dt, self.n_sub)
            i = np.arange(6, 9)
            Q_true[:, i, i] += extra[:, 1, None] * self.dt
            R_true = np.zeros((B, M_ROWS, M_ROWS))
            R_true[:, np.arange(M_ROWS), np.arange(M_ROWS)] = ep.true_r[rows, k]
            truth = TrueNoise(Q_true, R_true, ep.true_bias[rows, k].copy())
        return StepModels(trans, GnssFixModel(self.R), ep.z[rows, k], ep.mask[rows, k], self.dt, truth=truth)

    def position_error(
        self, mean: np.ndarray, ep: PedestrianEpisodes, t: np.ndarray, P: np.ndarray
    ) -> PositionError:
        """Horizontal error, truth and estimate, their covariance, the state error.

        A runaway covariance (a state variance beyond ``RUNAWAY_VARIANCE`` or non-finite) is
        reported as an infinite ``cov_ne``, which ends the episode as diverged (as the Quadrotor).
        """
        rows = np.arange(t.shape[0])
        truth = ep.truth[rows, t]
        d = mean - truth
        d[:, 6:9] = wrap_angle(d[:, 6:9])
        cov_ne = P[:, :2, :2].copy()
        diag = np.diagonal(P, axis1=1, axis2=2)
        cov_ne[~(diag <= RUNAWAY_VARIANCE).all(axis=1)] = np.inf
        return PositionError(np.hypot(d[:, 0], d[:, 1]), truth[:, :2], mean[:, :2].copy(), cov_ne, d)

    # ------------------------------------------------------------------------------ features
    def features(self) -> list[Feature]:
        """Innovations of the fix and ZUPT rows and the covariance's log-sigmas (no truth)."""
        return [
            *innovation_features(
                M_ROWS, "innovations (fix N, E, D; ZUPT N, E, D) / sqrt(S_ii); 0: row absent",
                rows="rows used", unit_rows="rows used / 6 (the ZUPT's 3 are always there)",
            ),
            *(b.feature for b in COVARIANCE_BLOCKS),
            *(context_features(M_ROWS) if self.context else ()),
        ]  # fmt: skip

    def initial_feature_values(self, belief: GaussianState, ep: PedestrianEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        return {
            **innovation_initial_values(B, M_ROWS),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
            **(context_feature_values(ep.context, np.zeros(B, int)) if ep.context is not None else {}),
        }

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: PedestrianEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        return {
            **innovation_values(info, models.mask, M_ROWS),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
            **(context_feature_values(ep.context, np.asarray(t)) if ep.context is not None else {}),
        }
