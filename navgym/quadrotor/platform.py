"""The Quadrotor estimation problem: flights, IMU and GNSS of B episodes, what the filter sees.

See :mod:`navgym.quadrotor.models` for the filter models and :mod:`navgym.quadrotor.env` for the card.

The v2 events of a scenario (:mod:`navgym.scenarios.scenario`) act on the IMU and the GNSS fixes
while the filter's ``Q`` and ``R`` stay nominal:

* a motion burst is **vibration** of the airframe (a damaged propeller, a motor resonance): for
  every step ``k -> k + 1`` that starts inside it, each of the step's ``n_sub`` IMU samples gets
  extra white accelerometer noise of ``velocity_sigma / sqrt(delta)`` [m/s^2] per axis
  (``delta = dt / n_sub``) and extra white gyro noise of ``yaw_rate_sigma / sqrt(delta)``
  [rad/s] per axis, on top of the grade's (variances add). So ``velocity_sigma`` is read as the
  burst's velocity random walk [m/s/sqrt(s)] (an accelerometer noise density) and
  ``yaw_rate_sigma`` as its angle random walk [rad/sqrt(s)]. The airframe does not move with it:
  the noise is measured, not flown (a gust, which the airframe does fly, is sensed by the IMU
  and so is no error of the strapdown solution; it is not modelled). Over one step the
  preintegration (:mod:`navgym.quadrotor.imu_kernel`) turns the samples' noise ``n_j`` (variance
  ``s^2 / delta`` per axis, ``s = velocity_sigma``) into ``dv = sum_j R_j n_j delta`` and ``dp =
  sum_j R_j n_j delta^2 (n_sub - j - 1/2)``; isotropic white noise stays isotropic and white
  under the rotations ``R_j``, so per axis exactly::

      Var(dv) = s^2 T,   Cov(dp, dv) = s^2 T^2 / 2,   Var(dp) = s^2 (T^3 / 3 - T delta^2 / 12)

  (``T = dt``; :func:`vibration_q`), which the step's true process noise adds to the position
  and velocity block, and ``yaw_rate_sigma^2 T`` to the Euler angles (the form of the filter's
  own angle random walk: exact when level);
* multipath adds its bias (and noise) to its row of the fix (the v2 ids draw it on the position
  rows N, E, D; a row's unit is the row's: m, or m/s on a velocity row);
* an urban canyon caps the satellites (below :data:`MIN_FIX_SATELLITES` no fix), multiplies the
  fix's sensor noise (all six rows) by ``noise_scale`` and loses each fix with ``loss_prob``
  (combined with a jammer's loss as independent causes: one uniform draw, no new randomness);
* a jamming ramp scales the jamming noise and loss (:func:`navgym.scenarios.noise_regime`);
  several outages are ``outage_count`` > 1.

With ``true_noise=True`` (the v2 ids) the episodes also hold what the simulator used, and
:meth:`QuadrotorPlatform.step_models` hands it to the evaluation as ``StepModels.truth``
(:class:`~navgym.envs.protocols.TrueNoise`): the true ``Q`` (the filter's ``Q`` times the true
IMU's squared error scale ``imu_scale**2``, 1 without ``imu_mismatch``, plus the bursts' terms
above), ``R`` with each row's variance as drawn (sensor noise times the impulsive-noise ratio
where that fix is an outlier, times the canyon's ``noise_scale**2``, plus the jamming, multipath
and gross-outlier variances) and the multipath bias per row. With ``bias_features=True`` (the v2
ids) the observation also carries the filter's own accelerometer and gyro bias estimates and
their rates (:meth:`QuadrotorPlatform.features`). Without events nothing new is drawn: an
episode without them is simulated bit for bit as before.

With ``context=True`` (v3, :mod:`navgym.quadrotor.context`) the fix's noise per row is
``HDOP sigma_nom sqrt(u)`` from the receiver's satellites and C/N0 instead: the canyon acts
through fewer satellites and a diffraction loss, the jamming through its J/S, multipath segments
through an NLOS loss (v2's canyon factor and jamming variance are then not added; the impulsive
ratio, multipath bias and noise and gross outliers are), and the observation gains the
receiver's report and the IMU samples' window statistics. The flight, the IMU and every v2 draw
stay as they are; the receiver draws from its own generator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from navgym.envs.features import (
    CovarianceBlock,
    Feature,
    covariance_values,
    innovation_features,
    innovation_initial_values,
    innovation_values,
)
from navgym.envs.platform import PlatformBase
from navgym.envs.protocols import PositionError, StepModels, TrueNoise
from navgym.envs.rows import epoch_index
from navgym.gnss.receiver_report import check_cn0_offset, fix_variance_factor
from navgym.ins import CONSUMER_MEMS, PERFECT, TACTICAL, ImuErrorSpec, home_frame, imu_bias_walks
from navgym.ins.attitude import wrap_angle
from navgym.quadrotor.context import (
    QuadrotorContext,
    context_feature_values,
    context_features,
    context_reports,
    imu_window,
    receiver_physics,
)
from navgym.quadrotor.flight import (
    QuadrotorParams,
    home_gravity,
    quadrotor_home_truth,
    quadrotor_positions,
    sample_quadrotor_plans,
)
from navgym.quadrotor.models import (
    M_ROWS,
    N_STATE,
    GnssFixModel,
    StrapdownTransition,
)
from navgym.scenarios import (
    Scenario,
    ScenarioBatch,
    ScenarioDistribution,
    canyon_regime,
    default_rngs,
    gnss_available,
    motion_burst,
    multipath_error,
    noise_regime,
    stack_scenarios,
)

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
#: Fewer usable satellites than this (an urban canyon's cap) means no fix.
MIN_FIX_SATELLITES = 4
#: Rows of the fix's position (N, E, D): the v2 ids draw multipath on these.
POSITION_ROWS = (0, 1, 2)
#: Bounds of the bias-estimate features (``bias_features``), in units of the IMU grade's turn-on
#: bias sigma (of ``P0_sigma``): the estimates, and their rates per second.
BIAS_BOUND = 20.0
BIAS_RATE_BOUND = 50.0
#: IMU samples (over all episodes) per chunk when simulating at reset: bounds the buffer of their
#: normals (6 per sample, 25 MB).
_CHUNK_SAMPLES = 1 << 19
#: Log-sigma features of the filter's covariance (sums of three variances each).
COVARIANCE_BLOCKS = (
    CovarianceBlock("log_sigma_pos", (0, 1, 2), -3.0, 5.0, "log10 m", "log10 sqrt(tr P_pp)"),
    CovarianceBlock("log_sigma_vel", (3, 4, 5), -4.0, 3.0, "log10 m/s", "log10 sqrt(tr P_vv)"),
    CovarianceBlock(
        "log_sigma_att", (6, 7, 8), -6.0, 1.0, "log10 rad", "log10 sqrt of the Euler-angle variances"
    ),
    CovarianceBlock("log_sigma_accel_bias", (9, 10, 11), -6.0, 1.0, "log10 m/s^2", "log10 sqrt(tr P_ba)"),
    CovarianceBlock("log_sigma_gyro_bias", (12, 13, 14), -8.0, 0.0, "log10 rad/s", "log10 sqrt(tr P_bg)"),
)


class QuadrotorEpisodes(NamedTuple):
    """Precomputed sensor data and truth of B episodes of T steps (episode axis first).

    Estimator-side (what a real filter has): the prior mean, the home's gravity, gravity gradient
    and Earth rate, the preintegrated IMU of every step and the GNSS fixes. Truth (evaluation
    only, never seen by the filter): ``truth``, ``t_start``, ``imu_scale``, ``origin`` and, with
    ``true_noise``, ``true_q``, ``true_r``, ``true_bias``.
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
    #: (B, T, 2) the vibration bursts' accelerometer and gyro noise densities squared,
    #: ``[velocity_sigma^2, yaw_rate_sigma^2]``, of step k -> k + 1 (truth only; None unless ``true_noise``)
    true_q: np.ndarray | None = None
    #: (B, T + 1, 6) measurement-noise variance of each fix row at epoch k (truth only, or None)
    true_r: np.ndarray | None = None
    #: (B, T + 1, 6) mean measurement error (multipath bias) of each row at epoch k (truth only, or None)
    true_bias: np.ndarray | None = None
    #: (B, 6) the filter's bias estimate ``[b_a, b_g]`` after the last step (estimator side, for the
    #: rate features; None unless ``bias_features``): a cursor the features advance
    bias_prev: np.ndarray | None = None
    #: The v3 context (receiver reports, IMU window statistics; sensor-side), or None
    context: QuadrotorContext | None = None


