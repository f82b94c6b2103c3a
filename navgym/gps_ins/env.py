"""GpsIns: seed 000's tightly coupled GPS/INS error filter on a land vehicle or ship.

The filter state is seed 000's eight-state error vector (eq. 13)::

    x = [e_lambda, e_phi, de_lambda, de_phi, a_x, a_y, b, d]

INS position errors east/north [m], their rates [m/s], horizontal accelerometer biases
[m/s^2], receiver clock bias b = c delta [m] and drift d = c d(delta)/dt [m/s] (seed 000 eq. 11
scaled by c for conditioning). Dynamics: :func:`navgym.ins.gps_ins_transition` with the known
heading. Measurements: pseudo-ranges (seed 000 eq. 10 and 15) of up to ``m_max`` satellites of
the real almanac at 1 Hz; the observation predicted from the INS-indicated position corrected by
the error state (eq. 14)::

    h_i(x) = |s_i' - (p_INS - e_lambda E - e_phi N)| + Sagnac + b + T_i

with ``s_i'`` the satellite moved back by the light time, ``E``, ``N`` the local east/north unit
vectors and ``T_i`` the modelled troposphere. It is nonlinear in x, so the filter choice matters.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, NamedTuple

import numpy as np
from scipy.signal import lfilter

from filters import GaussianState, LinearTransition
from filters.core.layout import is_component_major
from navgym.envs.features import Feature
from navgym.envs.protocols import StepModels
from navgym.envs.registration import fill_card
from navgym.geo import C_LIGHT, OMEGA_E, geodetic_to_ecef, north_east_axes
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


class PseudorangeModel(NamedTuple):
    """Observation model of the error state (module docstring), batched over B episodes.

    With ``d0 = s' - p_INS`` and ``delta = e_lambda E + e_phi N`` the corrected position is
    ``p = p_INS - delta`` and, exactly,
    ``|s' - p|^2 = |d0|^2 + 2 d0 . delta + |delta|^2`` with ``|delta|^2 = e_lambda^2 + e_phi^2``
    (E, N orthonormal); the Sagnac term ``(w_e / c)(s_x p_y - s_y p_x)`` is affine in delta. So
    ``h`` needs one ``(.., 2) @ (2, m)`` product per episode, whatever the number of sigma points
    or particles, and no cancellation (``d0`` is formed once in float64).
    """

    rho0_sq: np.ndarray  # (B, m) |d0|^2
    A: np.ndarray  # (B, 2, m) rows E.d0, N.d0
    W: np.ndarray  # (B, 2, m) rows E.w, N.w with w = (w_e/c)(-s_y, s_x, 0)
    c0: np.ndarray  # (B, m) Sagnac term at p_INS plus the modelled troposphere
    R: np.ndarray  # (m, m)

    @classmethod
    def build(cls, p_ins, east, north, sat, troposphere, R) -> PseudorangeModel:
        """From the INS point ``(B, 3)``, unit vectors ``(B, 3)`` and satellites ``(B, m, 3)``."""
        d0 = [sat[..., i] - p_ins[:, i : i + 1] for i in range(3)]  # component-first (B, m)
        k = OMEGA_E / C_LIGHT
        w = (-k * sat[..., 1], k * sat[..., 0])  # w = (w_e / c)(-s_y, s_x, 0)
        A = np.empty((sat.shape[0], 2, sat.shape[1]))
        W = np.empty_like(A)
        for r, u in enumerate((east, north)):
            A[:, r] = d0[0] * u[:, 0:1] + d0[1] * u[:, 1:2] + d0[2] * u[:, 2:3]
            W[:, r] = w[0] * u[:, 0:1] + w[1] * u[:, 1:2]
        c0 = k * (sat[..., 0] * p_ins[:, None, 1] - sat[..., 1] * p_ins[:, None, 0]) + troposphere
        return cls(d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2], A, W, c0, R)

    def repeat_batch(self, K: int) -> PseudorangeModel:
        """Each episode's parameters repeated K times (Gaussian-sum filters stack components)."""
        return PseudorangeModel(*(np.repeat(a, K, axis=0) for a in self[:4]), self.R)

    def _flat(self, x: np.ndarray) -> np.ndarray:
        return x.reshape(x.shape[0], -1, x.shape[-1])  # (B, K, n)

    def h(self, x: np.ndarray) -> np.ndarray:
        if is_component_major(x):  # particles stored as (B, n, N): the reduced form runs along N
            rho0 = np.sqrt(self.rho0_sq)
            return ReducedPseudorangeModel(self, rho0).h(x) + rho0[:, None, :]
        flat = self._flat(x)
        e = flat[..., 0:2]
        out = e @ self.A  # in-place from here: (B, K, m) may hold millions of particles x rows
        out *= 2.0
        out += self.rho0_sq[:, None, :]
        e2 = e[..., 0] * e[..., 0]  # |e|^2 from the two columns: a reduction over an axis of
        e2 += e[..., 1] * e[..., 1]  # length 2 costs NumPy several times more
        out += e2[..., None]
        np.sqrt(out, out=out)
        out -= e @ self.W
        out += self.c0[:, None, :]
        out += flat[..., 6:7]
        return out.reshape(*x.shape[:-1], self.A.shape[-1])

    def reduced(self, z: np.ndarray) -> tuple[ReducedPseudorangeModel, np.ndarray]:
        """The same model about ``rho0 = |d0|``: ``(model of h(x) - rho0, z - rho0)``.

        "Observed minus computed" pseudo-ranges are metres, not 2e7 m, so a float32 particle
        cloud can be weighed without losing the innovation (see :class:`ReducedPseudorangeModel`).
        """
        rho0 = np.sqrt(self.rho0_sq)
        return ReducedPseudorangeModel(self, rho0), z - rho0

    def H(self, x: np.ndarray) -> np.ndarray:
        e = x[:, 0:2]  # (B, 2)
        rho = np.sqrt(
            self.rho0_sq + 2.0 * (e[:, None, :] @ self.A)[:, 0] + (e * e).sum(axis=1, keepdims=True)
        )
        J = np.zeros((x.shape[0], self.A.shape[-1], 8))
        J[..., 0:2] = np.swapaxes((self.A + e[:, :, None]) / rho[:, None, :] - self.W, -1, -2)
        J[..., 6] = 1.0
        return J

    def position(self, x: np.ndarray, p_ins: np.ndarray, east: np.ndarray, north: np.ndarray) -> np.ndarray:
        """Corrected ECEF position ``p_INS - e_lambda E - e_phi N`` for ``x (B, n)``."""
        return p_ins - x[:, 0:1] * east - x[:, 1:2] * north


