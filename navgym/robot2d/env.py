"""Robot2d: seed 001's car-like robot (eq. 77) with wheel encoder, compass, GPS and GLONASS.

Seed 001 §2.7b-c fuses GPS (10 Hz), GLONASS (5 Hz) and an electronic compass (5 Hz) with a
wheel encoder on a car-like robot whose point L moves by eq. 77 (see
:mod:`navgym.robot2d.robot`). The encoder formula is the rear-right wheel in these axes (x north,
y east, clockwise heading); the seed's "back left wheel" names it in Guivant & Nebot's mirrored
frame. The filter state is::

    x = [x_N, y_E, phi]

north/east position of point L [m] and heading from north [rad] (unwrapped). Prediction over
one step ``dt = 0.1`` s is the exact discrete eq. 77 (circular arc,
:func:`navgym.robot2d.robot.robot_transition`) with the measured encoder speed and steering
angle held as control::

    v_c = v_e / (1 - H tan(alpha) / L),   w = v_c tan(alpha) / L,   x+ = eq. 77 arc

The truth has what the filter does not model: the encoder's scale error ``s`` (wheel radius,
the first extension seed 001 names after eq. 77; ``v_e = (1 + s) v_true + noise``, ``s`` drawn
per episode) and commands that change inside a step. An encoder-scale state was left out on
purpose: under a sustained fading factor it is unobservable within the filter's short memory
and runs away; the unmodelled scale is the model error that fading factors exist for.

Measurements at each step (``m_max = 5`` rows, a mask says which are present)::

    z = [gps_N, gps_E, glonass_N, glonass_E, compass] = [x_N, y_E, x_N, y_E, phi] + v

GPS every step (10 Hz), GLONASS and compass every other step (5 Hz); GNSS rows are further
masked by the episode's scenario (outages, jamming losses). The compass is unwrapped along its
own delivered readings (a 5 Hz heading changes far less than pi between readings), so every
filter, the particle filter included, sees a continuous heading; the Gaussian filters also
wrap the compass residual (:meth:`FixCompassModel.residual`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from filters import GaussianState
from filters.core.linalg import gram
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels
from navgym.robot2d.robot import (
    RobotGeometry,
    RobotParams,
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
    ScenarioDistribution,
    default_rngs,
    gnss_available,
    max_satellites,
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
#: Uniforms per step: GPS and GLONASS outlier draws (eq. 71), GPS and GLONASS loss draws.
_UNIFORM_WIDTH = 4


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to ``[-pi, pi)`` (NaN stays NaN: a diverged filter is flagged elsewhere)."""
    with np.errstate(invalid="ignore"):
        return np.mod(a + np.pi, 2.0 * np.pi) - np.pi


def _dsinc(th: np.ndarray) -> np.ndarray:
    """Derivative of ``sin(th) / th`` (series below 1e-3, where the quotient cancels)."""
    small = np.abs(th) < 1e-3
    safe = np.where(small, 1.0, th)
    exact = (safe * np.cos(safe) - np.sin(safe)) / (safe * safe)
    return np.where(small, -th / 3.0 + th**3 / 30.0, exact)


def _offset_rate(phi: np.ndarray, g: RobotGeometry) -> np.ndarray:
    """``d offset(phi) / d phi`` of the point L relative to the rear-axle centre, ``(..., 2)``."""
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([-g.a * s - g.b * c, g.a * c - g.b * s], axis=-1)


