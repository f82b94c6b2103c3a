"""The Robot2d estimation problem: truth and sensors of B episodes, what the filter sees.

See :mod:`navgym.robot2d.models` for the filter models and :mod:`navgym.robot2d.env` for the card.

The v2 events of a scenario (:mod:`navgym.scenarios.scenario`) act on the truth and the sensors
while the filter's ``Q`` and ``R`` stay nominal:

* a motion burst (wheel slip) adds, at every step ``k -> k + 1`` that starts inside it, a white
  position error ``w_k ~ N(0, (velocity_sigma dt)^2 I_2)`` and a heading error ``y_k ~ N(0,
  (yaw_rate_sigma dt)^2)``; the heading error accumulates (``psi_{k+1} = psi_k + y_k``) and turns
  the rest of the drive: ``p_{k+1} = p_k + R(psi_k) (p0_{k+1} - p0_k) + w_k`` and ``phi_k = phi0_k +
  psi_k`` over the commanded path ``(p0, phi0)``, exactly the step the filter's eq. 77 model
  makes plus ``(w_k, y_k)``, so the step's true process noise is the nominal ``Q`` plus
  ``diag((velocity_sigma dt)^2, (velocity_sigma dt)^2, (yaw_rate_sigma dt)^2)``; the encoder and
  steering sensors do not see it, the compass and the fixes do;
* multipath adds its bias (and noise) to its row's fixes;
* an urban canyon caps the satellites (below :data:`MIN_FIX_SATELLITES` no fix), multiplies the
  fix noise by ``noise_scale`` and loses each fix with ``loss_prob`` (combined with a jammer's
  loss as independent causes);
* a jamming ramp scales the jamming noise and loss (:func:`navgym.scenarios.noise_regime`).

With ``true_noise=True`` (the v2 ids) the episodes also hold what the simulator used, and
:meth:`Robot2dPlatform.step_models` hands it to the evaluation as ``StepModels.truth``
(:class:`~navgym.envs.protocols.TrueNoise`): the true ``Q`` above, ``R`` with each fix row's
variance as drawn (sensor noise, times the impulsive-noise ratio where that fix is an outlier,
times the canyon's ``noise_scale**2``, plus the jamming and multipath variances; the compass
nominal) and the multipath bias per row.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from filters.core.compiled import compiled_enabled
from filters.core.linalg import gram
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
from navgym.gnss.receiver_report import check_cn0_offset
from navgym.ins.attitude import wrap_angle
from navgym.robot2d.context import (
    CONTEXT_FEATURES,
    Robot2dContext,
    context_feature_values,
    context_reports,
    gyro_consistency,
    receiver_physics,
)
from navgym.robot2d.models import FixCompassModel, OdometryTransition, control_jacobian
from navgym.robot2d.noise_kernel import process_noise_pass
from navgym.robot2d.robot import (
    RobotGeometry,
    RobotParams,
    RobotTrajectory,
    encoder_speed,
    robot_trajectory,
    sample_robot_plans,
)
from navgym.robot2d.sensors import (
    COMPASS_RATE_HZ,
    GLONASS_RATE_HZ,
    GPS_RATE_HZ,
    ROBOT_NOISE_WIDTH,
    RobotSensorNoise,
    position_fixes,
    robot_measurements,
    schedule_stride,
)
from navgym.scenarios import (
    Scenario,
    ScenarioBatch,
    ScenarioDistribution,
    canyon_regime,
    default_rngs,
    gnss_available,
    max_satellites,
    motion_burst,
    multipath_error,
    noise_regime,
    stack_scenarios,
)
from navgym.scenarios.seeding import standard_normal_batch

#: Measurement rows: GPS north/east, GLONASS north/east, compass.
ROWS = ("gps_N", "gps_E", "glonass_N", "glonass_E", "compass")
#: Rows of the GNSS position fixes (the scenario's degradations act on these only).
GNSS_ROWS = (0, 1, 2, 3)
#: Fewer usable satellites than this (a partial outage) means no position fix.
MIN_FIX_SATELLITES = 4
#: Log-sigma features of the filter's covariance.
COVARIANCE_BLOCKS = (
    CovarianceBlock("log_sigma_pos", (0, 1), -3.0, 3.0, "log10 m", "log10 sqrt(P_NN + P_EE)"),
    CovarianceBlock("log_sigma_heading", (2,), -5.0, 1.0, "log10 rad", "log10 sqrt(P_phiphi)"),
)
#: Uniforms per step: GPS and GLONASS outlier draws (eq. 71), GPS and GLONASS loss draws.
_UNIFORM_WIDTH = 4


class Robot2dEpisodes(NamedTuple):
    """Precomputed truth and sensor data of B episodes (episode axis first, ``T + 1`` steps).

    Truth-only fields (evaluation; never in the observation): ``truth_pos``, ``truth_heading``,
    ``truth_scale`` and, with ``true_noise``, ``true_q``, ``true_r``, ``true_bias``. Everything
    else is what the robot's sensors deliver.
    """

    truth_pos: np.ndarray  # (B, T+1, 2) point L north/east [m] (truth only)
    truth_heading: np.ndarray  # (B, T+1) heading [rad], unwrapped (truth only)
    truth_scale: np.ndarray  # (B,) encoder scale error s, unmodelled (truth only)
    encoder: np.ndarray  # (B, T+1) measured rear-right wheel speed [m/s] (control)
    steering: np.ndarray  # (B, T+1) measured steering angle [rad] (control)
    z: np.ndarray  # (B, T+1, 5) measurements (NaN where not delivered), compass unwrapped
    mask: np.ndarray  # (B, T+1, 5) delivered rows
    q_heading: np.ndarray  # (B, T+1) last delivered compass heading (orients Q)
    fix_age: np.ndarray  # (B, T+1) time since the last GNSS fix [s]
    m0: np.ndarray  # (B, 3) initial estimate (first GPS fix and compass reading)
    #: (B, T+1, 3) process-noise variance the bursts add to step k -> k + 1 (truth only; None
    #: unless ``true_noise``)
    true_q: np.ndarray | None = None
    #: (B, T+1, 5) measurement-noise variance of each row at epoch k (truth only, or None)
    true_r: np.ndarray | None = None
    #: (B, T+1, 5) mean measurement error (multipath bias) of each row at epoch k (truth only, or None)
    true_bias: np.ndarray | None = None
    #: The v3 context (receiver reports, odometry-IMU consistency; sensor-side), or None
    context: Robot2dContext | None = None


@dataclass(frozen=True)
class Robot2dPlatform(PlatformBase):
    """Benzerrouk 2014's car-like robot navigation problem (see the module docstring and the env card).

    Attributes:
        dt: Filter step [s] (the GPS period; GLONASS and compass strides follow their rates).
        sensors: Sensor noise (GPS, GLONASS per-axis [m], compass [deg], encoder [m/s],
            steering [deg]); the filter's ``R`` and control noise use the same values.
        encoder_scale_sigma: Spread of the true encoder scale error s (unmodelled by the filter).
        robot: Drive distribution (speed, steering, command segments, geometry).
        scenarios: GNSS degradation distribution.
        slip_sigma: Unmodelled horizontal motion per step, as a velocity sigma [m/s]; adds
            ``(slip_sigma dt)^2`` to Q's position. It covers what the truth has and the model
            lacks: the encoder scale error (2 % of up to 3 m/s) and commands changing inside a
            step (7 mm rms per step, up to 0.26 m at a switch). 0.3 m/s makes the EKF's NEES
            about n on GNSS and keeps a 1000-particle filter from collapsing.
        yaw_sigma: Unmodelled yaw rate sigma [rad/s]; adds ``(yaw_sigma dt)^2`` to Q's heading
            (scale error on the yaw rate, command switches: 1.4 mrad rms per step).
        error_scale_m: Position error giving reward -1 [m].
        divergence_m: Position error ending an episode [m].
        true_noise: Keep the noise the simulator used and hand it out as ``StepModels.truth``
            (the v2 ids; see the module docstring). False: ``truth`` is None and nothing extra
            is stored.
        context: Simulate the v3 context (:mod:`navgym.robot2d.context`): the fix noise follows
            each receiver's HDOP and C/N0 (jamming as J/S, canyons as fewer satellites and a
            signal loss, NLOS segments as a loss), and the observation gains the receivers'
            reports and the odometry-IMU consistency. False (v0-v2): nothing of it is drawn.
        cn0_offset_db: Calibration offset [dB] of the receivers' C/N0 reports (another receiver
            model; :func:`navgym.gnss.receiver_report.check_cn0_offset`): the reported C/N0 and
            accuracy figures follow it, the true C/N0 and the fix noise do not. Needs ``context``.

    """

    dt: float = 0.1
    sensors: RobotSensorNoise = field(default_factory=RobotSensorNoise)
    encoder_scale_sigma: float = 0.02
    robot: RobotParams = field(default_factory=RobotParams)
    scenarios: ScenarioDistribution = field(default_factory=ScenarioDistribution)
    slip_sigma: float = 0.3
    yaw_sigma: float = 0.02
    error_scale_m: float = 2.0
    divergence_m: float = 200.0
    true_noise: bool = False
    context: bool = False
    cn0_offset_db: float = 0.0
    name: str = "Robot2d"
    n: int = 3
    m_max: int = 5

    def __post_init__(self) -> None:
        if not self.dt > 0:
            raise ValueError(f"dt must be > 0; got {self.dt}")
        for rate in (GPS_RATE_HZ, GLONASS_RATE_HZ, COMPASS_RATE_HZ):
            schedule_stride(self.dt, rate)  # raises unless the rates divide 1/dt
        for name in ("gps", "glonass", "compass_deg"):
            if not getattr(self.sensors, name) > 0:
                raise ValueError(
                    f"sensors.{name} must be > 0 (it is the filter's R); got {getattr(self.sensors, name)}"
                )
        for name in ("encoder_scale_sigma", "slip_sigma", "yaw_sigma"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0; got {v!r}")
        check_cn0_offset(self.cn0_offset_db, self.context)
        self.check_reward_scales()

    # --------------------------------------------------------------------------------- setup
    def episode_bytes(self, T: int) -> int:
        """Bytes of one episode of ``T`` steps at reset (see the Platform protocol).

        The per-step arrays of :class:`Robot2dEpisodes` (truth, controls, measurements and
        their mask, fix age: 101 bytes a step) five times over for the simulation's temporaries
        (sensor normals, trajectory, noise regime; its measured peak is 4.6 times) and 4 bytes a
        step per outage slot of the scenario distribution; with ``true_noise`` the truth's 13
        numbers a step too.
        """
        steps = int(T) + 1
        stored = steps * (8 * (2 + 1 + 1 + 1 + 5 + 1 + 1) + 5)
        if self.true_noise:
            stored += steps * 8 * (3 + 5 + 5)
        if self.context:  # the context's 17 numbers a step, and its temporaries (2 x 12 channels)
            stored += steps * 8 * (17 + 2 * 12 * 2)
        sc = self.scenarios
        slots = 4 * max(1, sc.outage_count[1])
        # the v2 events' interval slots (none without them: the v0/v1 figure is unchanged)
        slots += 4 * (sc.jamming_count[1] - 1)
        slots += 4 * sc.burst_count[1] * (sc.burst_probability > 0) + 4 * sc.canyon_count[1] * (
            sc.canyon_probability > 0
        )
        slots += 18 * self.m_max * sc.multipath_count[1] * (sc.multipath_probability > 0)
        return 5 * stored + steps * slots

    @property
    def geometry(self) -> RobotGeometry:
        return self.robot.geometry

    @property
    def gnss_rows(self) -> tuple[int, ...]:
        """Measurement rows that are GNSS (the compass is not): also the Mixture's outlier rows."""
        return GNSS_ROWS

    def R(self) -> np.ndarray:
        """Measurement noise ``(5, 5)``: GPS, GLONASS per axis, compass (nominal regime)."""
        s = self.sensors
        return np.diag([s.gps**2, s.gps**2, s.glonass**2, s.glonass**2, np.deg2rad(s.compass_deg) ** 2])

    def P0(self) -> np.ndarray:
        """Prior covariance: the noise of the first GPS fix and compass reading."""
        s = self.sensors
        return np.diag([s.gps**2, s.gps**2, np.deg2rad(s.compass_deg) ** 2])

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> Robot2dEpisodes:
        """Truth (eq. 77 plans) and every sensor reading of B episodes of T steps.

        Each episode draws, from its own generator, three child seeds (plan, sensor normals,
        scale + uniforms), so B episodes at once equal B single ones.
        """
        B = len(rngs)
        dt = self.dt
        g = self.geometry
        sens = self.sensors
        seeds = np.array([r.integers(0, 2**63 - 1, size=3) for r in rngs])
        g_plan = default_rngs(seeds[:, 0])
        g_meas = default_rngs(seeds[:, 1])
        g_misc = default_rngs(seeds[:, 2])
        params = self.robot
        if params.duration < T * dt:
            params = replace(params, duration=float(T * dt))
        plans = sample_robot_plans(g_plan, params)
        k = np.arange(T + 1)
        traj = robot_trajectory(plans, k * dt, g)
        normals = standard_normal_batch(g_meas, (T + 1, ROBOT_NOISE_WIDTH))
        scale = np.array([r.standard_normal() for r in g_misc]) * self.encoder_scale_sigma
        uniforms = standard_uniform_batch(g_misc, (T + 1, _UNIFORM_WIDTH))
        batch = stack_scenarios(list(scenarios))
        tt = np.broadcast_to(k * dt, (B, T + 1))
        burst_var = None
        if np.isfinite(batch.burst_start).any():  # wheel slip: the truth leaves the commanded path
            traj, burst_var = _slip(traj, batch, tt, seeds[:, 2], dt)
        meas = robot_measurements(traj, k[None, :], normals, dt, geometry=g, sensors=sens)
        phys = None
        if self.context:
            phys = receiver_physics(seeds[:, 2], batch, tt, (sens.gps, sens.glonass), self.cn0_offset_db)

        # GNSS degradations of the scenario (impulsive noise on the position fixes: Benzerrouk 2014, eq. 71)
        fix_ok = gnss_available(batch, tt) & (max_satellites(batch, tt) >= MIN_FIX_SATELLITES)
        reg = noise_regime(batch, tt)
        gps_out = uniforms[..., 0] < reg.eps
        glo_out = uniforms[..., 1] < reg.eps
        loss = reg.loss_prob
        canyon = np.isfinite(batch.canyon_start).any()
        multipath = np.isfinite(batch.multipath_start).any()
        if canyon:  # jamming and blockage lose a fix independently
            c_scale, c_loss = canyon_regime(batch, tt)
            loss = loss + c_loss - loss * c_loss
        gps_ok = meas.gps_mask & fix_ok & ~(uniforms[..., 2] < loss)
        glo_ok = meas.glonass_mask & fix_ok & ~(uniforms[..., 3] < loss)
        jam2 = reg.jam_sigma**2
        if phys is not None:  # v3: HDOP sigma_UERE(C/N0) carries canyon and jamming
            fv = np.where(np.isfinite(phys.fix_var), phys.fix_var, 0.0)  # no fix where not finite
            var_gps = fv[..., 0] * np.where(gps_out, reg.var_ratio, 1.0)
            var_glo = fv[..., 1] * np.where(glo_out, reg.var_ratio, 1.0)
        if canyon or multipath or self.true_noise or phys is not None:
            # per-row variances; without events they are the sums below, bit for bit
            if phys is None:
                var_gps = sens.gps**2 * np.where(gps_out, reg.var_ratio, 1.0)
                var_glo = sens.glonass**2 * np.where(glo_out, reg.var_ratio, 1.0)
                if canyon:
                    var_gps, var_glo = var_gps * c_scale**2, var_glo * c_scale**2
                var = np.stack([var_gps, var_gps, var_glo, var_glo], axis=-1) + jam2[..., None]
            else:
                var = np.stack([var_gps, var_gps, var_glo, var_glo], axis=-1)
            bias = np.zeros((B, T + 1, len(GNSS_ROWS)))
            if multipath:
                mp_bias, mp_var = multipath_error(batch, tt, self.m_max)
                if (mp_bias[..., len(GNSS_ROWS) :] != 0).any() or (mp_var[..., len(GNSS_ROWS) :] != 0).any():
                    raise ValueError("multipath acts on the GNSS rows 0-3 only (the compass is not GNSS)")
                var = var + mp_var[..., : len(GNSS_ROWS)]
                bias = mp_bias[..., : len(GNSS_ROWS)]
            fixes = traj.position[..., [0, 1, 0, 1]] + np.sqrt(var) * normals[..., 0:4]
            if multipath:
                fixes = fixes + bias
            gps, glo = fixes[..., 0:2], fixes[..., 2:4]
        else:
            sig_gps = np.sqrt(sens.gps**2 * np.where(gps_out, reg.var_ratio, 1.0) + jam2)
            sig_glo = np.sqrt(sens.glonass**2 * np.where(glo_out, reg.var_ratio, 1.0) + jam2)
            gps = position_fixes(traj.position, sig_gps, normals[..., 0:2])
            glo = position_fixes(traj.position, sig_glo, normals[..., 2:4])
        # wheel-radius error: v_e = (1 + s) v_true + noise
        encoder = meas.encoder + scale[:, None] * encoder_speed(traj.v_c, traj.alpha, g)

        # compass unwrapped along its own delivered readings (estimator side)
        stride = schedule_stride(dt, COMPASS_RATE_HZ)
        delivered = np.unwrap(meas.compass[:, ::stride], axis=1)
        compass = np.full((B, T + 1), np.nan)
        compass[:, ::stride] = delivered
        q_heading = np.repeat(delivered, stride, axis=1)[:, : T + 1]

        mask = np.stack([gps_ok, gps_ok, glo_ok, glo_ok, meas.compass_mask], axis=-1)
        z = np.concatenate([gps, glo, compass[..., None]], axis=-1)
        z = np.where(mask, z, np.nan)
        fix = gps_ok | glo_ok
        fix[:, 0] = True  # the fix the filter starts from
        last = np.maximum.accumulate(np.where(fix, k, 0), axis=1)
        fix_age = (k - last) * dt
        # prior mean: first GPS fix (before any degradation: raw sensor noise) and compass
        gps0 = traj.position[:, 0] + sens.gps * normals[:, 0, 0:2]
        m0 = np.concatenate([gps0, delivered[:, :1]], axis=1)
        truth: dict[str, Any] = {}
        if phys is not None:
            imu = gyro_consistency(traj.heading, encoder, meas.steering, seeds[:, 2], dt, g)
            truth["context"] = context_reports(phys, np.stack([gps_ok, glo_ok], axis=-1), imu, dt)
        if self.true_noise:
            r_compass = np.full((B, T + 1, 1), np.deg2rad(sens.compass_deg) ** 2)
            truth |= {
                "true_q": np.zeros((B, T + 1, 3)) if burst_var is None else burst_var,
                "true_r": np.concatenate([var, r_compass], axis=-1),
                "true_bias": np.concatenate([bias, np.zeros((B, T + 1, 1))], axis=-1),
            }
        return Robot2dEpisodes(
            traj.position,
            traj.heading,
            scale,
            encoder,
            meas.steering,
            z,
            mask,
            q_heading,
            fix_age,
            m0,
            **truth,
        )

    def initial_belief(self, ep: Robot2dEpisodes) -> GaussianState:
        B = ep.m0.shape[0]
        return GaussianState(ep.m0.copy(), np.broadcast_to(self.P0(), (B, 3, 3)).copy())

    # ---------------------------------------------------------------------------------- step
    def process_noise(self, q_heading: np.ndarray, v_e: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        """``Q = G diag(sigma_e^2, sigma_alpha^2) G^T + diag(q_slip, q_slip, q_yaw)`` ``(B, 3, 3)``.

        ``G = df/d(v_e, alpha)`` (:func:`control_jacobian`) at the last delivered compass heading
        (the platform does not see the filter's state); ``q_slip = (slip_sigma dt)^2`` and
        ``q_yaw = (yaw_sigma dt)^2`` are the unmodelled motion of the class docstring. The
        compiled twin (:mod:`navgym.robot2d.noise_kernel`) forms it unless
        :func:`filters.core.compiled.numpy_only` forces these NumPy passes.
        """
        dt = self.dt
        sigma_e, sigma_alpha = self.sensors.encoder, float(np.deg2rad(self.sensors.steering_deg))
        q_slip, q_yaw = (self.slip_sigma * dt) ** 2, (self.yaw_sigma * dt) ** 2
        if compiled_enabled():
            g = self.geometry
            Q = np.empty((q_heading.shape[0], 3, 3))
            f64 = np.float64
            process_noise_pass(
                np.ascontiguousarray(q_heading, f64), np.ascontiguousarray(v_e, f64),
                np.ascontiguousarray(alpha, f64), dt, g.wheelbase, g.a, g.b, g.encoder_offset,
                sigma_e, sigma_alpha, q_slip, q_yaw, Q,
            )  # fmt: skip
            return Q
        G = control_jacobian(q_heading, v_e, alpha, dt, self.geometry)
        Gs = G * np.array([sigma_e, sigma_alpha])
        Q = gram(Gs)
        Q[:, [0, 1, 2], [0, 1, 2]] += np.array([q_slip, q_slip, q_yaw])
        return Q

    def step_models(self, ep: Robot2dEpisodes, t: np.ndarray) -> StepModels:
        B = t.shape[0]
        rows = np.arange(B)
        last = ep.encoder.shape[1] - 1
        t = np.minimum(t, last - 1)
        k = t + 1  # measurement epoch
        v_e = ep.encoder[rows, t]
        alpha = ep.steering[rows, t]
        ta = np.tan(alpha)
        g = self.geometry
        v_c = v_e / (1.0 - g.encoder_offset * ta / g.wheelbase)
        Q = self.process_noise(ep.q_heading[rows, t], v_e, alpha)
        trans = OdometryTransition(v_c, ta, Q, g)
        obs = FixCompassModel(self.R())
        truth = None
        if ep.true_r is not None:  # the v2 ids: what the simulator used (evaluation only)
            Q_true = Q.copy()
            Q_true[:, [0, 1, 2], [0, 1, 2]] += ep.true_q[rows, t]
            R_true = np.zeros((B, self.m_max, self.m_max))
            R_true[:, np.arange(self.m_max), np.arange(self.m_max)] = ep.true_r[rows, k]
            truth = TrueNoise(Q_true, R_true, ep.true_bias[rows, k].copy())
        return StepModels(trans, obs, ep.z[rows, k], ep.mask[rows, k], self.dt, truth=truth)

    def position_error(
        self, mean: np.ndarray, ep: Robot2dEpisodes, t: np.ndarray, P: np.ndarray
    ) -> PositionError:
        rows = np.arange(t.shape[0])
        truth = ep.truth_pos[rows, t]
        d = mean[:, :2] - truth
        err = np.concatenate([d, wrap_angle(mean[:, 2] - ep.truth_heading[rows, t])[:, None]], axis=1)
        return PositionError(np.hypot(d[:, 0], d[:, 1]), truth, mean[:, :2].copy(), P[:, :2, :2].copy(), err)

    # ------------------------------------------------------------------------------ features
    def features(self) -> list[Feature]:
        return [
            *innovation_features(
                self.m_max, "innovations / sqrt(S_ii) of GPS N/E, GLONASS N/E, compass; 0 where not received",
                rows="rows used", unit_rows="measurement rows used / 5",
            ),
            *(b.feature for b in COVARIANCE_BLOCKS),
            Feature("time_since_fix", 0.0, 10.0, "min", "time since the last GNSS position fix / 60 s"),
            *(CONTEXT_FEATURES if self.context else ()),
        ]  # fmt: skip

    def initial_feature_values(self, belief: GaussianState, ep: Robot2dEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        return {
            **innovation_initial_values(B, self.m_max),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
            "time_since_fix": np.zeros(B),
            **(context_feature_values(ep.context, np.zeros(B, int)) if ep.context is not None else {}),
        }

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: Robot2dEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        rows = np.arange(t.shape[0])
        return {
            **innovation_values(info, models.mask, self.m_max),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
            "time_since_fix": ep.fix_age[rows, np.minimum(t, ep.fix_age.shape[1] - 1)] / 60.0,
            **(context_feature_values(ep.context, t) if ep.context is not None else {}),
        }


def _slip(
    traj: RobotTrajectory, batch: ScenarioBatch, tt: np.ndarray, seeds: np.ndarray, dt: float
) -> tuple[RobotTrajectory, np.ndarray]:
    """The truth under the scenario's motion bursts, and the variances they add per step.

    The commanded path ``(p0, phi0)`` of ``traj`` becomes ``p_{k+1} = p_k + R(psi_k) (p0_{k+1} -
    p0_k) + w_k``, ``phi_k = phi0_k + psi_k``, ``psi_{k+1} = psi_k + y_k`` with ``w_k ~ N(0,
    (velocity_sigma dt)^2 I)``, ``y_k ~ N(0, (yaw_rate_sigma dt)^2)`` at the step's start time
    (the module docstring). The normals come from ``default_rng([seed, 1])`` of each episode's
    misc seed, drawn only for episodes with a burst; the others keep ``traj`` exactly.

    Returns:
        The trajectory and ``(B, T+1, 3)`` variances ``[(v dt)^2, (v dt)^2, (y dt)^2]`` of step k -> k + 1.

    """
    B, n = tt.shape
    v_sig, y_sig = motion_burst(batch, tt)
    var = np.stack([(v_sig * dt) ** 2, (v_sig * dt) ** 2, (y_sig * dt) ** 2], axis=-1)
    has = np.isfinite(batch.burst_start).any(axis=1)
    noise = np.zeros((B, n, 3))
    for i in np.flatnonzero(has):
        noise[i] = np.random.default_rng([int(seeds[i]), 1]).standard_normal((n, 3))
    w = noise[:, :-1, :2] * (v_sig[:, :-1, None] * dt)
    yaw = noise[:, :-1, 2] * (y_sig[:, :-1] * dt)
    psi = np.concatenate([np.zeros((B, 1)), np.cumsum(yaw, axis=1)], axis=1)
    dp = np.diff(traj.position, axis=1)
    c, s = np.cos(psi[:, :-1]), np.sin(psi[:, :-1])
    turned = np.stack([c * dp[..., 0] - s * dp[..., 1], s * dp[..., 0] + c * dp[..., 1]], axis=-1)
    drift = np.concatenate([np.zeros((B, 1, 2)), np.cumsum(turned - dp + w, axis=1)], axis=1)
    keep = ~has[:, None]
    pos = np.where(keep[..., None], traj.position, traj.position + drift)
    heading = np.where(keep, traj.heading, traj.heading + psi)
    return traj._replace(position=pos, heading=heading), var


def standard_uniform_batch(rngs: Sequence[np.random.Generator], shape: tuple[int, ...]) -> np.ndarray:
    """Stack ``rng.random(shape)`` over the episodes: ``(B,) + shape`` (one draw per episode)."""
    out = np.empty((len(rngs), *shape))
    for i, rng in enumerate(rngs):
        out[i] = rng.random(shape)
    return out