@dataclass(frozen=True)
class QuadrotorPlatform(PlatformBase):
    """Benzerrouk 2014's quadrotor INS/GNSS estimation problem (module docstring and the env card).

    ``true_noise``: keep the noise the simulator used and hand it out as ``StepModels.truth``
    (the v2 ids; module docstring); False: ``truth`` is None and nothing extra is stored.
    ``bias_features``: the observation also carries the filter's bias estimates and their rates
    (the v2 ids); False: the v0/v1 observation.
    ``context``: simulate the v3 context (:mod:`navgym.quadrotor.context`): the fix noise follows
    the receiver's DOP and C/N0 (jamming as J/S, canyons as fewer satellites and a signal loss,
    multipath segments as a loss), and the observation gains the receiver's report and the IMU
    samples' window statistics. False (v0-v2): nothing of it is drawn or stored.
    ``cn0_offset_db``: the receiver report's C/N0 calibration offset [dB], another receiver model
    (:func:`navgym.gnss.receiver_report.check_cn0_offset`; the true C/N0 stays; needs ``context``).
    """

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
    true_noise: bool = False
    bias_features: bool = False
    context: bool = False
    cn0_offset_db: float = 0.0
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
        check_cn0_offset(self.cn0_offset_db, self.context)
        self.check_reward_scales()

    @property
    def process_noise_states(self) -> tuple[int, ...]:
        """Position and velocity (states 0-5): where the accelerometer's noise enters ``Q``.

        The IMU's white specific-force noise, and a v2 vibration burst's, is preintegrated into
        the position/velocity block (``Q_pp, Q_pv, Q_vv`` of one density, :func:`vibration_q`);
        RowScale's ``Q' = D Q D`` with ``sqrt(s_q)`` on these six states scales that block as a
        whole by ``s_q`` (the velocity alone would leave ``Q_pp`` and half-scale ``Q_pv``).
        """
        return (0, 1, 2, 3, 4, 5)

    @property
    def episode_cursors(self) -> tuple[str, ...]:
        """``bias_prev`` where the bias-rate features are on (they advance it), else none."""
        return ("bias_prev",) if self.bias_features else ()

    # --------------------------------------------------------------------------------- setup
    def episode_bytes(self, T: int) -> int:
        """Bytes of one episode of ``T`` steps at reset (see the Platform protocol).

        The per-step arrays of :class:`QuadrotorEpisodes` (preintegrated IMU, fixes, truth: 649
        bytes a step) two and a half times over for the simulation's temporaries, 4 bytes a
        step per outage slot of the scenario distribution, and the IMU samples' normals (48
        bytes each, ``dt * imu_rate_hz`` a step), drawn in chunks of at most ``_CHUNK_SAMPLES``
        samples. The v2 events add their interval slots, the per-step noise sigmas of a burst
        and, with ``true_noise``, the truth's 14 numbers a step (none of it without them: the
        v0/v1 figure is unchanged).
        """
        steps = int(T) + 1
        stored = steps * (8 * (9 + 9 + 6 + 36 + 6 + N_STATE) + 1)
        sc = self.scenarios
        slots = steps * 4 * max(1, sc.outage_count[1])
        slots += steps * 4 * (sc.jamming_count[1] - 1)
        bursts = sc.burst_probability > 0
        slots += steps * (4 * sc.burst_count[1] + 16) * bursts
        slots += steps * 4 * sc.canyon_count[1] * (sc.canyon_probability > 0)
        slots += steps * 18 * self.m_max * sc.multipath_count[1] * (sc.multipath_probability > 0)
        if self.true_noise:
            stored += steps * 8 * (2 + 6 + 6)
        if self.context:  # the context's 21 numbers and 8 IMU sums a step, the receiver's 12 channels
            stored += steps * 8 * (21 + 8 + 4 * 12)
        samples = self.n_sub * min(int(T), max(1, _CHUNK_SAMPLES // self.n_sub))
        return int(2.5 * stored) + slots + 48 * samples

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

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> QuadrotorEpisodes:
        """Truth, IMU (preintegrated) and GNSS fixes of ``len(rngs)`` episodes of ``T`` steps.

        Every episode draws from four child generators of its own generator (flight plan and
        start time, IMU errors, GNSS noise, prior), each a fixed amount whatever B, so B
        episodes at once equal B single ones.
        """
        from navgym.quadrotor.imu_kernel import N_STATS, preintegrated_imu  # numba: on first use

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
        grav, grad, omega = home_frame(lat0, h0)

        # IMU errors: the true IMU's scale (model mismatch), turn-on biases, walk once per epoch,
        # white noise per sample.
        s = self.imu
        u_scale = np.array([g.random() for g in g_imu])
        if self.imu_mismatch is None:
            scale = np.ones(B)
        else:
            lo, hi = np.log(self.imu_mismatch[0]), np.log(self.imu_mismatch[1])
            scale = np.exp(lo + (hi - lo) * u_scale)
        bias = imu_bias_walks(s, g_imu, dt, T, scale)
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
        batch = stack_scenarios(list(scenarios))
        tt = np.broadcast_to(np.arange(T + 1) * dt, (B, T + 1))
        burst_var = None
        if np.isfinite(batch.burst_start).any():  # vibration: the step's noise sigmas (module docstring)
            na, ng, burst_var = _vibration(batch, tt[:, :T], na, ng, delta)
        chunk = max(1, _CHUNK_SAMPLES // (B * n_sub))
        stats = np.empty((B, T, N_STATS)) if self.context else None
        noise = np.empty((B, min(chunk, T), n_sub, 6))
        for c0 in range(0, T, chunk):
            nc = min(T, c0 + chunk) - c0
            block = noise[:, :nc]
            for i, g in enumerate(g_imu):  # each episode's block drawn in place (as a (nc n_sub, 6) draw)
                g.standard_normal(out=block[i].reshape(nc * n_sub, 6))
            preintegrated_imu(
                plans,
                t_start,
                c0,
                dt,
                n_sub,
                omega,
                gamma_nodes,
                bias,
                block,
                na,
                ng,
                (dR, phi, d6, J6),
                stats,
            )

        truth = np.concatenate([np.stack(pos_t, axis=-1), np.stack(vel_t, axis=-1), euler, bias], axis=-1)

        # GNSS fixes at the epochs (episode-relative times of the scenario).
        normals = np.stack([g.standard_normal((T + 1, 12)) for g in g_gnss])
        uniforms = np.stack([g.random((T + 1, 3)) for g in g_gnss])
        reg = noise_regime(batch, tt)
        loss = reg.loss_prob
        canyon = np.isfinite(batch.canyon_start).any()
        multipath = np.isfinite(batch.multipath_start).any()
        if canyon:  # jamming and blockage lose a fix independently (the same uniform)
            c_scale, c_loss = canyon_regime(batch, tt)
            loss = loss + c_loss - loss * c_loss
        fix = gnss_available(batch, tt) & (uniforms[..., 0] >= loss)
        if canyon:
            fix &= _canyon_satellites(batch, tt) >= MIN_FIX_SATELLITES
        ratio = np.where(uniforms[..., 1] < reg.eps, reg.var_ratio, 1.0)[..., None]
        row_scale = np.array([1.0, 1.0, 1.0] + [self.sigma_vel / self.sigma_pos] * 3)
        phys = None
        if self.context:  # v3: DOP sigma_UERE(C/N0) carries the canyon and the jamming
            cap = sky_satellites(batch, tt)
            phys = receiver_physics(seeds[:, 2], batch, tt, cap, self.sigma_pos, self.cn0_offset_db)
            fix &= phys.n_sv >= MIN_FIX_SATELLITES  # the same as v2's rule unless max_satellites < 4
            f2 = fix_variance_factor(phys)  # no fix where 0
            var = self.row_sigma**2 * ratio * f2[..., None]  # (HDOP sigma_nom sqrt(u))^2, VDOP in sigma_nom
        else:
            if canyon:
                ratio = ratio * c_scale[..., None] ** 2
            var = self.row_sigma**2 * ratio + (reg.jam_sigma[..., None] * row_scale) ** 2
        bias_r = None
        if multipath:
            bias_r, mp_var = multipath_error(batch, tt, M_ROWS)
            var = var + mp_var
        gross = np.where(uniforms[..., 2] < reg.outlier_prob, reg.outlier_scale, 0.0)[..., None] * row_scale
        z = truth[..., :M_ROWS] + np.sqrt(var) * normals[..., :6] + gross * normals[..., 6:]
        if multipath:
            z = z + bias_r

        # Prior: truth + N(0, P0) for position, velocity, attitude; zero biases (the turn-on
        # biases above are drawn from the same N(0, sigma_b^2) the prior assumes).
        zi = np.stack([g.standard_normal(9) for g in g_init])
        m0 = np.zeros((B, N_STATE))
        m0[:, :9] = truth[:, 0, :9] + zi * self.P0_sigma[:9]
        extra: dict[str, np.ndarray] = {}
        if self.true_noise:
            extra["true_q"] = np.zeros((B, T, 2)) if burst_var is None else burst_var
            extra["true_r"] = var + gross**2
            extra["true_bias"] = np.zeros((B, T + 1, M_ROWS)) if bias_r is None else bias_r
        if self.bias_features:
            extra["bias_prev"] = m0[:, 9:15].copy()
        if phys is not None:
            imu = imu_window(stats, n_sub, dt)
            extra["context"] = context_reports(phys, fix, self.row_sigma, imu, dt)
        return QuadrotorEpisodes(
            m0,
            grav,
            grad,
            omega,
            dR,
            phi,
            d6,
            J6,
            z,
            fix,
            truth,
            t_start,
            scale,
            plans.origin.copy(),
            **extra,
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
        now, nxt = epoch_index(t), epoch_index(t + 1)  # views where every episode is at one step
        trans = StrapdownTransition(
            ep.dR[now], ep.phi[now], ep.d6[now], ep.J6[now],
            ep.gravity, ep.gradient, ep.earth_rate, self.dt, self.Q, [None],
        )  # fmt: skip
        fix = ep.fix[nxt]
        mask = np.repeat(fix[:, None], M_ROWS, axis=1)
        z = np.where(mask, ep.z[nxt], np.nan)
        truth = None
        if ep.true_r is not None:  # the v2 ids: what the simulator used (evaluation only)
            B = ep.m0.shape[0]
            extra = ep.true_q[now]  # (B, 2)
            Q_true = (ep.imu_scale**2)[:, None, None] * self.Q
            Q_true = Q_true + extra[:, 0, None, None] * vibration_q(self.dt, self.n_sub)
            i = np.arange(6, 9)
            Q_true[:, i, i] += extra[:, 1, None] * self.dt
            R_true = np.zeros((B, M_ROWS, M_ROWS))
            R_true[:, np.arange(M_ROWS), np.arange(M_ROWS)] = ep.true_r[nxt]
            truth = TrueNoise(Q_true, R_true, np.array(ep.true_bias[nxt]))
        return StepModels(trans, GnssFixModel(self.R), z, mask, self.dt, truth=truth)

    def position_error(
        self, mean: np.ndarray, ep: QuadrotorEpisodes, t: np.ndarray, P: np.ndarray
    ) -> PositionError:
        """Horizontal error, north/east truth and estimate, their covariance, the state error.

        A runaway covariance (any state variance beyond :data:`RUNAWAY_VARIANCE` or non-finite,
        e.g. extreme fading of the yaw and biases, which GNSS fixes observe weakly while the
        position stays pinned) is reported as an infinite ``cov_ne``: the core's covariance bound
        then ends the episode as diverged before the covariance can overflow.
        """
        rows = np.arange(t.shape[0])
        truth = ep.truth[rows, t]
        d = mean - truth
        d[:, 6:9] = wrap_angle(d[:, 6:9])
        cov_ne = P[:, :2, :2].copy()
        diag = np.diagonal(P, axis1=1, axis2=2)
        runaway = ~(diag <= RUNAWAY_VARIANCE).all(axis=1)
        cov_ne[runaway] = np.inf
        return PositionError(np.hypot(d[:, 0], d[:, 1]), truth[:, :2], mean[:, :2].copy(), cov_ne, d)

    # ------------------------------------------------------------------------------ features
    def features(self) -> list[Feature]:
        """Estimator-side observation features of the platform.

        With ``bias_features`` also the filter's bias estimates (the state's ``b_a``, ``b_g``) and
        their rates, each in units of the IMU grade's turn-on bias sigma (``P0_sigma``: 1 mg and
        0.1 deg/s for consumer MEMS): ``accel_bias`` and ``gyro_bias`` in
        ``[-BIAS_BOUND, BIAS_BOUND]`` (20), ``accel_bias_rate`` and ``gyro_bias_rate``, the change of
        the estimate over the last step divided by ``dt`` (per second), in
        ``[-BIAS_RATE_BOUND, BIAS_RATE_BOUND]`` (50). A bias estimate that runs away (a vibration
        burst or a multipath bias the filter explains as a sensor bias) shows here.
        """
        out = [
            *innovation_features(
                M_ROWS, "innovations (p, v NED) / sqrt(S_ii); 0: no fix", rows="rows used",
                unit_rows="fix rows used / 6 (0 or 1: the fix is all or nothing)",
            ),
            *(b.feature for b in COVARIANCE_BLOCKS),
        ]  # fmt: skip
        if self.context:
            out += context_features(M_ROWS)
        if self.bias_features:
            b, r = BIAS_BOUND, BIAS_RATE_BOUND
            sa, sg = "accelerometer", "gyro"
            out += [
                Feature(
                    "accel_bias",
                    -b,
                    b,
                    "sigma_ba",
                    f"the filter's {sa} bias estimate (x, y, z) / turn-on sigma",
                    3,
                ),
                Feature(
                    "gyro_bias",
                    -b,
                    b,
                    "sigma_bg",
                    f"the filter's {sg} bias estimate (x, y, z) / turn-on sigma",
                    3,
                ),
                Feature(
                    "accel_bias_rate",
                    -r,
                    r,
                    "sigma_ba/s",
                    f"change of the {sa} bias estimate in the step / dt",
                    3,
                ),
                Feature(
                    "gyro_bias_rate",
                    -r,
                    r,
                    "sigma_bg/s",
                    f"change of the {sg} bias estimate in the step / dt",
                    3,
                ),
            ]
        return out

    def _bias_values(self, m: np.ndarray, prev: np.ndarray) -> dict[str, np.ndarray]:
        """The bias features of estimates ``m (B, n)`` after a step from ``prev (B, 6)`` (see features)."""
        sig = self.P0_sigma[9:15]
        b = m[:, 9:15] / sig
        rate = (m[:, 9:15] - prev) / (sig * self.dt)
        return {
            "accel_bias": b[:, :3],
            "gyro_bias": b[:, 3:],
            "accel_bias_rate": rate[:, :3],
            "gyro_bias_rate": rate[:, 3:],
        }

    def initial_feature_values(self, belief: GaussianState, ep: QuadrotorEpisodes) -> dict[str, np.ndarray]:
        """Features of the prior (no fix processed yet; bias rates 0)."""
        out = {
            **innovation_initial_values(belief.m.shape[0], M_ROWS),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
        }
        if self.bias_features:
            out.update(self._bias_values(belief.m, belief.m[:, 9:15]))
        if self.context:
            out.update(context_feature_values(ep.context, np.zeros(belief.m.shape[0], int)))
        return out

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: QuadrotorEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Features from the filter's belief and update diagnostics (no truth).

        With ``bias_features`` the episodes' ``bias_prev`` (the last step's estimates, a cursor)
        advances to this step's.
        """
        out = {
            **innovation_values(info, models.mask, M_ROWS),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
        }
        if self.bias_features:
            out.update(self._bias_values(belief.m, ep.bias_prev))
            ep.bias_prev[:] = belief.m[:, 9:15]
        if self.context:
            out.update(context_feature_values(ep.context, np.asarray(t)))
        return out


def vibration_q(dt: float, n_sub: int) -> np.ndarray:
    """Process noise ``(n, n)`` of one step per unit accelerometer noise density squared.

    ``n_sub`` samples of white noise of variance ``1 / delta`` per axis (``delta = dt / n_sub``)
    preintegrated as the kernel does (module docstring): ``Var(dv) = T``, ``Cov(dp, dv) = T^2 / 2``,
    ``Var(dp) = T^3 / 3 - T delta^2 / 12`` per axis, ``T = dt``.
    """
    T, delta = dt, dt / n_sub
    Q = np.zeros((N_STATE, N_STATE))
    i = np.arange(3)
    Q[i, i] = T**3 / 3.0 - T * delta**2 / 12.0
    Q[i, i + 3] = Q[i + 3, i] = T**2 / 2.0
    Q[i + 3, i + 3] = T
    return Q


def _vibration(
    batch: ScenarioBatch, t: np.ndarray, na: np.ndarray, ng: np.ndarray, delta: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The per-step noise sigmas ``(B, T)`` under the bursts, and their densities squared ``(B, T, 2)``.

    ``t (B, T)`` are the steps' start times; a burst's ``velocity_sigma`` and ``yaw_rate_sigma``
    are noise densities, per sample ``sigma / sqrt(delta)``, added in variance to the grade's
    per-sample sigmas ``na``, ``ng`` ``(B,)`` (module docstring).
    """
    v_sig, y_sig = motion_burst(batch, t)
    na2 = np.sqrt(na[:, None] ** 2 + v_sig**2 / delta)
    ng2 = np.sqrt(ng[:, None] ** 2 + y_sig**2 / delta)
    return na2, ng2, np.stack([v_sig**2, y_sig**2], axis=-1)


def sky_satellites(batch: ScenarioBatch, t: np.ndarray) -> np.ndarray:
    """The v3 receiver's cap at ``t (B, T)``: 0 in an outage, a canyon's count in one, else the channels."""
    canyon = np.isfinite(batch.canyon_start).any()
    sats = _canyon_satellites(batch, t) if canyon else batch.max_satellites[:, None]
    return np.where(gnss_available(batch, t), sats, 0)


def _canyon_satellites(batch: ScenarioBatch, t: np.ndarray) -> np.ndarray:
    """Usable satellites under the urban canyons at times ``t (B, T)`` (the scenario's channels outside).

    Only the canyons' caps: a position fix has no partial outages (module docstring of
    :mod:`navgym.quadrotor.models`).
    """
    tt = t[:, :, None]
    active = (batch.canyon_start[:, None, :] <= tt) & (tt < batch.canyon_end[:, None, :])
    cap = np.where(active, batch.canyon_satellites[:, None, :], np.iinfo(np.int64).max).min(axis=-1)
    return np.minimum(cap, batch.max_satellites[:, None])