class ReducedPseudorangeModel(NamedTuple):
    """``h(x) - rho0`` of a :class:`PseudorangeModel`, cancellation-free for float32 particles.

    With ``q = 2 d0 . delta + |delta|^2`` (``delta`` as in :class:`PseudorangeModel`),
    ``|s' - p| - |d0| = q / (|s' - p| + |d0|)`` exactly; ``q`` is dominated by ``2 d0 . delta``
    (no cancellation), so every factor keeps the particles' relative precision (float32: about
    1e-4 m for errors of a kilometre against the 5 m pseudo-range noise). Particles stored as a
    ``(B, n, N)`` buffer are evaluated along N.
    """

    base: PseudorangeModel
    rho0: np.ndarray  # (B, m) |d0|

    @property
    def R(self) -> np.ndarray:
        return self.base.R

    def h(self, x: np.ndarray) -> np.ndarray:
        """``h(x) - rho0`` for ``x (B, N, n)``; a ``(B, n, N)`` cloud by the compiled loop.

        :func:`navgym.gps_ins.pseudorange_kernel.reduced_pseudoranges` when ``x`` is the view of a
        contiguous ``(B, n, N)`` buffer (the Resample envs' clouds), else :meth:`h_reference`.
        """
        xT = x.transpose(0, 2, 1) if x.ndim == 3 else None
        if xT is not None and xT.flags.c_contiguous and x.dtype in (np.float32, np.float64):
            from navgym.gps_ins.pseudorange_kernel import reduced_pseudoranges  # numba: on first use

            b = self.base
            return reduced_pseudoranges(xT, b.A, b.W, b.rho0_sq, self.rho0, b.c0).transpose(0, 2, 1)
        return self.h_reference(x)

    def h_reference(self, x: np.ndarray) -> np.ndarray:
        """NumPy form of :meth:`h` (any layout and leading shape ``(B, ...)``)."""
        b = self.base
        dt = x.dtype
        comp = is_component_major(x)
        xT = (
            x.transpose(0, 2, 1)
            if comp
            else np.ascontiguousarray(x.reshape(x.shape[0], -1, x.shape[-1]).transpose(0, 2, 1))
        )
        e = xT[:, 0:2]  # (B, 2, N)
        m = b.A.shape[-1]
        # one product for both linear terms: rows [2 d0 . delta ; w . delta], (B, 2m, N)
        lin = np.concatenate([2.0 * np.swapaxes(b.A, 1, 2), np.swapaxes(b.W, 1, 2)], axis=1).astype(dt) @ e
        q, sag = lin[:, :m], lin[:, m:]
        e2 = e[:, 0] * e[:, 0]
        e2 += e[:, 1] * e[:, 1]
        q += e2[:, None, :]
        r = q + b.rho0_sq.astype(dt)[:, :, None]
        np.sqrt(r, out=r)
        r += self.rho0.astype(dt)[:, :, None]
        np.divide(q, r, out=q)
        q = np.subtract(q, sag, out=r)  # contiguous (B, m, N) again
        q += b.c0.astype(dt)[:, :, None]
        q += xT[:, 6:7]
        out = q.transpose(0, 2, 1)
        return out if comp else np.ascontiguousarray(out).reshape(*x.shape[:-1], q.shape[1])


