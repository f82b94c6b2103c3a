"""The Jpa estimation problem: GNSS joint position and attitude (Belles et al. 2022, §5) of B episodes.

A vehicle with a master and ``N`` slave GNSS antennas estimates its position and attitude from
double-differenced (DD) code and carrier-phase observations against a base station (eq. 11-12;
the model of :mod:`navgym.jpa.models`, shared with the study ``experiments.robust_jpa``). The
filter is the iterated error-state KF on the attitude manifold (eq. 13-17): its mean keeps the
nominal attitude as a rotation vector, its covariance is that of the error state (see
:mod:`navgym.jpa.models`), the update runs on the error state and is reset into the nominal.

**Episodes** (``dt = 1`` s): the satellites are the ``n_satellites`` highest of the packaged
almanac over a window of the day (one of :data:`N_GEOMETRIES` windows, drawn per episode; the
reference is the highest), the truth moves as in the study (velocity, gyro bias and body rate
random walks; Belles et al. 2022, Table 1), and the undifferenced code and phase noises (elevation
dependent, ``sigma_zenith / sin el``) are drawn and differenced, so the DDs have exactly the
filter's covariance ``D diag(sigma^2) D^T``. The filter starts from a converged float solution
(truth plus errors of the prior sigmas :attr:`JpaPlatform.sigma0`).

**Within-episode events, unknown to the filter** (its ``Q`` and ``R`` stay nominal):

* **cycle slips** (Belles et al. 2022, §5: "affected by a cycle slip"): with probability
  ``slip_probability`` an episode has 1-2 slip zones of 10-30 s, each on 1-2 non-reference
  satellites, an integer of ``+-1 .. +-slip_max_cycles`` cycles at every vehicle antenna (none at
  the base station), removed at the end of the zone; it cancels in the master-slave DDs, so it
  biases the base-master phase DDs of those satellites by ``lambda x cycles``;
* **outages** (the scenario's, off by default): no DD at all, the filter predicts on the gyro;
* **multipath zones** (the scenario's multipath segments, :func:`navgym.scenarios.multipath_error`):
  each segment on the base-master code DD of one satellite (``multipath_rows`` are DD satellite
  indices), a bias of ``multipath_bias`` [m] (random sign) and extra noise ``multipath_sigma``.

With ``true_noise`` :meth:`JpaPlatform.step_models` hands the evaluation what the simulator
used (``StepModels.truth``): the nominal ``Q`` (the truth follows the filter's random walks),
``R`` plus the multipath variances, and each row's bias (slip and multipath).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
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
from navgym.ins.attitude import rotation_matrix
from navgym.jpa.models import (
    DEG,
    WAVELENGTH_L1,
    Geometry,
    JpaConfig,
    JpaDDObservation,
    JpaTransitionModel,
    _row_order,
    dd_operator,
    dd_values,
    log_so3,
    make_geometry,
    process_noise,
)
from navgym.scenarios import (
    Scenario,
    ScenarioDistribution,
    default_rngs,
    gnss_available,
    multipath_error,
    stack_scenarios,
)

#: Almanac windows an episode's satellites are drawn from (one start per hour of the day).
N_GEOMETRIES = 12
#: The platform's default constellation and antennas: 7 satellites, a master and 2 slaves 1 m
#: away (the study's 10 satellites and 3 slaves cost 2.3x more per filter step).
PLATFORM_CONFIG = JpaConfig(n_satellites=7, baselines=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)))


class JpaEpisodes(NamedTuple):
    """Precomputed truth and DDs of B episodes (episode axis first, ``T + 1`` epochs).

    Truth-only fields (evaluation, never in the observation): ``truth_p``, ``truth_R``,
    ``truth_v``, ``truth_b``, ``truth_a``, ``true_bias``, ``true_var``.
    """

    truth_p: np.ndarray  # (B, T+1, 3) ENU position of the master antenna [m] (truth)
    truth_v: np.ndarray  # (B, T+1, 3) [m/s] (truth)
    truth_R: np.ndarray  # (B, T+1, 3, 3) body-to-ENU attitude (truth)
    truth_b: np.ndarray  # (B, T+1, 3) gyro bias [rad/s] (truth)
    truth_a: np.ndarray  # (B, M) integer DD ambiguities [cycles] (truth)
    gyro: np.ndarray  # (B, T+1, 3) measured rate over [t_k, t_k+1) [rad/s]
    z: np.ndarray  # (B, T+1, m) DDs (z[:, 0] unused; NaN in outages)
    mask: np.ndarray  # (B, T+1, m) received rows (False in outages)
    U: np.ndarray  # (B, T+1, n, 3) DD lines of sight (from the almanac: estimator-side)
    elevation: np.ndarray  # (B, T+1, S) [rad] (estimator-side)
    m0: np.ndarray  # (B, n_states) initial mean (theta first)
    true_bias: np.ndarray  # (B, T+1, m) slip and multipath bias per row [m] (truth)
    true_var: np.ndarray  # (B, T+1, m) multipath variance added per row [m^2] (truth)
    slipped: np.ndarray  # (B, T+1) bool: a slip zone is active (truth)


@lru_cache(maxsize=8)
def geometry_library(cfg: JpaConfig, steps: int, dt: float) -> tuple[Geometry, ...]:
    """:data:`N_GEOMETRIES` windows of ``steps`` epochs, one search per 2 h of the almanac day."""
    from dataclasses import replace

    c = replace(cfg, duration=steps * dt, dt=dt)
    return tuple(make_geometry(c, start_s=7200.0 * j) for j in range(N_GEOMETRIES))


@dataclass(frozen=True)
class JpaPlatform(PlatformBase):
    """Belles et al. 2022's GNSS joint position and attitude (see the module docstring and the env card).

    Attributes:
        config: Constellation, antennas and noise (:class:`navgym.jpa.models.JpaConfig`).
        dt: Filter step [s].
        sigma0: Prior sigmas of the converged start: attitude [rad], ambiguities [cycles],
            position [m], velocity [m/s].
        slip_probability: Probability that an episode has cycle-slip zones.
        slip_count: Range of their number; slip_duration: of their length [s].
        slip_satellites: Range of satellites slipped per zone; slip_max_cycles: largest slip.
        attitude_weight: Metres of reward error per degree of attitude error.
        true_noise: Keep the noise the simulator used for ``StepModels.truth``.

    """

    config: JpaConfig = PLATFORM_CONFIG
    dt: float = 1.0
    sigma0: tuple[float, float, float, float] = (1.0 * DEG, 0.05, 0.05, 0.1)
    scenarios: ScenarioDistribution = field(default_factory=ScenarioDistribution)
    slip_probability: float = 0.9
    slip_count: tuple[int, int] = (1, 2)
    slip_duration: tuple[float, float] = (10.0, 30.0)
    slip_satellites: tuple[int, int] = (1, 2)
    slip_max_cycles: int = 5
    attitude_weight: float = 0.1
    error_scale_m: float = 1.0
    divergence_m: float = 100.0
    true_noise: bool = True
    name: str = "Jpa"

    def __post_init__(self) -> None:
        self.check_reward_scales()

    @property
    def n(self) -> int:  # type: ignore[override]
        return self.config.n_states

    @property
    def m_max(self) -> int:  # type: ignore[override]
        return self.config.n_obs

    @property
    def M(self) -> int:
        return self.config.n_ambiguities

    @property
    def outlier_rows(self) -> tuple[int, ...]:
        """The base-master DDs (phase and code), where slips and multipath fall."""
        return tuple(range(2 * self.config.n_dd))

    def row_names(self) -> list[str]:
        n, N = self.config.n_dd, len(self.config.baselines)
        names = [f"phi_bm{i + 1}" for i in range(n)] + [f"rho_bm{i + 1}" for i in range(n)]
        names += [f"phi_{j + 1}m{i + 1}" for j in range(N) for i in range(n)]
        return names + [f"rho_{j + 1}m{i + 1}" for j in range(N) for i in range(n)]

    def episode_bytes(self, T: int) -> int:
        """Bytes of one episode of ``T`` steps at reset (see the Platform protocol).

        Per epoch: truth (3 + 3 + 9 + 3 + 3), gyro, U, elevations, DDs and their bias and
        variance, 8 bytes each, three times over for the simulation's temporaries (the measured
        peak is 3.6 kB a step), and the undifferenced noises.
        """
        c = self.config
        per = 8 * (21 + 3 + 3 * c.n_dd + c.n_satellites + 3 * c.n_obs + 1)
        undiff = 8 * 2 * (len(c.baselines) + 2) * c.n_satellites
        return (int(T) + 1) * (3 * per + undiff) + 8 * c.n_states * 2

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> JpaEpisodes:
        """Truth, geometry, slips and DDs of B episodes of T steps.

        Each episode draws four child seeds (motion, noise, events, prior) from its generator, so
        B episodes at once equal B single ones.
        """
        cfg, dt = self.config, self.dt
        B = len(rngs)
        S, N = cfg.n_satellites, len(cfg.baselines)
        n, M, m = cfg.n_dd, cfg.n_ambiguities, cfg.n_obs
        lam = WAVELENGTH_L1
        seeds = np.array([r.integers(0, 2**63 - 1, size=4) for r in rngs])
        g_motion, g_noise, g_event, g_prior = (default_rngs(seeds[:, i]) for i in range(4))
        lib = geometry_library(cfg, int(T), float(dt))
        pick = np.array([r.integers(0, len(lib)) for r in g_event])
        U = np.stack([lib[i].U for i in pick])  # (B, T+1, n, 3)
        el = np.stack([lib[i].elevation for i in pick])  # (B, T+1, S)

        # --- truth (as experiments.robust_jpa's simulate, batched over episodes)
        u0 = np.array([r.random(3) for r in g_motion])
        bearing, yaw = 2 * np.pi * u0[:, 0], np.pi * (2 * u0[:, 1] - 1)
        p = np.stack(
            [cfg.start_distance * np.cos(bearing), cfg.start_distance * np.sin(bearing), np.zeros(B)], 1
        )
        nm = np.stack([r.standard_normal((T + 1, 18)) for r in g_motion])  # (B, T+1, 18)
        v = nm[:, 0, 0:3] * np.array([5.0, 5.0, 0.0])
        b = nm[:, 0, 3:6] * cfg.sigma0_bias
        w = np.zeros((B, 3))
        R = rotation_matrix(np.stack([np.zeros(B), np.zeros(B), yaw], 1))
        a = np.stack([r.integers(-20, 21, M) for r in g_motion]).astype(np.float64)
        tp, tv, tR, tb, gy = (np.empty((B, T + 1) + s) for s in ((3,), (3,), (3, 3), (3,), (3,)))
        for k in range(T + 1):  # the time recursion (vectorized over the episodes)
            tp[:, k], tv[:, k], tR[:, k], tb[:, k] = p, v, R, b
            gy[:, k] = w + b + nm[:, k, 6:9] * (cfg.sigma_gyro / np.sqrt(dt))
            R = R @ rotation_matrix(w * dt)
            p = p + dt * v
            v = v + nm[:, k, 9:12] * np.asarray(cfg.sigma_velocity) * np.sqrt(dt)
            b = b + nm[:, k, 12:15] * cfg.sigma_bias * np.sqrt(dt)
            w = w + nm[:, k, 15:18] * np.asarray(cfg.sigma_rate) * np.sqrt(dt)

        # --- DDs: undifferenced noises, differenced (their covariance is the filter's R)
        D = dd_operator(S, N)
        order = _row_order(cfg)
        scale = np.tile(1.0 / np.sin(el), (1, 1, N + 2))  # (B, T+1, (N+2) S), receiver-major
        e_ph = np.stack([r.standard_normal((T + 1, (N + 2) * S)) for r in g_noise]) * cfg.sigma_phase * scale
        e_co = np.stack([r.standard_normal((T + 1, (N + 2) * S)) for r in g_noise]) * cfg.sigma_code * scale
        noise = np.concatenate([e_ph @ D.T, e_co @ D.T], axis=-1)[..., order]
        clean = dd_values(
            tR.reshape(-1, 3, 3),
            tp.reshape(-1, 3),
            np.repeat(a, T + 1, axis=0),
            U.reshape(-1, n, 3),
            np.asarray(cfg.baselines).T,
        ).reshape(B, T + 1, m)

        # --- events: cycle slips (base-master phase rows) and multipath (base-master code rows)
        tt = np.arange(T + 1) * dt
        bias = np.zeros((B, T + 1, m))
        slipped = np.zeros((B, T + 1), dtype=bool)
        horizon = T * dt
        for i, r in enumerate(g_event):  # a few draws per episode (not the hot path)
            if r.random() >= self.slip_probability:
                continue
            for _ in range(int(r.integers(self.slip_count[0], self.slip_count[1] + 1))):
                dur = r.uniform(*self.slip_duration)
                margin = min(self.scenarios.start_margin, 0.5 * horizon)
                t0 = r.uniform(margin, max(margin, horizon - dur))
                k_sat = int(r.integers(self.slip_satellites[0], self.slip_satellites[1] + 1))
                sats = r.choice(n, size=min(k_sat, n), replace=False)
                cyc = r.integers(1, self.slip_max_cycles + 1, sats.size) * r.choice([-1.0, 1.0], sats.size)
                on = (tt >= t0) & (tt < t0 + dur)
                bias[i][np.ix_(on, sats)] += lam * cyc
                slipped[i] |= on
        batch = stack_scenarios(list(scenarios))
        mp_bias, mp_var = multipath_error(batch, np.broadcast_to(tt, (B, T + 1)), n)
        bias[..., n : 2 * n] += mp_bias
        var = np.zeros((B, T + 1, m))
        var[..., n : 2 * n] = mp_var
        z = clean + noise + bias + np.sqrt(var) * np.stack([r.standard_normal((T + 1, m)) for r in g_noise])
        ok = gnss_available(batch, np.broadcast_to(tt, (B, T + 1)))  # outages: no DD at all
        ok[:, 0] = True
        mask = np.repeat(ok[..., None], m, axis=-1)
        z = np.where(mask, z, np.nan)

        # --- the prior: truth plus errors of sigma0 (a converged float solution)
        s_att, s_amb, s_pos, s_vel = self.sigma0
        pr = np.stack([r.standard_normal(12 + M) for r in g_prior])
        R0 = tR[:, 0] @ rotation_matrix(pr[:, 0:3] * s_att)
        m0 = np.concatenate(
            [
                log_so3(R0),
                a + pr[:, 3 : 3 + M] * s_amb,
                tp[:, 0] + pr[:, 3 + M : 6 + M] * s_pos,
                tv[:, 0] + pr[:, 6 + M : 9 + M] * s_vel,
                tb[:, 0] + pr[:, 9 + M : 12 + M] * cfg.sigma0_bias,
            ],
            axis=1,
        )
        return JpaEpisodes(tp, tv, tR, tb, a, gy, z, mask, U, el, m0, bias, var, slipped)

    def P0(self) -> np.ndarray:
        """Prior covariance ``(n, n)``: diagonal of :attr:`sigma0` (bias: Table 1)."""
        M = self.M
        s_att, s_amb, s_pos, s_vel = self.sigma0
        d = np.concatenate(
            [
                np.full(3, s_att),
                np.full(M, s_amb),
                np.full(3, s_pos),
                np.full(3, s_vel),
                np.full(3, self.config.sigma0_bias),
            ]
        )
        return np.diag(d**2)

    def initial_belief(self, ep: JpaEpisodes) -> GaussianState:
        B = ep.m0.shape[0]
        return GaussianState(ep.m0.copy(), np.broadcast_to(self.P0(), (B, self.n, self.n)).copy())

    # ---------------------------------------------------------------------------------- step
    def step_models(self, ep: JpaEpisodes, t: np.ndarray) -> StepModels:
        B = t.shape[0]
        rows = np.arange(B)
        last = ep.z.shape[1] - 1
        t = np.minimum(t, last - 1)
        k = t + 1
        Q = np.broadcast_to(process_noise(self.config), (B, self.n, self.n)).copy()
        R = dd_covariance(self, ep.elevation[rows, k])
        obs = JpaDDObservation(ep.U[rows, k], np.asarray(self.config.baselines).T, R)
        truth = None
        if self.true_noise:
            R_true = R + np.einsum("bi,ij->bij", ep.true_var[rows, k], np.eye(self.m_max))
            truth = TrueNoise(Q.copy(), R_true, ep.true_bias[rows, k].copy())
        mask = ep.mask[rows, k]
        return StepModels(
            JpaTransitionModel(ep.gyro[rows, t], Q, self.M), obs, ep.z[rows, k], mask, self.dt, truth=truth
        )

    def attitude_error_deg(self, mean: np.ndarray, ep: JpaEpisodes, t: np.ndarray) -> np.ndarray:
        """``|Log(R_true^T R_est)|`` [deg] ``(B,)`` (truth: evaluation only)."""
        rows = np.arange(t.shape[0])
        R_est = rotation_matrix(mean[:, 0:3])
        d = log_so3(np.swapaxes(ep.truth_R[rows, t], 1, 2) @ R_est)
        return np.linalg.norm(d, axis=1) / DEG

    def position_error(
        self, mean: np.ndarray, ep: JpaEpisodes, t: np.ndarray, P: np.ndarray
    ) -> PositionError:
        """Horizontal error of the master antenna; ``extra_error``: ``attitude_weight`` x attitude error."""
        M = self.M
        rows = np.arange(t.shape[0])
        p_true = ep.truth_p[rows, t]
        p = mean[:, 3 + M : 6 + M]
        ne = [1, 0]  # ENU -> north, east
        d = p[:, ne] - p_true[:, ne]
        R_est = rotation_matrix(mean[:, 0:3])
        dpsi = log_so3(np.swapaxes(ep.truth_R[rows, t], 1, 2) @ R_est)
        err = np.concatenate(
            [
                dpsi,
                mean[:, 3 : 3 + M] - ep.truth_a,
                p - p_true,
                mean[:, 6 + M : 9 + M] - ep.truth_v[rows, t],
                mean[:, 9 + M :] - ep.truth_b[rows, t],
            ],
            axis=1,
        )
        idx = [3 + M + 1, 3 + M]
        cov = P[:, idx][:, :, idx]
        att = np.linalg.norm(dpsi, axis=1) / DEG
        return PositionError(
            np.hypot(d[:, 0], d[:, 1]),
            p_true[:, ne],
            p[:, ne].copy(),
            cov.copy(),
            err,
            self.attitude_weight * att,
        )

    # ------------------------------------------------------------------------------ features
    def covariance_blocks(self) -> tuple[CovarianceBlock, ...]:
        M = self.M
        return (
            CovarianceBlock("log_sigma_att", (0, 1, 2), -5.0, 0.0, "log10 rad", "log10 sqrt(tr P_psi)"),
            CovarianceBlock(
                "log_sigma_amb", tuple(range(3, 3 + M)), -4.0, 2.0, "log10 cycles", "log10 sqrt(tr P_a)"
            ),
            CovarianceBlock(
                "log_sigma_pos", (3 + M, 4 + M, 5 + M), -4.0, 2.0, "log10 m", "log10 sqrt(tr P_p)"
            ),
            CovarianceBlock(
                "log_sigma_vel", (6 + M, 7 + M, 8 + M), -4.0, 2.0, "log10 m/s", "log10 sqrt(tr P_v)"
            ),
        )

    def features(self) -> list[Feature]:
        return [
            *innovation_features(
                self.m_max, "DD innovations / sqrt(S_ii) (phase, code; base-master then master-slave)"
            ),
            *(Feature(b.name, b.low, b.high, b.unit, b.description) for b in self.covariance_blocks()),
            Feature("min_elevation", 0.0, 90.0, "deg", "lowest elevation of the tracked satellites"),
        ]

    def initial_feature_values(self, belief: GaussianState, ep: JpaEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        return {
            **innovation_initial_values(B, self.m_max),
            **covariance_values(belief.P, self.covariance_blocks()),
            "min_elevation": ep.elevation[:, 0].min(axis=1) / DEG,
        }

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: JpaEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        rows = np.arange(t.shape[0])
        k = np.minimum(t, ep.elevation.shape[1] - 1)
        return {
            **innovation_values(info, models.mask, self.m_max),
            **covariance_values(belief.P, self.covariance_blocks()),
            "min_elevation": ep.elevation[rows, k].min(axis=1) / DEG,
        }


def dd_covariance(platform: JpaPlatform, elevation: np.ndarray) -> np.ndarray:
    """``R (B, m, m)`` batched: ``D diag(sigma^2) D^T`` per episode (one einsum, no loop over B)."""
    cfg = platform.config
    N = len(cfg.baselines)
    D = dd_operator(cfg.n_satellites, N)
    s2 = np.tile(1.0 / np.sin(elevation), (1, N + 2)) ** 2  # (B, (N+2) S)
    S_ph = np.einsum("ik,bk,jk->bij", D, s2 * cfg.sigma_phase**2, D)
    S_co = np.einsum("ik,bk,jk->bij", D, s2 * cfg.sigma_code**2, D)
    P = D.shape[0]
    full = np.zeros((elevation.shape[0], 2 * P, 2 * P))
    full[:, :P, :P] = S_ph
    full[:, P:, P:] = S_co
    order = _row_order(cfg)
    return full[:, order][:, :, order]