class Robot2dEpisodes(NamedTuple):
    """Precomputed truth and sensor data of B episodes (episode axis first, ``T + 1`` steps).

    Truth-only fields (evaluation; never in the observation): ``truth_pos``, ``truth_heading``,
    ``truth_scale``. Everything else is what the robot's sensors deliver.
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


class OdometryTransition(NamedTuple):
    """Eq. 77 driven by the measured encoder speed and steering, batched over B episodes.

    ``f`` broadcasts over ``(B, n)``, sigma points ``(B, S, n)`` and particles ``(B, N, n)``;
    the controls ``(B,)`` are aligned with axis 0.
    """

    v_c: np.ndarray  # (B,) rear-axle speed from the encoder, v_e / kappa [m/s]
    tan_alpha: np.ndarray  # (B,) tan of the measured steering angle
    Q: np.ndarray  # (B, 3, 3)
    geometry: RobotGeometry

    def repeat_batch(self, K: int) -> OdometryTransition:
        """Each episode's parameters repeated K times (Gaussian-sum filters stack components)."""
        return OdometryTransition(*(np.repeat(a, K, axis=0) for a in self[:3]), self.geometry)

    def _half_turn(self, dt: float) -> np.ndarray:
        """``th = w dt / 2`` with ``w = v_c tan(alpha) / L``, ``(B,)``."""
        return 0.5 * dt * self.v_c * self.tan_alpha / self.geometry.wheelbase

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 0.1) -> np.ndarray:
        """Exact discrete eq. 77 over one step (seed 001 eq. 77; arc form of ``robot_transition``).

        ``phi+ = phi + w dt``, ``c+ = c + v_c dt sinc(w dt / 2) [cos, sin](phi + w dt / 2)`` for the
        rear-axle centre ``c = p - offset(phi)``, ``p+ = c+ + offset(phi+)``. With ``offset(phi) =
        R(phi) [a, b]`` and ``th = w dt / 2`` the position step is ``R(phi) [d cos th - 2 a sin^2 th
        - 2 b sin th cos th, d sin th + 2 a sin th cos th - 2 b sin^2 th]``, ``d = v_c dt
        sinc(th)``: the body-frame step is the same for every state of an episode, so sigma points
        and particles cost two trigonometric calls each. ``u`` is ignored (controls are held in
        the model).
        """
        g = self.geometry
        B = x.shape[0]
        flat = x.reshape(B, -1, x.shape[-1])
        th = self._half_turn(dt)
        sn, cs = np.sin(th), np.cos(th)
        d = self.v_c * dt * np.sinc(th / np.pi)
        s2, sc2 = 2.0 * sn * sn, 2.0 * sn * cs
        bx = (d * cs - g.a * s2 - g.b * sc2)[:, None]
        by = (d * sn + g.a * sc2 - g.b * s2)[:, None]
        phi = flat[..., 2]
        c0, s0 = np.cos(phi), np.sin(phi)
        out = np.empty_like(flat)
        out[..., 0] = flat[..., 0] + c0 * bx - s0 * by
        out[..., 1] = flat[..., 1] + s0 * bx + c0 * by
        out[..., 2] = phi + 2.0 * th[:, None]
        return out.reshape(x.shape)

    def F(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 0.1) -> np.ndarray:
        """Jacobian ``df/dx (B, 3, 3)`` of :meth:`f` at ``x (B, 3)`` (seed 001 eq. 77).

        ``dp+/dphi = d [-sin, cos](phi + th) + offset'(phi + 2 th) - offset'(phi)``; the rest is
        the identity.
        """
        g = self.geometry
        th = self._half_turn(dt)
        phi = x[:, 2]
        d = self.v_c * dt * np.sinc(th / np.pi)
        mid = phi + th
        J = np.zeros((x.shape[0], 3, 3))
        J[:, 0, 0] = J[:, 1, 1] = J[:, 2, 2] = 1.0
        J[:, :2, 2] = (
            d[:, None] * np.stack([-np.sin(mid), np.cos(mid)], axis=-1)
            + _offset_rate(phi + 2.0 * th, g)
            - _offset_rate(phi, g)
        )
        return J


def control_jacobian(
    phi: np.ndarray, v_e: np.ndarray, alpha: np.ndarray, dt: float, geometry: RobotGeometry
) -> np.ndarray:
    """``df/d(v_e, alpha) (B, 3, 2)`` of eq. 77's arc (maps control noise into Q).

    Chain rule through ``v_c = v_e / kappa``, ``kappa = 1 - H tan(alpha) / L``, ``w = v_c
    tan(alpha) / L`` and the arc's ``dp+/dv_c = dt sinc(th) [cos, sin](phi + th)``, ``dp+/dw =
    v_c dt^2 / 2 sinc'(th) [cos, sin](phi + th) + d dt / 2 [-sin, cos](phi + th) + dt
    offset'(phi + 2 th)``, ``dphi+/dw = dt``.
    """
    g = geometry
    t = np.tan(alpha)
    sec2 = 1.0 + t * t
    kappa = 1.0 - g.encoder_offset * t / g.wheelbase
    v = v_e / kappa
    w = v * t / g.wheelbase
    th = 0.5 * w * dt
    sc = np.sinc(th / np.pi)
    d = v * dt * sc
    mid = phi + th
    along = np.stack([np.cos(mid), np.sin(mid)], axis=-1)
    normal = np.stack([-np.sin(mid), np.cos(mid)], axis=-1)
    dp_dv = (dt * sc)[:, None] * along
    dp_dw = (
        (v * dt * dt / 2.0 * _dsinc(th))[:, None] * along
        + (d * dt / 2.0)[:, None] * normal
        + dt * _offset_rate(phi + 2.0 * th, g)
    )
    dv = np.stack([1.0 / kappa, v * g.encoder_offset * sec2 / (g.wheelbase * kappa)], axis=-1)
    dw = t[:, None] / g.wheelbase * dv
    dw[:, 1] += v * sec2 / g.wheelbase
    G = np.zeros((phi.shape[0], 3, 2))
    G[:, :2, :] = dp_dv[:, :, None] * dv[:, None, :] + dp_dw[:, :, None] * dw[:, None, :]
    G[:, 2, :] = dt * dw
    return G