@dataclass(frozen=True)
class GpsInsPlatform:
    """Seed 000's GPS/INS estimation problem (see the module docstring and the env card)."""

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
        if not (self.error_scale_m > 0 and np.isfinite(self.error_scale_m)):
            raise ValueError(f"error_scale_m must be finite and > 0; got {self.error_scale_m}")
        if not self.divergence_m > 0:
            raise ValueError(f"divergence_m must be > 0; got {self.divergence_m}")

    # --------------------------------------------------------------------------------- setup
    @property
    def almanac(self):
        return default_orbit_cache().almanac

    def sample_scenario(self, rng: np.random.Generator) -> Scenario:
        if self.critical:
            return critical_scenario()
        return self.scenarios.sample(rng)

    def sample_scenarios(self, rngs: Sequence[np.random.Generator]) -> list[Scenario]:
        if self.critical:
            return [critical_scenario() for _ in rngs]
        return list(self.scenarios.sample_many(list(rngs)))

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
    ) -> dict[str, np.ndarray]:
        rows = np.arange(t.shape[0])
        e = ep.ins_err[rows, t]
        clk = ep.clock[rows, t]
        x_true = np.concatenate([e, C_LIGHT * clk], axis=1)
        de = mean[:, :2] - e[:, :2]  # estimated minus true INS error (east, north)
        truth = ep.truth_ne[rows, t]
        # corrected position p_INS - e_hat (eq. 14) minus truth p_INS - e is e - e_hat = -de
        est = truth - np.stack([de[:, 1], de[:, 0]], axis=1)
        cov_ne = P[:, [1, 0]][:, :, [1, 0]]
        return {
            "pos_err_m": np.hypot(de[:, 0], de[:, 1]),
            "truth_pos": truth,
            "est_pos": est,
            "state_err": mean - x_true,
            "cov_ne": cov_ne,
        }

    # ------------------------------------------------------------------------------ features
    def features(self) -> list[Feature]:
        m = self.m_max
        return [
            Feature(
                "innovation", -10.0, 10.0, "-", "pseudo-range innovations / sqrt(S_ii), 0 where masked", m
            ),
            Feature("log_nis", 0.0, 10.0, "-", "log(1 + NIS / satellites used)"),
            Feature("satellites", 0.0, 1.0, "-", "satellites used / m_max"),
            Feature("log_gdop", 0.0, 3.0, "-", "log10 GDOP at the estimate (3 when < 4 satellites)"),
            Feature("log_sigma_pos", -2.0, 5.0, "log10 m", "log10 sqrt(P_ee + P_nn)"),
            Feature("log_sigma_vel", -4.0, 2.0, "log10 m/s", "log10 sqrt of the velocity-error variances"),
            Feature("log_sigma_bias", -8.0, 0.0, "log10 m/s^2", "log10 sqrt of the bias variances"),
            Feature("log_sigma_clock", -2.0, 6.0, "log10 m", "log10 sqrt(P_bb)"),
        ]

    def _cov_features(self, P: np.ndarray) -> dict[str, np.ndarray]:
        d = np.maximum(np.diagonal(P, axis1=1, axis2=2), 1e-300)
        return {
            "log_sigma_pos": 0.5 * np.log10(d[:, 0] + d[:, 1]),
            "log_sigma_vel": 0.5 * np.log10(d[:, 2] + d[:, 3]),
            "log_sigma_bias": 0.5 * np.log10(d[:, 4] + d[:, 5]),
            "log_sigma_clock": 0.5 * np.log10(d[:, 6]),
        }

    def initial_feature_values(self, belief: GaussianState, ep: GpsInsEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        cols = {
            "innovation": np.zeros((B, self.m_max)),
            "log_nis": np.zeros(B),
            "satellites": np.zeros(B),
            "log_gdop": np.full(B, 3.0),
        }
        cols.update(self._cov_features(belief.P))
        return cols

    def feature_values(self, belief, info, models: StepModels, ep, t) -> dict[str, np.ndarray]:
        S_diag = np.maximum(np.diagonal(info.S, axis1=1, axis2=2), 1e-12)
        n_used = np.maximum(info.n_meas, 1)
        p_ins, east, north, sat = models.aux
        p_est = models.observation.position(belief.m, p_ins, east, north)
        g = gdop(p_est, sat, models.mask)
        cols = {
            "innovation": np.where(models.mask, info.innovation / np.sqrt(S_diag), 0.0),
            "log_nis": np.log1p(np.maximum(info.nis, 0.0) / n_used),
            "satellites": info.n_meas / self.m_max,
            "log_gdop": np.log10(np.where(np.isfinite(g), np.maximum(g, 1.0), 1e3)),
        }
        cols.update(self._cov_features(belief.P))
        return cols


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
    """Receiver clock bias [s] and drift [s/s] (seed 000 eq. 11), ``(B, T + 1, 2)``.

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


__all__ = ["GpsInsPlatform", "GpsInsEpisodes", "PseudorangeModel", "Any"]


# ---------------------------------------------------------------------------------------------
# Environments
# ---------------------------------------------------------------------------------------------
from navgym.envs.base import NavEnv, NavVectorEnv  # noqa: E402
from navgym.envs.factory import build_core  # noqa: E402

#: Scenario defaults per task: the degradations that make the task's knob matter.
TASK_SCENARIOS: dict[str, dict[str, Any]] = {
    "fading": {"outage_probability": 0.6, "outage_duration": (20.0, 120.0), "jamming_probability": 0.3},
    "mixture": {"outage_probability": 0.2, "impulsive_probability": 0.8, "impulsive_eps": (0.05, 0.3)},
    "resample": {"outage_probability": 0.5, "outage_duration": (20.0, 120.0), "partial_probability": 0.3},
}
SCENARIO_KWARGS = (
    "outage_probability",
    "outage_duration",
    "partial_probability",
    "partial_satellites",
    "impulsive_probability",
    "impulsive_eps",
    "impulsive_var_ratio",
    "jamming_probability",
    "jamming_sigma",
    "outlier_probability",
)
#: Per-task model mismatch: range of the true IMU bias limit [ug], log-uniform per episode, while
#: the filter assumes ``imu_grade`` (the fading factor exists to absorb such mismatch).
TASK_MISMATCH: dict[str, tuple[float, float] | None] = {
    "fading": (10.0, 3000.0),
    "mixture": None,
    "resample": None,
}
#: IMU grades of the two-axis error model: bias limit [ug] (seed 000: 10 ug, navigation grade).
IMU_GRADES = {"navigation": 10.0, "tactical": 100.0, "consumer": 2000.0}


def make_platform(task: str, kwargs: dict[str, Any], steps: int) -> GpsInsPlatform:
    """A :class:`GpsInsPlatform` from the env keyword arguments it owns (popped from ``kwargs``)."""
    scen = dict(TASK_SCENARIOS[task])
    given = sorted(k for k in (*SCENARIO_KWARGS, "mask_deg") if k in kwargs)
    if kwargs.get("critical", False) and given:
        raise ValueError(
            f"critical=True runs seed 000's fixed scenario (50 deg mask, 3 -> 2 satellites); "
            f"the scenario keyword arguments {given} would be ignored: leave them out"
        )
    scen.update({k: kwargs.pop(k) for k in SCENARIO_KWARGS if k in kwargs})
    if "mask_deg" in kwargs:
        m = float(kwargs.pop("mask_deg"))
        scen["mask_deg"] = (m, m)
    dt = float(kwargs.pop("dt", 1.0))
    scen["duration"] = steps * dt
    scen.setdefault("start_margin", min(30.0, 0.1 * steps * dt))
    grade = kwargs.pop("imu_grade", "navigation")
    if grade not in IMU_GRADES:
        raise ValueError(f"imu_grade must be one of {sorted(IMU_GRADES)}; got {grade!r}")
    limit = IMU_GRADES[grade] * 1e-6 * 9.80665
    ins = InsErrorParams(
        sigma_x=limit / 120.0, sigma_y=limit / 120.0, bias_limit=limit, sigma_bias0=limit / 2.0
    )
    mismatch = kwargs.pop("true_bias_limit_ug", TASK_MISMATCH.get(task))
    if mismatch is not None:
        lo, hi = (float(v) for v in mismatch)
        if not 0 < lo <= hi:
            raise ValueError(f"true_bias_limit_ug must be (low, high) with 0 < low <= high; got {mismatch!r}")
        mismatch = (lo, hi)
    return GpsInsPlatform(
        vehicle=kwargs.pop("vehicle", "land"),
        dt=dt,
        m_max=int(kwargs.pop("m_max", 12)),
        sigma_pr=float(kwargs.pop("sigma_pr", SIGMA_PR_M)),
        ins=ins,
        scenarios=ScenarioDistribution(**scen),
        critical=bool(kwargs.pop("critical", False)),
        true_bias_limit_ug=mismatch,
        error_scale_m=float(kwargs.pop("error_scale_m", 10.0)),
        divergence_m=float(kwargs.pop("divergence_m", 2000.0)),
    )


def _core(task: str, num_envs: int, kwargs: dict[str, Any]):
    kwargs = dict(kwargs)
    critical = bool(kwargs.get("critical", False))
    if critical and (kwargs.get("episode_steps", 3600) != 3600 or kwargs.get("dt", 1.0) != 1.0):
        raise ValueError(
            "critical=True runs seed 000's scenario as published (3600 s at dt = 1 s, the 3 -> 2 "
            f"satellite drop at 1983 s); got episode_steps={kwargs.get('episode_steps', 3600)}, "
            f"dt={kwargs.get('dt', 1.0)} (use max_episode_steps to stop earlier)"
        )
    steps = int(kwargs.pop("episode_steps", 3600 if critical else 300))
    platform = make_platform(task, kwargs, steps)
    return build_core(platform, task, num_envs, kwargs, steps)


class GpsInsEnv(NavEnv):
    """Seed 000's tightly coupled GPS/INS, with an agent steering the navigation filter.

    ## Description
    A land vehicle (or ship) navigates with a navigation-grade INS whose errors follow seed 000's
    two-axis model (Carvalho et al., IEEE T-AES 1997, eq. 12-14) and a GPS receiver tracking up to
    ``m_max`` satellites of a real almanac (GPS week 2086) at 1 Hz: pseudo-ranges of eq. 10/15
    with receiver clock (eq. 11), troposphere and switchable noise regimes. An eight-state
    error filter (eq. 13) fuses them. Episodes bring GNSS outages, partial outages, impulsive noise
    (seed 001 eq. 71) and jamming, drawn from a seeded scenario distribution; seed 000's critical
    scenario (50 deg mask, 3 -> 2 satellites over 3600 s) is ``critical=True``. The agent controls
    the filter, not the vehicle: the fading factor (``GpsInsFading``), the outlier weight of a
    Gaussian-sum filter (``GpsInsMixture``) or a particle filter's resampling (``GpsInsResample``).

    ## Action Space
    ``Fading``: ``Box(-1, 1, (1,), float32)``, ``lambda = lambda_max ** ((a + 1) / 2)`` applied as
    ``P- = lambda F P F^T + Q`` (``a = -1``: the plain filter). ``Mixture``: ``Box(-1, 1, (1,))``,
    ``eps = eps_max (a + 1) / 2``, noise ``(1 - eps) N(0, R) + eps N(0, variance_ratio R)``.
    ``Resample``: ``Discrete(2)``, 1 = resample the particles now. Non-finite actions raise
    ``ValueError``; Box actions outside [-1, 1] are clipped and counted in ``info["action_clipped"]``.

    ## Observation Space
    A flat ``Box`` of float32 with the bounds below; values are clipped into it. Everything comes
    from the filter (innovations, covariances, satellites used, the previous action); no truth.

    {observation_table}

    In the Fading ids ``log_tr_HQH`` stays at its floor -8: seed 000's process noise drives only
    the accelerometer biases and the clock drift, which no pseudo-range sees within one step, so
    ``tr(H Q H^T) = 0`` (the column is kept so every Fading env publishes the same traces of
    seed 001 eq. 67-70).

    ## Rewards
    ``r = -min(pos_err_m / error_scale_m, reward_clip) - resample_cost * resampled``, with
    ``error_scale_m = 10`` m and ``reward_clip = 10``: 0 is perfect, -1 is a 10 m horizontal error.
    The terms are in ``info["reward_terms"]``. Divergence (see Episode End) ends the episode
    with an extra ``-divergence_penalty = -100``.

    ## Starting State
    The filter starts from its prior ``N(0, P0)`` (10 m, 0.05 m/s, bias ``imu_grade``'s limit / 2
    = 5 ug for the navigation grade, 30 m, 0.3 m/s). The true clock and INS errors are drawn from
    it too, except the IMU biases where ``true_bias_limit_ug = (lo, hi)`` is set (the default of
    ``GpsInsFading``: ``(10, 3000)``): each episode's true IMU then has a bias limit ``L`` drawn
    log-uniformly in ``[lo, hi]`` ug, its initial bias sigma (``L / 2``) and bias random walk
    scaled by ``L`` over the assumed limit, while the filter keeps ``imu_grade``'s model (the
    model mismatch the fading factor is for: true biases of hundreds of ug against a prior sigma
    of 5 ug). ``GpsInsMixture`` and ``GpsInsResample`` default to ``None`` (true IMU = assumed
    IMU). Vehicle start within 35-60 N, 10 W-30 E, GPS time within +-2 days of the almanac.

    ## Episode End
    Truncation after ``max_episode_steps`` (registry default 300; pass 3600 for the full critical
    run) or at the simulated horizon ``episode_steps`` (300 s; 3600 s with ``critical=True``).
    Termination on divergence: the filter's health flag is False, the horizontal error exceeds
    ``divergence_m = 2000`` m, or the filter's horizontal sigma ``sqrt(tr P_ne)`` exceeds
    ``SIGMA_DIVERGENCE x divergence_m`` (``navgym.envs.core.SIGMA_DIVERGENCE =
    {SIGMA_DIVERGENCE}``: a runaway covariance, e.g. extreme fading through an outage, ended
    before it overflows, however small the error). ``episode_steps`` sets the simulated episode
    (truth and scenario timing); ``max_episode_steps`` only cuts it short, so a single env and a
    vector env built with the same keyword arguments simulate the same episodes.

    ## Arguments
    ``gym.make("navgym/GpsInsFading-v0", filter="ekf", lambda_max=10.0, max_episode_steps=300,
    episode_steps=300, dt=1.0, vehicle="land"|"ship", imu_grade="navigation"|"tactical"|"consumer", m_max=12,
    sigma_pr=5.0, mask_deg=10, outage_probability=..., outage_duration=(lo, hi),
    partial_probability=..., partial_satellites=(lo, hi), impulsive_probability=...,
    impulsive_eps=(lo, hi), impulsive_var_ratio=(lo, hi), jamming_probability=..., jamming_sigma=...,
    outlier_probability=..., critical=False, true_bias_limit_ug=(10.0, 3000.0) or None,
    error_scale_m=10.0, divergence_m=2000.0, reward_clip=10.0, divergence_penalty=100.0,
    eval_info=True, render_mode=None)``. ``true_bias_limit_ug`` is the model mismatch between the
    IMU the filter assumes (``imu_grade``) and the true one: the range [ug] of the true bias limit,
    drawn log-uniformly per episode (see Starting State); ``None`` makes the true IMU the assumed
    one (default ``(10, 3000)`` for ``GpsInsFading``, ``None`` for the other tasks).
    ``GpsInsMixture`` takes ``filter="ckf"``, ``eps_max=0.5``, ``variance_ratio=100``;
    ``GpsInsResample`` takes ``n_particles=1000``, ``resample_cost=0.05``, ``method="systematic"``,
    ``roughening=0.0`` (v1: 0.2), ``log_ess_feature=False`` (v1: True),
    ``particle_dtype="float32"`` (the cloud's precision; weights, moments and diagnostics stay
    float64, and the pseudo-ranges are weighed "observed minus computed", so float32 loses no
    innovation precision: with no resampling the two precisions agree to 2e-4 m over 60 steps)
    and is registered with ``m_max=8`` satellites (the particle likelihood costs N x m per step).
    Every env takes ``penalize_remaining_steps=False`` (v1: True): the divergence penalty becomes
    ``divergence_penalty + reward_clip x steps not played`` (of the simulated
    ``episode_steps``, also where ``max_episode_steps`` truncates earlier: a single env cannot see
    gym.make's ``TimeLimit``, and single and vector envs give the same reward).
    ``reset(options={"scenario": navgym.scenarios.Scenario(...)})`` pins a scenario.

    ## Version History
    {version_history}
    """

    def __init__(self, task: str = "fading", render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(_core(task, 1, kwargs), render_mode=render_mode)


class GpsInsVectorEnv(NavVectorEnv):
    """Native batched GpsIns environment (see :class:`GpsInsEnv` for the card)."""

    def __init__(self, num_envs: int = 1, task: str = "fading", **kwargs: Any) -> None:
        kwargs.pop("render_mode", None)
        super().__init__(_core(task, num_envs, kwargs))


def _card() -> None:
    """Fill the card's observation tables (every registered id) and its version history."""
    GpsInsEnv.__doc__ = fill_card(GpsInsEnv.__doc__, __name__, _core, resample=True)


_card()
