"""The GpsIns estimation problem: the platform that the env core steps.

:class:`GpsInsPlatform` is Carvalho et al. 1997's GPS/INS problem as a
:class:`~navgym.envs.protocols.Platform`: its episodes are simulated at reset by
:mod:`navgym.gps_ins.episodes` (truth, sensors and the v2 events), each step builds the filter's
transition and the pseudo-range epoch's observation model (:meth:`GpsInsPlatform.step_models`:
compiled by :mod:`navgym.gps_ins.epoch_kernel`, or in NumPy), and the observation's
platform-specific features are in :mod:`navgym.gps_ins.features`. See
:mod:`navgym.gps_ins.models` for the filter models and :mod:`navgym.gps_ins.env` for the card.
The names of those modules that other code uses are re-exported here.

With ``true_noise=True`` (the v2 ids) the episodes also keep the process noise the v2 events add
(:mod:`navgym.gps_ins.episodes`), and :meth:`GpsInsPlatform.step_models` hands the step's truth
to the evaluation as ``StepModels.truth`` (:class:`~navgym.envs.protocols.TrueNoise`) in the
filter's row order: the true ``Q`` (the nominal one plus the episodes' ``true_q``; the clock
block nominal: the simulator's exact discretization of eq. 11 differs from the filter's Euler
step by less than 1e-6 of it), ``R`` diagonal with each row's variance as drawn
(``(sigma_pr noise_scale)^2`` times the impulsive ratio where the row is contaminated, plus the
jamming, multipath and troposphere-model (5 % of the delay) variances) and the bias per row
(multipath, plus the gross error of an outlier satellite where one was drawn). Rows not used
hold the nominal variance and bias 0. With ``context=True`` (v3, :mod:`navgym.gps_ins.context`)
each row's variance is the DLL law at its C/N0 (times the impulsive ratio) plus the
troposphere model's, and the true ``Q``'s nominal part is the simulation's (without the v3
filter's velocity random walk, ``VELOCITY_WALK``).

With ``bias_features=True`` (the v2 ids) the observation also carries the filter's own
accelerometer-bias and clock-drift estimates and their rates (:data:`BIAS_FEATURES`).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from filters import GaussianState, LinearTransition
from navgym.envs.features import (
    Feature,
    covariance_values,
    innovation_features,
    innovation_initial_values,
    innovation_values,
)
from navgym.envs.platform import PlatformBase
from navgym.envs.protocols import PositionError, StepModels, TrueNoise
from navgym.geo import C_LIGHT
from navgym.gnss import ClockState, gdop, make_regime, simulate_gnss_step
from navgym.gnss.clock import DEFAULT_CLOCK
from navgym.gnss.orbit_cache import default_orbit_cache
from navgym.gnss.receiver_report import check_cn0_offset
from navgym.gnss.signal_quality import reported_cn0_dbhz
from navgym.gnss.troposphere import TROPO_NOISE_FRACTION, goad_goodman_coefficients
from navgym.gps_ins import context as ctx
from navgym.gps_ins.episodes import (
    MULTIPATH_SLOTS,
    NOISE_BLOCK,
    REGIME_COLUMNS,
    GpsInsEpisodes,
    next_noise,
    refill_noise,
    simulate_episodes,
)
from navgym.gps_ins.features import (
    BIAS_BOUNDS,
    BIAS_FEATURES,
    BIAS_SCALES,
    BIAS_STATES,
    COVARIANCE_BLOCKS,
    bias_values,
)
from navgym.gps_ins.gdop_kernel import gdop as compiled_gdop
from navgym.gps_ins.models import PseudorangeModel
from navgym.ins.error_model import (
    InsErrorParams,
    gps_ins_process_noise,
    gps_ins_transition,
    ins_error_initial_covariance,
)
from navgym.scenarios import Scenario, ScenarioDistribution, critical_scenario

#: The names of :mod:`navgym.gps_ins.episodes` and :mod:`navgym.gps_ins.features` are re-exported.
__all__ = [
    "BIAS_BOUNDS",
    "BIAS_FEATURES",
    "BIAS_SCALES",
    "COVARIANCE_BLOCKS",
    "MULTIPATH_SLOTS",
    "NOISE_BLOCK",
    "REGIME_COLUMNS",
    "SIGMA_PR_M",
    "GpsInsEpisodes",
    "GpsInsPlatform",
]

#: Pseudo-range noise of the nominal regime [m] (also the filter's sigma).
SIGMA_PR_M = 5.0
#: The v3 filter's velocity random walk [m/s/sqrt(s)] (``context=True`` only; see ``GpsInsPlatform._Q``).
VELOCITY_WALK = 0.002


class SatelliteGeometry(NamedTuple):
    """The estimator-side geometry of an epoch, the features' input (``StepModels.context``)."""

    p_ins: np.ndarray  #: (B, 3) the INS position of the epoch (ECEF) [m]
    east: np.ndarray  #: (B, 3) the local east unit vector (ECEF)
    north: np.ndarray  #: (B, 3) the local north unit vector (ECEF)
    sat: np.ndarray  #: (B, m, 3) satellite positions of the rows (ECEF) [m]
    #: (B, m_max) the receiver's reported C/N0 of the rows received [dB-Hz] (0 elsewhere; v3 only)
    cn0_reported: np.ndarray | None = None


