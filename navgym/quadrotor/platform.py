"""The Quadrotor estimation problem: flights, IMU and GNSS of B episodes, what the filter sees.

See :mod:`navgym.quadrotor.models` for the filter models and :mod:`navgym.quadrotor.env` for the card.
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
from navgym.envs.protocols import PositionError, StepModels
from navgym.geo import gravity, meridian_radius, normal_radius
from navgym.ins import CONSUMER_MEMS, PERFECT, TACTICAL, ImuErrorSpec, earth_rate_ned
from navgym.ins.attitude import wrap_angle
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
    ScenarioDistribution,
    default_rngs,
    gnss_available,
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
class QuadrotorPlatform(PlatformBase):
    """Benzerrouk 2014's quadrotor INS/GNSS estimation problem (module docstring and the env card)."""

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
        self.check_reward_scales()

    # --------------------------------------------------------------------------------- setup
    def episode_bytes(self, T: int) -> int:
        """Bytes of one episode of ``T`` steps at reset (see the Platform protocol).

        The per-step arrays of :class:`QuadrotorEpisodes` (preintegrated IMU, fixes, truth: 649
        bytes a step) two and a half times over for the simulation's temporaries, 4 bytes a
        step per outage slot of the scenario distribution, and the IMU samples' normals (48
        bytes each, ``dt * imu_rate_hz`` a step), drawn in chunks of at most ``_CHUNK_SAMPLES``
        samples.
        """
        steps = int(T) + 1
        stored = steps * (8 * (9 + 9 + 6 + 36 + 6 + N_STATE) + 1)
        slots = steps * 4 * max(1, self.scenarios.outage_count[1])
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
        """Estimator-side observation features of the platform."""
        return [
            *innovation_features(
                M_ROWS, "innovations (p, v NED) / sqrt(S_ii); 0: no fix", rows="rows used",
                unit_rows="fix rows used / 6 (0 or 1: the fix is all or nothing)",
            ),
            *(b.feature for b in COVARIANCE_BLOCKS),
        ]  # fmt: skip

    def initial_feature_values(self, belief: GaussianState, ep: QuadrotorEpisodes) -> dict[str, np.ndarray]:
        """Features of the prior (no fix processed yet)."""
        return {
            **innovation_initial_values(belief.m.shape[0], M_ROWS),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
        }

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: QuadrotorEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Features from the filter's belief and update diagnostics (no truth)."""
        return {
            **innovation_values(info, models.mask, M_ROWS),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
        }