class FixCompassModel(NamedTuple):
    """``h(x) = [x_N, y_E, x_N, y_E, phi]``: GPS fix, GLONASS fix, compass (seed 001 §2.7c).

    Linear with constant ``H (5, 3)``; the compass residual is wrapped to ``[-pi, pi)``.
    """

    R: np.ndarray  # (5, 5)

    def repeat_batch(self, K: int) -> FixCompassModel:
        """No parameter is batched: the same model serves the stacked ``(B*K)`` batch."""
        return self

    def h(self, x: np.ndarray) -> np.ndarray:
        return x[..., [0, 1, 0, 1, 2]]

    def H(self, x: np.ndarray) -> np.ndarray:
        return _H

    def residual(self, z: np.ndarray, z_hat: np.ndarray) -> np.ndarray:
        """``z - z_hat`` with the compass row wrapped to ``[-pi, pi)``."""
        v = np.asarray(z, dtype=np.float64) - z_hat
        v[..., 4] = _wrap(v[..., 4])
        return v


_H = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]], dtype=np.float64)
_H.setflags(write=False)


@dataclass(frozen=True)
class Robot2dPlatform:
    """Seed 001's car-like robot navigation problem (see the module docstring and the env card).

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
        if not (self.error_scale_m > 0 and self.divergence_m > 0):
            raise ValueError("error_scale_m and divergence_m must be > 0")

    # --------------------------------------------------------------------------------- setup
    @property
    def geometry(self) -> RobotGeometry:
        return self.robot.geometry

    @property
    def gnss_rows(self) -> tuple[int, ...]:
        """Measurement rows that are GNSS (the core's time-since-GNSS looks at these)."""
        return GNSS_ROWS

    @property
    def outlier_rows(self) -> tuple[int, ...]:
        """Rows subject to impulsive noise (the Mixture task inflates only these)."""
        return GNSS_ROWS

    def sample_scenario(self, rng: np.random.Generator) -> Scenario:
        return self.scenarios.sample(rng)

    def sample_scenarios(self, rngs: Sequence[np.random.Generator]) -> list[Scenario]:
        return list(self.scenarios.sample_many(list(rngs)))

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
        meas = robot_measurements(traj, k[None, :], normals, dt, geometry=g, sensors=sens)

        # GNSS degradations of the scenario (position fixes: seed 001 eq. 71 on the fix noise)
        batch = stack_scenarios(list(scenarios))
        tt = np.broadcast_to(k * dt, (B, T + 1))
        fix_ok = gnss_available(batch, tt) & (max_satellites(batch, tt) >= MIN_FIX_SATELLITES)
        reg = noise_regime(batch, tt)
        gps_out = uniforms[..., 0] < reg.eps
        glo_out = uniforms[..., 1] < reg.eps
        gps_ok = meas.gps_mask & fix_ok & ~(uniforms[..., 2] < reg.loss_prob)
        glo_ok = meas.glonass_mask & fix_ok & ~(uniforms[..., 3] < reg.loss_prob)
        jam2 = reg.jam_sigma**2
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
        return Robot2dEpisodes(
            traj.position, traj.heading, scale, encoder, meas.steering, z, mask, q_heading, fix_age, m0
        )

    def initial_belief(self, ep: Robot2dEpisodes) -> GaussianState:
        B = ep.m0.shape[0]
        return GaussianState(ep.m0.copy(), np.broadcast_to(self.P0(), (B, 3, 3)).copy())

    # ---------------------------------------------------------------------------------- step
    def process_noise(self, q_heading: np.ndarray, v_e: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        """``Q = G diag(sigma_e^2, sigma_alpha^2) G^T + diag(q_slip, q_slip, q_yaw)`` ``(B, 3, 3)``.

        ``G = df/d(v_e, alpha)`` (:func:`control_jacobian`) at the last delivered compass heading
        (the platform does not see the filter's state); ``q_slip = (slip_sigma dt)^2`` and
        ``q_yaw = (yaw_sigma dt)^2`` are the unmodelled motion of the class docstring.
        """
        dt = self.dt
        G = control_jacobian(q_heading, v_e, alpha, dt, self.geometry)
        su = np.array([self.sensors.encoder, np.deg2rad(self.sensors.steering_deg)])
        Gs = G * su
        Q = gram(Gs)
        Q[:, [0, 1, 2], [0, 1, 2]] += np.array(
            [(self.slip_sigma * dt) ** 2] * 2 + [(self.yaw_sigma * dt) ** 2]
        )
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
        trans = OdometryTransition(v_c, ta, self.process_noise(ep.q_heading[rows, t], v_e, alpha), g)
        obs = FixCompassModel(self.R())
        return StepModels(trans, obs, ep.z[rows, k], ep.mask[rows, k], self.dt)

    def position_error(
        self, mean: np.ndarray, ep: Robot2dEpisodes, t: np.ndarray, P: np.ndarray
    ) -> dict[str, np.ndarray]:
        rows = np.arange(t.shape[0])
        truth = ep.truth_pos[rows, t]
        d = mean[:, :2] - truth
        err = np.concatenate([d, _wrap(mean[:, 2] - ep.truth_heading[rows, t])[:, None]], axis=1)
        return {
            "pos_err_m": np.hypot(d[:, 0], d[:, 1]),
            "truth_pos": truth,
            "est_pos": mean[:, :2].copy(),
            "state_err": err,
            "cov_ne": P[:, :2, :2].copy(),
        }

    # ------------------------------------------------------------------------------ features
    def features(self) -> list[Feature]:
        return [
            Feature(
                "innovation",
                -10.0,
                10.0,
                "-",
                "innovations / sqrt(S_ii) of GPS N/E, GLONASS N/E, compass; 0 where not received",
                self.m_max,
            ),
            Feature("log_nis", 0.0, 10.0, "-", "log(1 + NIS / rows used)"),
            Feature("rows_used", 0.0, 1.0, "-", "measurement rows used / 5"),
            Feature("log_sigma_pos", -3.0, 3.0, "log10 m", "log10 sqrt(P_NN + P_EE)"),
            Feature("log_sigma_heading", -5.0, 1.0, "log10 rad", "log10 sqrt(P_phiphi)"),
            Feature("time_since_fix", 0.0, 10.0, "min", "time since the last GNSS position fix / 60 s"),
        ]

    def _cov_features(self, P: np.ndarray) -> dict[str, np.ndarray]:
        d = np.maximum(np.diagonal(P, axis1=1, axis2=2), 1e-300)
        return {
            "log_sigma_pos": 0.5 * np.log10(d[:, 0] + d[:, 1]),
            "log_sigma_heading": 0.5 * np.log10(d[:, 2]),
        }

    def initial_feature_values(self, belief: GaussianState, ep: Robot2dEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        cols = {
            "innovation": np.zeros((B, self.m_max)),
            "log_nis": np.zeros(B),
            "rows_used": np.zeros(B),
            "time_since_fix": np.zeros(B),
        }
        cols.update(self._cov_features(belief.P))
        return cols

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: Robot2dEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        S_diag = np.maximum(np.diagonal(info.S, axis1=1, axis2=2), 1e-12)
        n_used = np.maximum(info.n_meas, 1)
        rows = np.arange(t.shape[0])
        cols = {
            "innovation": np.where(models.mask, info.innovation / np.sqrt(S_diag), 0.0),
            "log_nis": np.log1p(np.maximum(info.nis, 0.0) / n_used),
            "rows_used": info.n_meas / self.m_max,
            "time_since_fix": ep.fix_age[rows, np.minimum(t, ep.fix_age.shape[1] - 1)] / 60.0,
        }
        cols.update(self._cov_features(belief.P))
        return cols


def standard_uniform_batch(rngs: Sequence[np.random.Generator], shape: tuple[int, ...]) -> np.ndarray:
    """Stack ``rng.random(shape)`` over the episodes: ``(B,) + shape`` (one draw per episode)."""
    out = np.empty((len(rngs), *shape))
    for i, rng in enumerate(rngs):
        out[i] = rng.random(shape)
    return out


__all__ = [
    "Robot2dPlatform",
    "Robot2dEpisodes",
    "OdometryTransition",
    "FixCompassModel",
    "control_jacobian",
    "make_platform",
    "Robot2dEnv",
    "Robot2dVectorEnv",
]


# ---------------------------------------------------------------------------------------------
# Environments
# ---------------------------------------------------------------------------------------------
from navgym.envs.base import NavEnv, NavVectorEnv  # noqa: E402
from navgym.envs.factory import build_core  # noqa: E402
from navgym.envs.registration import fill_card  # noqa: E402

#: Scenario defaults per task (episodes last 60 s): the degradations that make the knob matter.
TASK_SCENARIOS: dict[str, dict[str, Any]] = {
    "fading": {
        "outage_probability": 0.6,
        "outage_duration": (5.0, 25.0),
        "jamming_probability": 0.3,
        "jamming_duration": (5.0, 20.0),
    },
    "mixture": {
        "outage_probability": 0.2,
        "outage_duration": (5.0, 20.0),
        "impulsive_probability": 0.8,
        "impulsive_eps": (0.05, 0.3),
        "impulsive_duration": (10.0, 40.0),
    },
    "resample": {"outage_probability": 0.5, "outage_duration": (5.0, 25.0)},
}
SCENARIO_KWARGS = (
    "outage_probability",
    "outage_count",
    "outage_duration",
    "partial_probability",
    "partial_satellites",
    "partial_duration",
    "impulsive_probability",
    "impulsive_eps",
    "impulsive_var_ratio",
    "impulsive_duration",
    "jamming_probability",
    "jamming_sigma",
    "jamming_loss",
    "jamming_duration",
    "start_margin",
)
#: Sensor keyword arguments and the :class:`RobotSensorNoise` field they set.
SENSOR_KWARGS = {
    "sigma_gps": "gps",
    "sigma_glonass": "glonass",
    "sigma_compass_deg": "compass_deg",
    "sigma_encoder": "encoder",
    "sigma_steering_deg": "steering_deg",
}
#: Default largest fading factor, per second of filtering: ``lambda_max = 3.16 ** dt`` = 1.122 per
#: 0.1 s step. Ten per step at 10 Hz (GpsInsFading's 10 at 1 Hz) would inflate P by 1e10 per
#: second: a sustained a = 1 makes P ~ 1e17 m^2 within 2 s of outage, where the duplicated
#: GPS/GLONASS rows make S numerically singular. At 3.16 per second, P stays below ~1e12 m^2
#: through the longest default outage (25 s).
LAMBDA_MAX_PER_SECOND = 10.0**0.5
#: Platform keyword arguments passed through as they are.
PLATFORM_KWARGS = ("encoder_scale_sigma", "slip_sigma", "yaw_sigma")


def make_platform(task: str, kwargs: dict[str, Any], steps: int) -> Robot2dPlatform:
    """A :class:`Robot2dPlatform` from the env keyword arguments it owns (popped from ``kwargs``)."""
    if task not in TASK_SCENARIOS:
        raise ValueError(f"task must be one of {sorted(TASK_SCENARIOS)}; got {task!r}")
    dt = 0.1
    scen = dict(TASK_SCENARIOS[task])
    scen.update({k: kwargs.pop(k) for k in SCENARIO_KWARGS if k in kwargs})
    scen["duration"] = steps * dt
    scen.setdefault("start_margin", min(10.0, 0.1 * steps * dt))
    sensors = RobotSensorNoise(**{f: float(kwargs.pop(k)) for k, f in SENSOR_KWARGS.items() if k in kwargs})
    extra = {k: float(kwargs.pop(k)) for k in PLATFORM_KWARGS if k in kwargs}
    return Robot2dPlatform(
        dt=dt,
        sensors=sensors,
        robot=RobotParams(duration=max(steps * dt, 1.0)),
        scenarios=ScenarioDistribution(**scen),
        error_scale_m=float(kwargs.pop("error_scale_m", 2.0)),
        divergence_m=float(kwargs.pop("divergence_m", 200.0)),
        **extra,
    )


def _core(task: str, num_envs: int, kwargs: dict[str, Any]):
    kwargs = dict(kwargs)
    steps = int(kwargs.pop("episode_steps", 600))
    if steps < 1:
        raise ValueError(f"episode_steps must be >= 1; got {steps}")
    platform = make_platform(task, kwargs, steps)
    if task == "fading":
        kwargs.setdefault("lambda_max", LAMBDA_MAX_PER_SECOND**platform.dt)
    return build_core(platform, task, num_envs, kwargs, steps)


class Robot2dEnv(NavEnv):
    """Seed 001's car-like robot (eq. 77), with an agent steering its navigation filter.

    ## Description
    A car-like robot (seed 001 §2.7b-c, Benzerrouk 2014; kinematics eq. 77, geometry of the
    Victoria Park car of Guivant & Nebot 2001) drives piecewise-constant speed (0.5-3 m/s) and
    steering (+-25 deg) commands. A three-state filter ``x = [x_N, y_E, phi]`` (north/east
    position of the tracked point L [m], heading from north [rad]) predicts with the exact
    discrete eq. 77 driven by the rear-right wheel encoder (the seed's "back left" in its
    mirrored frame, :mod:`navgym.robot2d.robot`) and the steering sensor (held over the
    step; process noise from their noise plus unmodelled motion), and updates with GPS
    fixes at 10 Hz, GLONASS fixes at 5 Hz and an electronic compass at 5 Hz (the rates of
    seed 001). Sensor noise (assumed; seed 001 gives none): GPS 3 m and GLONASS 5 m per axis,
    compass 2 deg, encoder 0.05 m/s, steering 0.5 deg. The truth carries what the filter does
    not model: an encoder scale error ``N(0, 2 %)`` per episode (wheel radius) and commands
    changing inside a step, the model error a fading factor is for. Episodes bring GNSS outages,
    jamming (extra fix noise ``jam_sigma`` per axis and lost fixes), impulsive noise on the fixes
    (seed 001 eq. 71: with probability ``eps`` a fix's variance is multiplied by ``var_ratio``)
    and partial outages (fewer than 4 satellites: no fix), drawn from a seeded scenario
    distribution; the compass is not GNSS and never degrades. The agent controls the filter, not
    the robot: the fading factor (``Robot2dFading``), the outlier weight of a Gaussian-sum filter
    (``Robot2dMixture``) or a particle filter's resampling (``Robot2dResample``).

    ## Action Space
    ``Fading``: ``Box(-1, 1, (1,), float32)``, ``lambda = lambda_max ** ((a + 1) / 2)`` applied as
    ``P- = lambda F P F^T + Q`` at every 0.1 s step (``a = -1``: the plain filter); ``lambda_max``
    defaults to ``10 ** 0.05 = 1.122`` (up to 3.16-fold per second, see ``LAMBDA_MAX_PER_SECOND``;
    ten per step at 10 Hz would make P numerically singular within seconds of an outage).
    ``Mixture``: ``Box(-1, 1, (1,))``, ``eps = eps_max (a + 1) / 2``, noise ``(1 - eps) N(0, R) +
    eps N(0, variance_ratio R)`` on the four GNSS rows (GPS and GLONASS N/E); the compass row
    keeps ``N(0, R)``.
    ``Resample``: ``Discrete(2)``, 1 = resample the particles now. Non-finite actions raise
    ``ValueError``; Box actions outside [-1, 1] are clipped and counted in ``info["action_clipped"]``.

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter and the sensors (innovations, covariances, rows used, fix age, the previous
    action); no truth. ``time_since_gnss`` counts only the GNSS rows (a compass reading does not
    reset it), so it equals ``time_since_fix``.

    {observation_table}

    ## Rewards
    ``r = -min(pos_err_m / error_scale_m, reward_clip) - resample_cost * resampled``, with
    ``error_scale_m = 2`` m and ``reward_clip = 10``: 0 is perfect, -1 is a 2 m horizontal error.
    The terms are in ``info["reward_terms"]``. Divergence (see Episode End) ends the episode
    with an extra ``-divergence_penalty = -100``.

    ## Starting State
    The robot starts at the origin of its local north/east frame with a uniform heading. The
    filter starts from the first GPS fix and compass reading, ``P0 = diag(3 m, 3 m, 2 deg)^2``.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 600 steps of 0.1 s = 60 s) or at the
    simulated horizon ``episode_steps`` (600). Termination on divergence: the filter's health
    flag is False, the horizontal error exceeds ``divergence_m = 200`` m (a hundred times the
    scale and far beyond any outage drift of a 60 s episode), or the filter's horizontal sigma
    ``sqrt(tr P_ne)`` exceeds ``SIGMA_DIVERGENCE x divergence_m``
    (``navgym.envs.core.SIGMA_DIVERGENCE = {SIGMA_DIVERGENCE}``: a runaway covariance, e.g.
    extreme fading through an outage, ended before it overflows, however small the error).
    ``episode_steps`` sets the simulated episode (truth, scenario timing); ``max_episode_steps``
    only cuts it short, so a single env and a vector env built with the same keyword arguments
    simulate the same episodes.

    ## Arguments
    ``gym.make("navgym/Robot2dFading-v0", filter="ekf", lambda_max=1.122, max_episode_steps=600,
    episode_steps=600, sigma_gps=3.0, sigma_glonass=5.0, sigma_compass_deg=2.0, sigma_encoder=0.05,
    sigma_steering_deg=0.5, encoder_scale_sigma=0.02, slip_sigma=0.3, yaw_sigma=0.02,
    outage_probability=..., outage_count=(lo, hi), outage_duration=(lo, hi),
    partial_probability=..., partial_satellites=(lo, hi), partial_duration=(lo, hi),
    impulsive_probability=..., impulsive_eps=(lo, hi), impulsive_var_ratio=(lo, hi),
    impulsive_duration=(lo, hi), jamming_probability=..., jamming_sigma=(lo, hi),
    jamming_loss=(lo, hi), jamming_duration=(lo, hi), start_margin=6.0, error_scale_m=2.0,
    divergence_m=200.0, reward_clip=10.0, divergence_penalty=100.0, eval_info=True,
    render_mode=None)``. Durations in seconds. Task defaults: ``Fading`` outages 0.6 (5-25 s),
    jamming 0.3 (5-20 s); ``Mixture`` outages 0.2 (5-20 s), impulsive 0.8 (eps 0.05-0.3,
    10-40 s), and takes ``filter="ckf"``, ``eps_max=0.5``, ``variance_ratio=100``; ``Resample``
    outages 0.5 (5-25 s), and takes ``n_particles=1000``, ``resample_cost=0.05``,
    ``method="systematic"``, ``roughening=0.0`` (v1: 0.2), ``log_ess_feature=False`` (v1:
    True), ``particle_dtype="float32"`` (the cloud's precision; weights and moments stay float64).
    Every env takes ``penalize_remaining_steps=False`` (v1: True): the divergence penalty
    becomes ``divergence_penalty + reward_clip x steps not played`` (of the simulated
    ``episode_steps``, also where ``max_episode_steps`` truncates earlier: a single env cannot see
    gym.make's ``TimeLimit``, and single and vector envs give the same reward). ``slip_sigma`` [m/s] and
    ``yaw_sigma`` [rad/s] are the filter's unmodelled-motion noise (scale error, commands
    changing inside a step); ``sigma_*`` set both the simulated sensors and the filter's ``R``
    and control noise. ``reset(options={"scenario":
    navgym.scenarios.Scenario(...)})`` pins a scenario.

    ## Version History
    {version_history}
    """

    def __init__(self, task: str = "fading", render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(_core(task, 1, kwargs), render_mode=render_mode)


class Robot2dVectorEnv(NavVectorEnv):
    """Native batched Robot2d environment (see :class:`Robot2dEnv` for the card)."""

    def __init__(self, num_envs: int = 1, task: str = "fading", **kwargs: Any) -> None:
        kwargs.pop("render_mode", None)
        super().__init__(_core(task, num_envs, kwargs))


def _card() -> None:
    """Fill the card's observation tables (every registered id) and its version history."""
    Robot2dEnv.__doc__ = fill_card(Robot2dEnv.__doc__, __name__, _core, resample=True)


_card()