@dataclass(frozen=True)
class GpsInsPlatform(PlatformBase):
    """Carvalho et al. 1997's GPS/INS estimation problem (see the module docstring and the env card)."""

    vehicle: str = "land"
    dt: float = 1.0
    m_max: int = 12
    sigma_pr: float = SIGMA_PR_M
    ins: InsErrorParams = field(default_factory=InsErrorParams)
    scenarios: ScenarioDistribution = field(default_factory=ScenarioDistribution)
    critical: bool = False
    true_bias_limit_ug: tuple[float, float] | None = None
    start_spread_s: float = 2 * 86400.0
    error_scale_m: float = 10.0
    divergence_m: float = 2000.0
    name: str = "GpsIns"
    n: int = 8
    #: Simulate the GNSS epoch with the compiled kernel (:mod:`navgym.gps_ins.epoch_kernel`)
    #: and observe the GDOP by :mod:`navgym.gps_ins.gdop_kernel` (the same values bit for bit);
    #: False runs the NumPy reference paths (the same measurements to rounding).
    compiled: bool = True
    #: Keep the noise the simulator used and hand it out as ``StepModels.truth`` (the v2 ids; see
    #: the module docstring). False: ``truth`` is None and nothing extra is stored.
    true_noise: bool = False
    #: Observe the filter's bias estimates and their rates (the v2 ids; :data:`BIAS_BOUNDS`).
    bias_features: bool = False
    #: The v3 context (:mod:`navgym.gps_ins.context`): each pseudo-range row's noise follows its
    #: C/N0 (elevation, satellite offset, NLOS and canyon losses, the jammer's J/S), the IMU
    #: senses the manoeuvre bursts, and the observation gains ``row_cn0``, ``row_elevation``,
    #: ``row_reported_sigma`` and the IMU statistics. False (v0-v2): nothing of it is drawn.
    context: bool = False
    #: Calibration offset [dB] of the receiver's C/N0 report (another receiver model;
    #: :func:`navgym.gnss.receiver_report.check_cn0_offset`): ``row_cn0`` and
    #: ``row_reported_sigma`` follow it, the true C/N0 and the rows' noise do not. Needs ``context``.
    cn0_offset_db: float = 0.0

    @property
    def process_noise_states(self) -> tuple[int, ...]:
        """The velocity-error states ``de_lambda, de_phi`` (indices 2, 3).

        The layout is :mod:`navgym.gps_ins.models`' eight-state error vector; the motion
        bursts' unmodelled INS velocity error enters there, so a process-noise scale knob
        (RowScale's ``s_q``) acts on them only.
        """
        return (2, 3)

    @property
    def episode_cursors(self) -> tuple[str, ...]:  # type: ignore[override]
        return ("noise_ptr", "bias_est") if self.bias_features else ("noise_ptr",)

    def __post_init__(self) -> None:
        if self.vehicle not in ("land", "ship"):
            raise ValueError(f"vehicle must be 'land' or 'ship'; got {self.vehicle!r}")
        if not self.dt > 0:
            raise ValueError(f"dt must be > 0; got {self.dt}")
        if not 4 <= int(self.m_max) <= 16:
            raise ValueError(f"m_max must lie in [4, 16]; got {self.m_max}")
        if not self.sigma_pr > 0:
            raise ValueError(f"sigma_pr must be > 0; got {self.sigma_pr}")
        check_cn0_offset(self.cn0_offset_db, self.context)
        self.check_reward_scales()

    # --------------------------------------------------------------------------------- setup
    def episode_bytes(self, T: int) -> int:
        """Bytes of one episode of ``T`` steps at reset (see the Platform protocol).

        The per-step arrays of :class:`GpsInsEpisodes` (heading, INS errors, five ECEF vectors,
        clock, truth, noise regime, availability: 273 bytes a step) three times over for the
        simulation's temporaries (its measured peak is 2.3 times), 4 bytes a step per outage
        slot of the scenario distribution, and the buffered noise of ``NOISE_BLOCK`` steps;
        with ``true_noise`` the 4 process-noise variances a step, and 4 bytes a step per slot of
        the v2 events (bursts, canyons, more jamming; none without them).
        """
        steps = int(T) + 1
        stored = steps * (8 * (1 + 6 + 5 * 3 + 2 + 2 + 7 + 1) + 1)
        if self.true_noise:
            stored += steps * 8 * 4
        sc = self.scenarios
        slots = 4 * max(1, sc.outage_count[1]) + 4 * (sc.jamming_count[1] - 1)
        slots += 4 * sc.burst_count[1] * (sc.burst_probability > 0) + 4 * sc.canyon_count[1] * (
            sc.canyon_probability > 0
        )
        if self.context:  # canyon loss, J/S, fading and estimator normals per row, IMU statistics
            stored += steps * 8 * (2 + 2 * self.m_max + 4) + 8 * (self.almanac.prn.shape[0] + MULTIPATH_SLOTS)
            slots += 8 * 6 * int(round(ctx.IMU_RATE_HZ * ctx.IMU_WINDOW_S * self.dt))  # the IMU's samples
        return 3 * stored + steps * slots + 2 * NOISE_BLOCK * 3 * self.m_max * 8

    @property
    def almanac(self):
        return default_orbit_cache().almanac

    def sample_scenario(self, rng: np.random.Generator) -> Scenario:
        """One scenario: the distribution's, or Carvalho et al. 1997's fixed critical scenario."""
        return critical_scenario() if self.critical else self.scenarios.sample(rng)

    def sample_scenarios(self, rngs: Sequence[np.random.Generator]) -> list[Scenario]:
        if self.critical:
            return [critical_scenario() for _ in rngs]
        return super().sample_scenarios(rngs)

    @functools.cached_property
    def _R(self) -> np.ndarray:
        """Pseudo-range noise covariance ``sigma^2 I`` of the filter (computed once, read-only)."""
        R = self.sigma_pr**2 * np.eye(self.m_max)
        R.flags.writeable = False  # shared by every step's model
        return R

    @functools.cached_property
    def _Q_sim(self) -> np.ndarray:
        """Process noise the simulation draws between events (the truth's nominal part; read-only)."""
        Q = gps_ins_process_noise(self.dt, self.ins.sigma_x, self.ins.sigma_y, DEFAULT_CLOCK.sigma_w)
        c = np.diag([1.0] * 6 + [C_LIGHT, C_LIGHT])
        Q = c @ Q @ c
        Q.flags.writeable = False  # shared by every step's model
        return Q

    @functools.cached_property
    def _Q(self) -> np.ndarray:
        """The filter's process noise of the eight-state model in the state's units (read-only).

        Carvalho et al. 1997's model (:attr:`_Q_sim`) has no velocity process noise, so a scale
        of the velocity states (RowScale's ``s_q`` on :attr:`process_noise_states`) would act on
        zeros; with the context (v3) the filter adds a velocity random walk of
        :data:`VELOCITY_WALK` (``q_v = VELOCITY_WALK^2 dt`` per velocity state, negligible against
        the 5 m pseudo-ranges), which ``s_q`` up to 1e4 raises to 0.2 m/s per step: the v2
        manoeuvres' range. Without the context: :attr:`_Q_sim` itself.
        """
        if not self.context:
            return self._Q_sim
        Q = self._Q_sim.copy()
        Q[[2, 3], [2, 3]] += VELOCITY_WALK**2 * self.dt
        Q.flags.writeable = False
        return Q

    def _P0(self) -> np.ndarray:
        P = np.zeros((8, 8))
        P[:6, :6] = ins_error_initial_covariance(self.ins)
        P[6, 6] = (C_LIGHT * DEFAULT_CLOCK.bias0_std) ** 2
        P[7, 7] = (C_LIGHT * DEFAULT_CLOCK.drift0_std) ** 2
        return P

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> GpsInsEpisodes:
        """B episodes of ``T`` steps (:func:`navgym.gps_ins.episodes.simulate_episodes`)."""
        return simulate_episodes(self, rngs, scenarios, T)

    def initial_belief(self, ep: GpsInsEpisodes) -> GaussianState:
        B = ep.gps_t0.shape[0]
        return GaussianState(np.zeros((B, 8)), np.broadcast_to(self._P0(), (B, 8, 8)).copy())

    # ---------------------------------------------------------------------------------- step
    def step_models(self, ep: GpsInsEpisodes, t: np.ndarray) -> StepModels[SatelliteGeometry]:
        """The transition of step ``t`` and the pseudo-range epoch ``t + 1`` with its model.

        Compiled (:mod:`navgym.gps_ins.epoch_kernel`) unless ``compiled=False`` or an episode's
        time lies outside the orbit table; then :meth:`step_models_reference` (NumPy).
        """
        k = t + 1  # measurement epoch
        cache = default_orbit_cache()
        found = cache.interval_coefficients(ep.gps_t0 + k * self.dt, ep.orbit) if self.compiled else None
        if found is None:
            return self.step_models_reference(ep, t)
        from navgym.gps_ins.epoch_kernel import pseudorange_epoch  # numba: on first use

        refill_noise(ep)
        z, mask, sat, rho0_sq, A, W, c0, true_var, true_bias, cn0 = pseudorange_epoch(
            *found,
            cache.step,
            k,
            ep,
            self.almanac.prn,
            self.sigma_pr,
            min(self.m_max, self.almanac.prn.shape[0]),
            goad_goodman_coefficients(),
            TROPO_NOISE_FRACTION,
            self.dt,
            ep.context,
        )
        np.add(ep.noise_ptr, 1, out=ep.noise_ptr)
        obs = PseudorangeModel(rho0_sq, A, W, c0, self._R)
        return self._step_models(ep, t, obs, z, mask, sat, true_var, true_bias, cn0)

    def _step_models(
        self, ep, t, obs, z, mask, sat, true_var, true_bias, cn0=None
    ) -> StepModels[SatelliteGeometry]:
        """The step's :class:`StepModels`: transition of step ``t``, epoch ``t + 1``'s model.

        With ``true_noise`` its ``truth`` (the module docstring): the nominal ``Q`` plus the
        episodes' ``true_q``, ``R = diag(true_var)`` and ``true_bias`` on the rows used (the
        nominal variance and 0 elsewhere). With the context, the rows' true C/N0 ``cn0 (B, m)``
        plus the report's calibration offset ``cn0_offset_db`` becomes the receiver's report
        (:func:`~navgym.gnss.signal_quality.reported_cn0_dbhz` with the episodes' estimator
        normals) on the rows received, 0 elsewhere.
        """
        rows, k = np.arange(t.shape[0]), t + 1
        trans = LinearTransition(gps_ins_transition(ep.heading[rows, t], self.dt, self.ins.K), self._Q)
        reported = None
        if cn0 is not None:
            B, m = mask.shape
            est = ep.context.est[rows, k, :m]
            reported = np.zeros((B, self.m_max))
            rep = reported_cn0_dbhz(
                cn0 + self.cn0_offset_db, est, ctx.CN0_ESTIMATOR_DB, ctx.CN0_RESOLUTION_DB
            )
            reported[:, :m] = np.where(mask, rep, 0.0)
        geometry = SatelliteGeometry(ep.p_ins[rows, k], ep.east[rows, k], ep.north[rows, k], sat, reported)
        truth = None
        if self.true_noise and ep.true_q is not None:
            B, m = mask.shape
            Q = np.broadcast_to(self._Q_sim, (B, 8, 8)).copy()
            Q[:, [2, 3, 4, 5], [2, 3, 4, 5]] += ep.true_q[rows, t]
            R = np.zeros((B, self.m_max, self.m_max))
            R[:, np.arange(m), np.arange(m)] = np.where(mask, true_var, self.sigma_pr**2)
            bias = np.zeros((B, self.m_max))
            bias[:, :m] = np.where(mask, true_bias, 0.0)
            truth = TrueNoise(Q, R, bias)
        return StepModels(trans, obs, z, mask, self.dt, geometry, truth=truth)

    def step_models_reference(self, ep: GpsInsEpisodes, t: np.ndarray) -> StepModels[SatelliteGeometry]:
        """:meth:`step_models` in NumPy (the reference the compiled epoch is tested against).

        :func:`~navgym.gnss.simulate_gnss_step` and :meth:`PseudorangeModel.build`.
        """
        B = t.shape[0]
        rows = np.arange(B)
        k = t + 1  # measurement epoch
        normals, uniforms = next_noise(ep)
        reg = ep.regime[rows, k]
        regime = make_regime(
            B,
            sigma=self.sigma_pr * reg[:, 6],  # the canyon's factor (1 outside: sigma_pr exactly)
            eps=reg[:, 0],
            var_ratio=reg[:, 1],
            jam_sigma=reg[:, 2],
            loss_prob=reg[:, 3],
            outlier_prob=reg[:, 4],
            outlier_scale=reg[:, 5],
            outlier_prns=ep.outlier_prns,
        )
        clk = ep.clock[rows, k]
        meas = simulate_gnss_step(
            self.almanac,
            ep.gps_t0 + k * self.dt,
            ep.rx_ecef[rows, k],
            np.zeros((B, 3)),  # the receiver velocity enters the delta-ranges only (not simulated)
            ClockState(clk[:, 0], clk[:, 1]),
            regime,
            normals,
            uniforms,
            mask_deg=ep.mask_deg,
            m_max=self.m_max,
            orbit=default_orbit_cache().lookup(ep.gps_t0 + k * self.dt, ep.orbit),
            delta_range=False,  # the filter uses pseudo-ranges only
        )
        mask = (
            meas.mask & (np.arange(self.m_max) < ep.row_cap[rows, k][:, None]) & ep.gnss_ok[rows, k][:, None]
        )
        noise = meas.noise
        pr = meas.pseudorange
        # multipath of each row's satellite (navgym.gps_ins.episodes): bias and variance added
        tk = (k * self.dt)[:, None, None]
        on = (ep.mp_start[:, None, :] <= tk) & (tk < ep.mp_end[:, None, :])
        on = on & (ep.mp_sat[:, None, :] == meas.sat_index[:, :, None])  # (B, m, L)
        mpb = np.where(on, ep.mp_bias[:, None, :], 0.0).sum(axis=2)
        mpv = np.where(on, ep.mp_var[:, None, :], 0.0).sum(axis=2)
        m = pr.shape[1]
        var = noise.std**2
        u_out = uniforms[:, 2 * self.m_max : 2 * self.m_max + m]
        sign = np.where(u_out < 0.5 * reg[:, 4:5], 1.0, -1.0)
        gross = np.where(noise.outlier, sign * reg[:, 5:6], 0.0)
        cn0 = None
        if ep.context is not None:  # v3: every row's variance from its C/N0 (the compiled law)
            c = ep.context
            loss = np.where(on, c.seg_loss_db[:, None, :], 0.0).sum(axis=2)
            loss = loss + c.canyon_loss_db[rows, k][:, None]
            cn0, var = ctx.row_cn0_and_variance(
                meas.sin_elevation,
                np.take_along_axis(c.sat_offset_db, meas.sat_index, axis=1),
                loss,
                c.fade_db[rows, k, :m],
                c.jam_lin[rows, k][:, None],
                self.sigma_pr,
            )
            var = np.where(uniforms[:, :m] < reg[:, 0:1], var * reg[:, 1:2], var)
            pr = pr - noise.pseudorange + np.sqrt(var) * normals[:, :m] + gross + mpb
        elif on.any():
            hit = on.any(axis=2)
            var = np.where(hit, var + mpv, var)
            e_new = np.sqrt(var) * normals[:, :m] + gross + mpb
            pr = np.where(hit, pr - noise.pseudorange + e_new, pr)
        true_var = var + (TROPO_NOISE_FRACTION * meas.troposphere) ** 2
        true_bias = gross + mpb
        p_ins = ep.p_ins[rows, k]
        # Light time from the INS point, on component slabs (3, B, m) of the satellite states.
        s_c, v_c = np.moveaxis(meas.sat_pos, -1, 0), np.moveaxis(meas.sat_vel, -1, 0)
        d = [s_c[i] - p_ins[:, i : i + 1] for i in range(3)]
        tau = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) / C_LIGHT
        sat = np.moveaxis(s_c - v_c * tau, 0, -1)  # (B, m, 3) view of component slabs
        obs = PseudorangeModel.build(
            p_ins,
            ep.east[rows, k],
            ep.north[rows, k],
            sat,
            meas.troposphere,
            self._R,
        )
        return self._step_models(ep, t, obs, np.where(mask, pr, np.nan), mask, sat, true_var, true_bias, cn0)

    def position_error(
        self, mean: np.ndarray, ep: GpsInsEpisodes, t: np.ndarray, P: np.ndarray
    ) -> PositionError:
        rows = np.arange(t.shape[0])
        e = ep.ins_err[rows, t]
        clk = ep.clock[rows, t]
        x_true = np.concatenate([e, C_LIGHT * clk], axis=1)
        de = mean[:, :2] - e[:, :2]  # estimated minus true INS error (east, north)
        truth = ep.truth_ne[rows, t]
        # corrected position p_INS - e_hat (eq. 14) minus truth p_INS - e is e - e_hat = -de
        est = truth - np.stack([de[:, 1], de[:, 0]], axis=1)
        cov_ne = np.ascontiguousarray(P[:, 1::-1, 1::-1])  # rows/columns (north, east): a copy
        return PositionError(np.hypot(de[:, 0], de[:, 1]), truth, est, cov_ne, mean - x_true)

    # ------------------------------------------------------------------------------ features
    def features(self) -> list[Feature]:
        return [
            *innovation_features(
                self.m_max, "pseudo-range innovations / sqrt(S_ii), 0 where masked", "satellites",
                rows="satellites used", unit_rows="satellites used / m_max",
            ),
            Feature("log_gdop", 0.0, 3.0, "-", "log10 GDOP at the estimate (3 when < 4 satellites)"),
            *(b.feature for b in COVARIANCE_BLOCKS),
            *(BIAS_FEATURES if self.bias_features else ()),
            *(ctx.context_features(self.m_max) if self.context else ()),
        ]  # fmt: skip

    def initial_feature_values(self, belief: GaussianState, ep: GpsInsEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        return {
            **innovation_initial_values(B, self.m_max, "satellites"),
            "log_gdop": np.full(B, 3.0),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
            **(bias_values(belief.m, belief.m, self.dt) if self.bias_features else {}),
            **(self._initial_context_values(ep) if ep.context is not None else {}),
        }

    def _initial_context_values(self, ep: GpsInsEpisodes) -> dict[str, np.ndarray]:
        """The context features before the first epoch: no rows received, the IMU's epoch 0 (zeros)."""
        B = ep.gps_t0.shape[0]
        zero = np.zeros((B, self.m_max))
        rows = {"row_cn0": zero, "row_elevation": zero, "row_reported_sigma": zero}
        return {**rows, **ctx.imu_feature_values(ep.context.imu[:, 0])}

    def _context_values(self, models: StepModels[SatelliteGeometry], p_est: np.ndarray, ep, t) -> dict:
        """The context features of epoch ``t + 1`` (receiver side and IMU; the card says which).

        The elevation is the receiver's, from its estimated position ``p_est`` and the
        satellites: ``asin(u . (s - p) / |s - p|)`` with ``u = E x N`` the local up.
        """
        geo = models.context
        B, m = models.mask.shape
        up = np.cross(geo.east, geo.north)
        d = geo.sat - p_est[:, None, :]
        sin_el = np.einsum("bmi,bi->bm", d, up) / np.linalg.norm(d, axis=-1)
        el = np.zeros((B, self.m_max))
        el[:, :m] = np.where(models.mask, np.degrees(np.arcsin(np.clip(sin_el, -1.0, 1.0))), 0.0)
        rep = geo.cn0_reported
        sig = np.where(rep > 0, ctx.pseudorange_sigma_m(np.where(rep > 0, rep, 45.0), self.sigma_pr), 0.0)
        k = np.minimum(t + 1, ep.context.imu.shape[1] - 1)
        return {
            "row_cn0": rep,
            "row_elevation": el,
            "row_reported_sigma": sig,
            **ctx.imu_feature_values(ep.context.imu[np.arange(B), k]),
        }

    def feature_values(
        self, belief, info, models: StepModels[SatelliteGeometry], ep, t
    ) -> dict[str, np.ndarray]:
        p_ins, east, north, sat = models.context[:4]
        p_est = models.observation.position(belief.m, p_ins, east, north)
        # the compiled GDOP (navgym.gps_ins.gdop_kernel: gnss.visibility.gdop's numbers, bit for bit)
        g = compiled_gdop(p_est, sat, models.mask) if self.compiled else gdop(p_est, sat, models.mask)
        out = {
            **innovation_values(info, models.mask, self.m_max, "satellites"),
            "log_gdop": np.log10(np.where(np.isfinite(g), np.maximum(g, 1.0), 1e3)),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
        }
        if self.bias_features:  # the estimates after the previous step are the episodes' cursor
            out.update(bias_values(belief.m, ep.bias_est, self.dt))
            ep.bias_est[...] = belief.m[:, BIAS_STATES]
        if ep.context is not None:
            out.update(self._context_values(models, p_est, ep, t))
        return out
