"""The GpsIns estimation problem: truth and sensors of B episodes, what the filter sees.

See :mod:`navgym.gps_ins.models` for the filter models and :mod:`navgym.gps_ins.env` for the card.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import ClassVar, NamedTuple

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
from navgym.envs.protocols import PositionError, StepModels
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
from navgym.gps_ins.models import PseudorangeModel
from navgym.gps_ins.vehicle import LAND_VEHICLE, SHIP, sample_vehicle_plans, vehicle_trajectory
from navgym.ins.error_model import (
    InsErrorParams,
    gps_ins_process_noise,
    gps_ins_transition,
    ins_error_initial_covariance,
    ins_indicated_position,
    simulate_ins_errors,
)
from navgym.motion.trajectory import trajectory_heading
from navgym.scenarios import (
    Scenario,
    ScenarioDistribution,
    critical_scenario,
    default_rngs,
    gnss_available,
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


@dataclass(frozen=True)
class GpsInsPlatform(PlatformBase):
    """Carvalho et al. 1997's GPS/INS estimation problem (see the module docstring and the env card)."""

    #: Fields of :class:`GpsInsEpisodes` that :meth:`step_models` advances (see the protocol).
    episode_cursors: ClassVar[tuple[str, ...]] = ("noise_ptr",)

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
    #: Simulate the GNSS epoch with the compiled kernel (:mod:`navgym.gps_ins.epoch_kernel`);
    #: False runs the NumPy reference path (the same measurements to rounding).
    compiled: bool = True

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
        clock, truth, noise regime, availability: 265 bytes a step) three times over for the
        simulation's temporaries (its measured peak is 2.3 times), 4 bytes a step per outage
        slot of the scenario distribution, and the buffered noise of ``NOISE_BLOCK`` steps.
        """
        steps = int(T) + 1
        stored = steps * (8 * (1 + 6 + 5 * 3 + 2 + 2 + 6 + 1) + 1)
        slots = steps * 4 * max(1, self.scenarios.outage_count[1])
        return 3 * stored + slots + 2 * NOISE_BLOCK * 3 * self.m_max * 8

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
        heading = trajectory_heading(traj)
        ins_err = _simulate_ins(heading, dt, self.ins, true_limit, g_ins)
        lat_i, lon_i = ins_indicated_position(traj.lat, traj.lon, ins_err, traj.h)
        p_ins = geodetic_to_ecef(lat_i, lon_i, traj.h)
        north, east = north_east_axes(lat_i, lon_i)
        rx = geodetic_to_ecef(traj.lat, traj.lon, traj.h)
        clock = _simulate_clock(g_clock, T, dt)
        batch = stack_scenarios(list(scenarios))
        tt = np.broadcast_to(times, (B, T + 1))
        gnss_ok = gnss_available(batch, tt)
        row_cap = satellite_row_mask(batch, tt, self.m_max).sum(axis=-1)
        reg = noise_regime(batch, tt)
        regime = np.stack(
            [reg.eps, reg.var_ratio, reg.jam_sigma, reg.loss_prob, reg.outlier_prob, reg.outlier_scale], -1
        )
        prns = reg.outlier_prns.any(axis=1)
        mask_deg = np.array([s.mask_deg for s in scenarios], dtype=np.float64)
        sin_mask = np.sin(np.deg2rad(mask_deg))  # the ranking compares sin(el)|sin(el)| with it
        k = 3 * self.m_max
        noise_n = np.empty((B, NOISE_BLOCK, k))
        noise_u = np.empty((B, NOISE_BLOCK, k))
        for i in range(B):
            _fill_noise(gens[i], noise_n[i], noise_u[i])
        return GpsInsEpisodes(
            gps_t0,
            heading,
            ins_err,
            p_ins,
            east,
            north,
            rx,
            up_axis(traj.lat, traj.lon),
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
        z, mask, sat, rho0_sq, A, W, c0 = pseudorange_epoch(
            *found,
            cache.step,
            k,
            ep,
            self.almanac.prn,
            self.sigma_pr,
            min(self.m_max, self.almanac.prn.shape[0]),
            goad_goodman_coefficients(),
            TROPO_NOISE_FRACTION,
        )
        np.add(ep.noise_ptr, 1, out=ep.noise_ptr)
        obs = PseudorangeModel(rho0_sq, A, W, c0, self._R)
        return self._step_models(ep, t, obs, z, mask, sat)

    def _step_models(self, ep, t, obs, z, mask, sat) -> StepModels:
        """The step's :class:`StepModels`: transition of step ``t``, epoch ``t + 1``'s model."""
        rows, k = np.arange(t.shape[0]), t + 1
        trans = LinearTransition(gps_ins_transition(ep.heading[rows, t], self.dt, self.ins.K), self._Q)
        geometry = (ep.p_ins[rows, k], ep.east[rows, k], ep.north[rows, k], sat)
        return StepModels(trans, obs, z, mask, self.dt, geometry)

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
            sigma=self.sigma_pr,
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
        return self._step_models(ep, t, obs, np.where(mask, meas.pseudorange, np.nan), mask, sat)

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
        cov_ne = P[:, [1, 0]][:, :, [1, 0]]
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
        ]  # fmt: skip

    def initial_feature_values(self, belief: GaussianState, ep: GpsInsEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        return {
            **innovation_initial_values(B, self.m_max, "satellites"),
            "log_gdop": np.full(B, 3.0),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
        }

    def feature_values(self, belief, info, models: StepModels, ep, t) -> dict[str, np.ndarray]:
        p_ins, east, north, sat = models.aux
        p_est = models.observation.position(belief.m, p_ins, east, north)
        g = gdop(p_est, sat, models.mask)
        return {
            **innovation_values(info, models.mask, self.m_max, "satellites"),
            "log_gdop": np.log10(np.where(np.isfinite(g), np.maximum(g, 1.0), 1e3)),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
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
    """Evaluate plans of regular and critical episodes and interleave them in batch order."""
    parts = {}
    if plans is not None:
        parts[False] = vehicle_trajectory(plans, times, imu=False)
    if plans_c is not None:
        parts[True] = vehicle_trajectory(plans_c, times, imu=False)
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
