"""The GpsIns estimation problem: truth and sensors of B episodes, what the filter sees.

See :mod:`navgym.gps_ins.models` for the filter models and :mod:`navgym.gps_ins.env` for the card.

The v2 events of a scenario (:mod:`navgym.scenarios.scenario`) act on the truth and the sensors
while the filter's ``Q`` and ``R`` stay nominal (episodes without them simulate bit for bit as
before, and nothing more is drawn for them):

* a motion burst is an unmodelled manoeuvre: every step ``k -> k + 1`` that starts inside it adds
  a white velocity error ``w_k ~ N(0, (velocity_sigma dt)^2 I_2)`` to the INS velocity errors
  (east, north), i.e. an unmodelled horizontal acceleration of ``velocity_sigma`` read in m/s^2
  held over the step (IMU scale-factor and misalignment errors excited by the manoeuvre,
  vibration); ``de_{k+1} = (1 - K dt) de_k + dt M(Theta_k) a_k + w_k``, the position errors
  integrate it from the next step on. That is eq. 13's step plus ``w_k``, so the step's true
  process noise is the nominal ``Q`` plus ``(velocity_sigma dt)^2`` on the two velocity states
  (``yaw_rate_sigma`` is not used: the heading is known, Carvalho et al. 1997, §IV-D);
* a multipath/NLOS segment is tied to a satellite: its ``row`` is an elevation rank (0 the
  highest, the measurement rows' order) resolved once, at the segment's first epoch, to the
  satellite on that row seen from the true position (the lowest visible one where fewer
  satellites are visible; none where none is), and from then on that satellite's pseudo-range
  carries the ``bias`` (either sign) plus noise of ``sigma`` on whatever row it is ranked, while
  it is tracked (low ranks, ``multipath_rows`` = (6, ..., 11) in the v2 defaults, mean low
  elevation); segments on one satellite add;
* an urban canyon caps the satellites (the highest ``max_satellites`` stay), multiplies the
  nominal pseudo-range sigma (both mixture components) by ``noise_scale`` and loses each
  pseudo-range with ``loss_prob`` (combined with a jammer's loss as independent causes);
* a jamming ramp scales the jamming noise and loss (:func:`navgym.scenarios.noise_regime`);
  several outages are ``outage_count``.

With ``true_noise=True`` (the v2 ids) the episodes also keep the process noise the bursts add
(and the bias walk of a true IMU other than the filter's, ``true_bias_limit_ug``), and
:meth:`GpsInsPlatform.step_models` hands the step's truth to the evaluation as
``StepModels.truth`` (:class:`~navgym.envs.protocols.TrueNoise`) in the filter's row order: the
true ``Q`` above (the clock block nominal: the simulator's exact discretization of eq. 11
differs from the filter's Euler step by less than 1e-6 of it), ``R`` diagonal with each row's
variance as drawn (``(sigma_pr noise_scale)^2`` times the impulsive ratio where the row is
contaminated, plus the jamming, multipath and troposphere-model (5 % of the delay) variances)
and the bias per row (multipath, plus the gross error of an outlier satellite where one was
drawn). Rows not used hold the nominal variance and bias 0.

With ``bias_features=True`` (the v2 ids) the observation also carries the filter's own
accelerometer-bias and clock-drift estimates and their rates (:data:`BIAS_FEATURES`).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from scipy.signal import lfilter

from filters import GaussianState, LinearTransition
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
from navgym.geo import C_LIGHT, geodetic_to_ecef, north_east_axes
from navgym.geo.frames import up_axis
from navgym.gnss import (
    ClockState,
    default_critical_window,
    gdop,
    make_regime,
    simulate_gnss_step,
)
from navgym.gnss.clock import DEFAULT_CLOCK, clock_transition
from navgym.gnss.orbit_cache import OrbitBuffer, default_orbit_cache
from navgym.gnss.troposphere import TROPO_NOISE_FRACTION, goad_goodman_coefficients
from navgym.gnss.visibility import rank_satellites
from navgym.gps_ins.gdop_kernel import gdop as compiled_gdop
from navgym.gps_ins.models import PseudorangeModel
from navgym.gps_ins.vehicle import LAND_VEHICLE, SHIP, sample_vehicle_plans, vehicle_track
from navgym.ins.error_model import (
    InsErrorParams,
    gps_ins_process_noise,
    gps_ins_transition,
    ins_error_initial_covariance,
    ins_indicated_position,
    simulate_ins_errors,
)
from navgym.ins.imu_grades import G0
from navgym.scenarios import (
    Scenario,
    ScenarioBatch,
    ScenarioDistribution,
    canyon_regime,
    critical_scenario,
    default_rngs,
    gnss_available,
    motion_burst,
    noise_regime,
    satellite_row_mask,
    stack_scenarios,
)

#: Steps of per-episode noise drawn at a time (one Python loop over episodes per block).
NOISE_BLOCK = 64
#: Pseudo-range noise of the nominal regime [m] (also the filter's sigma).
SIGMA_PR_M = 5.0
#: Log-sigma features of the filter's covariance.
COVARIANCE_BLOCKS = (
    CovarianceBlock("log_sigma_pos", (0, 1), -2.0, 5.0, "log10 m", "log10 sqrt(P_ee + P_nn)"),
    CovarianceBlock(
        "log_sigma_vel", (2, 3), -4.0, 2.0, "log10 m/s", "log10 sqrt of the velocity-error variances"
    ),
    CovarianceBlock("log_sigma_bias", (4, 5), -8.0, 0.0, "log10 m/s^2", "log10 sqrt of the bias variances"),
    CovarianceBlock("log_sigma_clock", (6,), -2.0, 6.0, "log10 m", "log10 sqrt(P_bb)"),
)
#: Multipath segments an episode holds at most (fixed, so that episodes of any scenario swap
#: into a batch; a pinned scenario with more raises). The v2 defaults draw up to 5.
MULTIPATH_SLOTS = 8
#: Columns of :attr:`GpsInsEpisodes.regime`: the noise regime of :func:`navgym.gnss.make_regime`
#: and the canyon's factor on the nominal pseudo-range sigma (1 outside canyons).
REGIME_COLUMNS = (
    "eps",
    "var_ratio",
    "jam_sigma",
    "loss_prob",
    "outlier_prob",
    "outlier_scale",
    "noise_scale",
)
#: The bias features of ``bias_features=True`` (v2): the filter's own estimates of the states
#: that are biases (x, y accelerometer biases, clock drift) and their rates, per bound.
#: Accelerometer bias [mg] within +-1 mg (100 times the navigation-grade limit of 10 ug: an
#: estimate beyond it is clipped), its rate [mg/s] within +-0.1; clock drift [m/s] within +-5
#: (c times the drift's prior sigma 1e-9 is 0.3 m/s), its rate [m/s^2] within +-0.5.
BIAS_SCALES = {
    "accel_bias": 1e-3 * G0,
    "accel_bias_rate": 1e-3 * G0,
    "clock_drift": 1.0,
    "clock_drift_rate": 1.0,
}
BIAS_BOUNDS = {"accel_bias": 1.0, "accel_bias_rate": 0.1, "clock_drift": 5.0, "clock_drift_rate": 0.5}


class GpsInsEpisodes(NamedTuple):
    """Precomputed truth and sensor inputs of B episodes (episode axis first, ``T + 1`` times)."""

    gps_t0: np.ndarray  # (B,) GPS seconds at t = 0
    heading: np.ndarray  # (B, T+1) known heading [rad]
    ins_err: np.ndarray  # (B, T+1, 6) true INS errors (evaluation only)
    p_ins: np.ndarray  # (B, T+1, 3) INS-indicated ECEF position [m]
    east: np.ndarray  # (B, T+1, 3) local east unit vector at the INS point
    north: np.ndarray  # (B, T+1, 3)
    rx_ecef: np.ndarray  # (B, T+1, 3) true receiver position (simulation only)
    up: np.ndarray  # (B, T+1, 3) ellipsoid normal at the true position (simulation only)
    clock: np.ndarray  # (B, T+1, 2) true clock bias [s], drift [s/s]
    truth_ne: np.ndarray  # (B, T+1, 2) true north/east offset from the start [m]
    mask_deg: np.ndarray  # (B,)
    mask_score: np.ndarray  # (B,) sin(mask)|sin(mask)|: the visibility threshold of the ranking score
    gnss_ok: np.ndarray  # (B, T+1) no full outage
    row_cap: np.ndarray  # (B, T+1) usable satellites at most
    regime: np.ndarray  # (B, T+1, 6) eps, var_ratio, jam_sigma, loss_prob, outlier_prob, outlier_scale
    outlier_prns: np.ndarray  # (B, 33) union of faulty PRNs of the episode
    noise_n: np.ndarray  # (B, NOISE_BLOCK, 3 m) buffered standard normals
    noise_u: np.ndarray  # (B, NOISE_BLOCK, 3 m) buffered uniforms
    noise_ptr: np.ndarray  # (B,) next buffered step
    gens: np.ndarray  # (B,) object: per-episode noise generator
    orbit: OrbitBuffer  # per-episode orbit coefficients of the current grid interval (a cache)
    #: (B, MULTIPATH_SLOTS) multipath segments: start, end [s] (inf: unused), satellite index
    #: into the almanac (-1: none), bias [m], variance [m^2] (truth: simulation only)
    mp_start: np.ndarray | None = None
    mp_end: np.ndarray | None = None
    mp_sat: np.ndarray | None = None
    mp_bias: np.ndarray | None = None
    mp_var: np.ndarray | None = None
    #: (B, T+1, 4) process-noise variance the events add to the velocity and bias states (2-5)
    #: in step k -> k + 1 (truth only; None unless ``true_noise``)
    true_q: np.ndarray | None = None
    #: (B, 3) the filter's bias estimates after the last step (x, y accelerometer [m/s^2], clock
    #: drift [m/s]), for their rates (``bias_features``; estimator side, a cursor)
    bias_est: np.ndarray | None = None


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
    def _Q(self) -> np.ndarray:
        """Process noise of the eight-state model in the state's units (computed once, read-only)."""
        Q = gps_ins_process_noise(self.dt, self.ins.sigma_x, self.ins.sigma_y, DEFAULT_CLOCK.sigma_w)
        c = np.diag([1.0] * 6 + [C_LIGHT, C_LIGHT])
        Q = c @ Q @ c
        Q.flags.writeable = False  # shared by every step's model
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
        B = len(rngs)
        dt = self.dt
        times = np.arange(T + 1) * dt
        crit = np.array([s.critical for s in scenarios])
        window = default_critical_window(self.almanac) if crit.any() else None
        base = LAND_VEHICLE if self.vehicle == "land" else SHIP
        base = replace(base, duration=max(float(T * dt), 60.0))
        # One child generator per episode and purpose keeps the draw order fixed per episode.
        seeds = np.array([r.integers(0, 2**63 - 1, size=4) for r in rngs])
        g_plan = default_rngs(seeds[:, 0])
        g_ins = default_rngs(seeds[:, 1])
        g_clock = default_rngs(seeds[:, 2])
        gens = np.empty(B, dtype=object)
        for i, g in enumerate(default_rngs(seeds[:, 3])):
            gens[i] = g
        t_start = np.array([r.uniform(-self.start_spread_s, self.start_spread_s) for r in rngs])
        if self.true_bias_limit_ug is not None:  # model mismatch: the true IMU is drawn per episode
            lo, hi = np.log(self.true_bias_limit_ug[0]), np.log(self.true_bias_limit_ug[1])
            true_limit = np.exp(np.array([r.uniform(lo, hi) for r in rngs])) * 1e-6 * 9.80665
        else:
            true_limit = np.full(B, self.ins.bias_limit)
        gps_t0 = float(self.almanac.t_ref[0]) + t_start
        if crit.any():
            ship = replace(
                SHIP,
                duration=base.duration,
                origin_lat_deg=(np.degrees(window.lat),) * 2,
                origin_lon_deg=(np.degrees(window.lon),) * 2,
                origin_h=(window.h, window.h),
            )
            plans_c = sample_vehicle_plans([g_plan[i] for i in np.flatnonzero(crit)], ship)
            gps_t0[crit] = window.t0
        plans = (
            sample_vehicle_plans([g_plan[i] for i in np.flatnonzero(~crit)], base) if (~crit).any() else None
        )
        traj = _merge_trajectories(plans, plans_c if crit.any() else None, crit, times)
        heading = traj.heading
        ins_err = _simulate_ins(heading, dt, self.ins, true_limit, g_ins)
        batch = stack_scenarios(list(scenarios))
        tt = np.broadcast_to(times, (B, T + 1))
        burst_var = None
        if np.isfinite(batch.burst_start).any():  # unmodelled manoeuvres: the INS errors grow
            ins_err, burst_var = _manoeuvre(ins_err, batch, tt, seeds[:, 1], dt, self.ins.K)
        lat_i, lon_i = ins_indicated_position(traj.lat, traj.lon, ins_err, traj.h)
        p_ins = geodetic_to_ecef(lat_i, lon_i, traj.h)
        north, east = north_east_axes(lat_i, lon_i)
        rx = traj.ecef  # geodetic_to_ecef(traj.lat, traj.lon, traj.h)
        clock = _simulate_clock(g_clock, T, dt)
        gnss_ok = gnss_available(batch, tt)
        row_cap = satellite_row_mask(batch, tt, self.m_max).sum(axis=-1)
        reg = noise_regime(batch, tt)
        loss, scale = reg.loss_prob, np.ones((B, T + 1))
        if np.isfinite(batch.canyon_start).any():  # jamming and blockage lose a satellite independently
            scale, c_loss = canyon_regime(batch, tt)
            loss = loss + c_loss - loss * c_loss
        regime = np.stack(
            [reg.eps, reg.var_ratio, reg.jam_sigma, loss, reg.outlier_prob, reg.outlier_scale, scale], -1
        )
        prns = reg.outlier_prns.any(axis=1)
        mask_deg = np.array([s.mask_deg for s in scenarios], dtype=np.float64)
        sin_mask = np.sin(np.deg2rad(mask_deg))  # the ranking compares sin(el)|sin(el)| with it
        k = 3 * self.m_max
        noise_n = np.empty((B, NOISE_BLOCK, k))
        noise_u = np.empty((B, NOISE_BLOCK, k))
        for i in range(B):
            _fill_noise(gens[i], noise_n[i], noise_u[i])
        up = up_axis(traj.lat, traj.lon)
        mp = _multipath_segments(batch, self.m_max, dt, rx, up, gps_t0, sin_mask * np.abs(sin_mask))
        truth = {}
        if self.true_noise:
            q = np.zeros((B, T + 1, 4))
            if burst_var is not None:
                q[..., 0:2] = burst_var[..., None]
            k = true_limit / self.ins.bias_limit  # a true IMU of another grade walks k times as fast
            q[..., 2] = ((k**2 - 1.0) * self.ins.sigma_x**2 * dt)[:, None]
            q[..., 3] = ((k**2 - 1.0) * self.ins.sigma_y**2 * dt)[:, None]
            truth["true_q"] = q
        if self.bias_features:
            truth["bias_est"] = np.zeros((B, 3))
        return GpsInsEpisodes(
            gps_t0,
            heading,
            ins_err,
            p_ins,
            east,
            north,
            rx,
            up,
            clock,
            traj.position_ned[..., :2],
            mask_deg,
            sin_mask * np.abs(sin_mask),
            gnss_ok,
            row_cap,
            regime,
            prns,
            noise_n,
            noise_u,
            np.zeros(B, dtype=np.int64),
            gens,
            default_orbit_cache().new_buffer(B),
            *mp,
            **truth,
        )

    def initial_belief(self, ep: GpsInsEpisodes) -> GaussianState:
        B = ep.gps_t0.shape[0]
        return GaussianState(np.zeros((B, 8)), np.broadcast_to(self._P0(), (B, 8, 8)).copy())

    # ---------------------------------------------------------------------------------- step
    def _refill_noise(self, ep: GpsInsEpisodes) -> None:
        for i in np.flatnonzero(ep.noise_ptr >= NOISE_BLOCK):  # once per NOISE_BLOCK steps
            _fill_noise(ep.gens[i], ep.noise_n[i], ep.noise_u[i])
            ep.noise_ptr[i] = 0

    def _noise(self, ep: GpsInsEpisodes) -> tuple[np.ndarray, np.ndarray]:
        B = ep.noise_ptr.shape[0]
        self._refill_noise(ep)
        rows = np.arange(B)
        n, u = ep.noise_n[rows, ep.noise_ptr], ep.noise_u[rows, ep.noise_ptr]
        np.add(ep.noise_ptr, 1, out=ep.noise_ptr)
        return n, u

    def step_models(self, ep: GpsInsEpisodes, t: np.ndarray) -> StepModels:
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

        self._refill_noise(ep)
        z, mask, sat, rho0_sq, A, W, c0, true_var, true_bias = pseudorange_epoch(
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
        )
        np.add(ep.noise_ptr, 1, out=ep.noise_ptr)
        obs = PseudorangeModel(rho0_sq, A, W, c0, self._R)
        return self._step_models(ep, t, obs, z, mask, sat, true_var, true_bias)

    def _step_models(self, ep, t, obs, z, mask, sat, true_var, true_bias) -> StepModels:
        """The step's :class:`StepModels`: transition of step ``t``, epoch ``t + 1``'s model.

        With ``true_noise`` its ``truth`` (the module docstring): the nominal ``Q`` plus the
        episodes' ``true_q``, ``R = diag(true_var)`` and ``true_bias`` on the rows used (the
        nominal variance and 0 elsewhere).
        """
        rows, k = np.arange(t.shape[0]), t + 1
        trans = LinearTransition(gps_ins_transition(ep.heading[rows, t], self.dt, self.ins.K), self._Q)
        geometry = (ep.p_ins[rows, k], ep.east[rows, k], ep.north[rows, k], sat)
        truth = None
        if self.true_noise and ep.true_q is not None:
            B, m = mask.shape
            Q = np.broadcast_to(self._Q, (B, 8, 8)).copy()
            Q[:, [2, 3, 4, 5], [2, 3, 4, 5]] += ep.true_q[rows, t]
            R = np.zeros((B, self.m_max, self.m_max))
            R[:, np.arange(m), np.arange(m)] = np.where(mask, true_var, self.sigma_pr**2)
            bias = np.zeros((B, self.m_max))
            bias[:, :m] = np.where(mask, true_bias, 0.0)
            truth = TrueNoise(Q, R, bias)
        return StepModels(trans, obs, z, mask, self.dt, geometry, truth=truth)

    def step_models_reference(self, ep: GpsInsEpisodes, t: np.ndarray) -> StepModels:
        """:meth:`step_models` in NumPy (the reference the compiled epoch is tested against).

        :func:`~navgym.gnss.simulate_gnss_step` and :meth:`PseudorangeModel.build`.
        """
        B = t.shape[0]
        rows = np.arange(B)
        k = t + 1  # measurement epoch
        normals, uniforms = self._noise(ep)
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
        # multipath of each row's satellite (module docstring): bias and variance added
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
        if on.any():
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
        return self._step_models(ep, t, obs, np.where(mask, pr, np.nan), mask, sat, true_var, true_bias)

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
        ]  # fmt: skip

    def initial_feature_values(self, belief: GaussianState, ep: GpsInsEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        return {
            **innovation_initial_values(B, self.m_max, "satellites"),
            "log_gdop": np.full(B, 3.0),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
            **(_bias_values(belief.m, belief.m, self.dt) if self.bias_features else {}),
        }

    def feature_values(self, belief, info, models: StepModels, ep, t) -> dict[str, np.ndarray]:
        p_ins, east, north, sat = models.aux
        p_est = models.observation.position(belief.m, p_ins, east, north)
        # the compiled GDOP (navgym.gps_ins.gdop_kernel: gnss.visibility.gdop's numbers, bit for bit)
        g = compiled_gdop(p_est, sat, models.mask) if self.compiled else gdop(p_est, sat, models.mask)
        out = {
            **innovation_values(info, models.mask, self.m_max, "satellites"),
            "log_gdop": np.log10(np.where(np.isfinite(g), np.maximum(g, 1.0), 1e3)),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
        }
        if self.bias_features:  # the estimates after the previous step are the episodes' cursor
            out.update(_bias_values(belief.m, ep.bias_est, self.dt))
            ep.bias_est[...] = belief.m[:, _BIAS_STATES]
        return out


def _manoeuvre(
    ins_err: np.ndarray, batch: ScenarioBatch, tt: np.ndarray, seeds: np.ndarray, dt: float, K: float
) -> tuple[np.ndarray, np.ndarray]:
    """INS errors under the scenario's motion bursts, and the velocity variance they add per step.

    Every step ``k -> k + 1`` that starts inside a burst adds ``w_k ~ N(0, (velocity_sigma dt)^2
    I_2)`` to the velocity errors (the module docstring): by linearity the nominal errors plus
    ``dv_{k+1} = (1 - K dt) dv_k + w_k``, ``dp_{k+1} = dp_k + dt dv_k`` from ``dv_0 = dp_0 = 0``.
    The normals come from ``default_rng([seed, 1])`` of each episode's INS seed, drawn only for
    episodes with a burst; the others keep ``ins_err`` exactly.

    Returns:
        The errors ``(B, T+1, 6)`` and ``(B, T+1)`` variances ``(velocity_sigma dt)^2`` of step k -> k + 1.
    """
    B, n = tt.shape
    v_sig, _ = motion_burst(batch, tt)
    var = (v_sig * dt) ** 2
    has = np.isfinite(batch.burst_start).any(axis=1)
    out = ins_err.copy()
    for i in np.flatnonzero(has):
        w = np.random.default_rng([int(seeds[i]), 1]).standard_normal((n, 2)) * (v_sig[i, :, None] * dt)
        x = np.zeros((n, 2))
        x[1:] = w[:-1]
        dv = lfilter([1.0], [1.0, -(1.0 - K * dt)], x, axis=0)
        dp = np.zeros((n, 2))
        dp[1:] = dt * np.cumsum(dv[:-1], axis=0)
        out[i, :, 0:2] += dp
        out[i, :, 2:4] += dv
    return out, var


def _multipath_segments(
    batch: ScenarioBatch,
    m_max: int,
    dt: float,
    rx: np.ndarray,
    up: np.ndarray,
    gps_t0: np.ndarray,
    threshold: np.ndarray,
) -> tuple[np.ndarray, ...]:
    """The multipath segments of B episodes as :data:`MULTIPATH_SLOTS` slots, tied to satellites.

    A segment's ``row`` (an elevation rank) is resolved at its first epoch ``k = ceil(start /
    dt)`` to the satellite ranked there from the true position (the ranking of
    :func:`navgym.gnss.simulate_gnss_step`: ``sin(el)|sin(el)|`` above the mask, highest first),
    or the lowest visible one where fewer are visible; -1 where none is or the segment starts
    after the last epoch.

    Returns:
        ``(start, end, sat, bias, var)``, each ``(B, MULTIPATH_SLOTS)``.
    """
    B, n = rx.shape[:2]
    K = MULTIPATH_SLOTS
    start = np.full((B, K), np.inf)
    end = np.full((B, K), np.inf)
    sat = np.full((B, K), -1, dtype=np.int64)
    bias = np.zeros((B, K))
    var = np.zeros((B, K))
    used = np.isfinite(batch.multipath_start)
    if not used.any():
        return start, end, sat, bias, var
    if used.sum(axis=1).max() > K:
        raise ValueError(
            f"an episode has {int(used.sum(axis=1).max())} multipath segments; GpsIns holds at most {K}"
        )
    b_idx, j_idx = np.nonzero(used)
    slot = np.cumsum(used, axis=1)[b_idx, j_idx] - 1
    s0 = batch.multipath_start[b_idx, j_idx]
    start[b_idx, slot] = s0
    end[b_idx, slot] = batch.multipath_end[b_idx, j_idx]
    bias[b_idx, slot] = batch.multipath_bias[b_idx, j_idx]
    var[b_idx, slot] = batch.multipath_sigma[b_idx, j_idx] ** 2
    k = np.ceil(s0 / dt - 1e-9).astype(np.int64)
    ok = k < n
    kk = np.minimum(k, n - 1)
    orbit = default_orbit_cache().lookup(gps_t0[b_idx] + kk * dt)
    pos = orbit.position  # (N, S, 3)
    r = rx[b_idx, kk][:, None, :]
    d = pos - r
    su = (d * up[b_idx, kk][:, None, :]).sum(axis=-1)
    score = su * np.abs(su) / (d * d).sum(axis=-1)
    order, vis = rank_satellites(score, threshold[b_idx][:, None], m_max)
    n_vis = vis.sum(axis=1)
    row = np.minimum(batch.multipath_row[b_idx, j_idx], n_vis - 1)
    chosen = np.take_along_axis(order, np.maximum(row, 0)[:, None], axis=1)[:, 0]
    sat[b_idx, slot] = np.where(ok & (n_vis > 0), chosen, -1)
    return start, end, sat, bias, var


#: States published by ``bias_features``: x, y accelerometer biases [m/s^2], clock drift [m/s].
_BIAS_STATES = [4, 5, 7]
#: The bias features (``bias_features=True``): the filter's estimates and their change over the
#: last step, scaled and bounded as :data:`BIAS_SCALES` and :data:`BIAS_BOUNDS` say (values beyond
#: are clipped).
BIAS_FEATURES = (
    Feature("accel_bias", -BIAS_BOUNDS["accel_bias"], BIAS_BOUNDS["accel_bias"], "mg",
            "the filter's x, y accelerometer-bias estimates (along / across the heading)", 2),
    Feature("accel_bias_rate", -BIAS_BOUNDS["accel_bias_rate"], BIAS_BOUNDS["accel_bias_rate"], "mg/s",
            "change of the accelerometer-bias estimates over the last step / dt", 2),
    Feature("clock_drift", -BIAS_BOUNDS["clock_drift"], BIAS_BOUNDS["clock_drift"], "m/s",
            "the filter's clock-drift estimate (c times the drift)"),
    Feature("clock_drift_rate", -BIAS_BOUNDS["clock_drift_rate"], BIAS_BOUNDS["clock_drift_rate"], "m/s^2",
            "change of the clock-drift estimate over the last step / dt"),
)  # fmt: skip


def _bias_values(m: np.ndarray, previous: np.ndarray, dt: float) -> dict[str, np.ndarray]:
    """The bias features of the filter's means ``m (B, 8)`` and the previous estimates ``(B, 3)``.

    ``previous`` is ``m`` itself at reset (``(B, 8)``: rates 0).
    """
    now = m[:, _BIAS_STATES]
    before = previous[:, _BIAS_STATES] if previous.shape[1] == m.shape[1] else previous
    rate = (now - before) / dt
    values = {
        "accel_bias": now[:, 0:2],
        "accel_bias_rate": rate[:, 0:2],
        "clock_drift": now[:, 2],
        "clock_drift_rate": rate[:, 2],
    }
    return {
        k: np.clip(np.nan_to_num(v / BIAS_SCALES[k]), -BIAS_BOUNDS[k], BIAS_BOUNDS[k])
        for k, v in values.items()
    }


def _fill_noise(gen: np.random.Generator, normals: np.ndarray, uniforms: np.ndarray) -> None:
    """One block of an episode's normals then uniforms, drawn straight into its buffers."""
    gen.standard_normal(out=normals)
    gen.random(out=uniforms)


def _simulate_ins(heading, dt, ins: InsErrorParams, true_limit: np.ndarray, rngs) -> np.ndarray:
    """True INS errors; with a per-episode bias limit differing from the filter's (mismatch).

    The error model is linear in the bias-walk scale, so an episode whose true IMU has bias limit
    ``L`` is the nominal simulation with the biases (limit, walk and initial sigma) scaled by
    ``L / L_nominal``; the initial position and velocity errors keep the filter's prior.
    """
    if np.all(true_limit == ins.bias_limit):
        return simulate_ins_errors(heading, dt, ins, rngs)
    return simulate_ins_errors(heading, dt, ins, rngs, bias_limit=true_limit)


def _simulate_clock(rngs: Sequence[np.random.Generator], T: int, dt: float) -> np.ndarray:
    """Receiver clock bias [s] and drift [s/s] (Carvalho et al. 1997, eq. 11), ``(B, T + 1, 2)``.

    ``x_{k+1} = Phi x_k + w_k`` with ``Phi = [[1, c], [0, phi]]`` (:func:`clock_transition`),
    solved along time for the whole batch: the drift is the first-order recursion
    ``d_{k+1} = phi d_k + w1_k`` (``scipy.signal.lfilter``), the bias the running sum
    ``b_{k+1} = (b_k + c d_k) + w0_k`` in that order (``np.add.accumulate``). A loop over the
    T steps cost 0.8 ms per reset whatever B, the fixed cost of resetting a few episodes.
    """
    z = np.stack([r.standard_normal((T + 1, 2)) for r in rngs])
    Phi, Q = clock_transition(dt, DEFAULT_CLOCK.a, DEFAULT_CLOCK.sigma_w)
    L = np.linalg.cholesky(Q + 1e-300 * np.eye(2)) if np.any(Q) else np.zeros((2, 2))
    B = z.shape[0]
    b0 = DEFAULT_CLOCK.bias0_std * z[:, 0, 0]
    d0 = DEFAULT_CLOCK.drift0_std * z[:, 0, 1]
    w = z[:, 1:] @ L.T
    c, phi = Phi[0, 1], Phi[1, 1]
    x = np.empty_like(z)
    x[:, 0, 1] = d0
    x[:, 1:, 1] = lfilter([1.0], [1.0, -phi], w[:, :, 1], axis=1, zi=(phi * d0)[:, None])[0]
    terms = np.empty((B, 2 * T + 1))  # b0, c d0, w0_0, c d1, w0_1, ...
    terms[:, 0] = b0
    terms[:, 1::2] = c * x[:, :-1, 1]
    terms[:, 2::2] = w[:, :, 0]
    x[:, :, 0] = np.add.accumulate(terms, axis=1)[:, ::2]
    return x


def _merge_trajectories(plans, plans_c, crit: np.ndarray, times: np.ndarray):
    """Evaluate plans of regular and critical episodes and interleave them in batch order.

    The :class:`~navgym.gps_ins.vehicle.VehicleTrack` of the plans (``vehicle_trajectory``'s
    position and heading, and the ECEF position, without what the episodes do not use).
    """
    parts = {}
    if plans is not None:
        parts[False] = vehicle_track(plans, times)
    if plans_c is not None:
        parts[True] = vehicle_track(plans_c, times)
    if len(parts) == 1:
        return next(iter(parts.values()))
    out = []
    for fa, fb in zip(parts[False], parts[True], strict=True):
        if fa is None:  # a field not computed (imu=False)
            out.append(None)
            continue
        shape = (crit.shape[0], *fa.shape[1:])
        arr = np.empty(shape, dtype=fa.dtype)
        arr[~crit] = fa
        arr[crit] = fb
        out.append(arr)
    return type(parts[False])(*out)
