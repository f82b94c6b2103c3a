"""The Iridium estimation problem: truth and fixes of B episodes, what the filter sees.

A road vehicle (Benzerrouk 2014, §2.7d: a dynamic test from Belgium through France to Spain
during GPS loss) is positioned by Iridium geolocation fixes alone, used as virtual beacons
(eq. 83; :mod:`navgym.iridium.models`), one attempt per ``dt = 10`` s step (the source's SBD
period). What decides and degrades a fix:

* **The constellation** (:mod:`navgym.iridium.constellation`): a fix needs an Iridium satellite
  above the elevation mask (the scenario's ``mask_deg``) at the vehicle's latitude/longitude;
  the highest one serves it and sets the fix's reported CEP radius
  (:class:`~navgym.iridium.sensors.IridiumFixNoise`), from which the filter's ``R`` is set.
  The episode starts somewhere in the Belgium-France-Spain corridor (latitude 41-51 deg N,
  longitude 4 deg W - 5 deg E) with the constellation in a random phase; the vehicle's local
  north/east offsets map to latitude/longitude on the ellipsoid's radii of curvature at the start
  (an hour's drive spans ~100 km).
* **The fix errors** (:mod:`navgym.iridium.sensors`): Gaussian with the CEP's sigma, the
  source's 2-10 km outliers and its rare ones above 100 km, which the reported CEP ignores.
* **The v2 events of the scenario** (:mod:`navgym.scenarios`), unknown to the filter (its ``Q``
  and the CEP-derived ``R`` stay nominal): outages (no fix), impulsive segments (Benzerrouk
  2014, eq. 71: with probability ``eps`` a fix's variance times ``var_ratio``), jamming ramps
  (extra fix noise ``jam_sigma`` per axis and lost fixes), masked segments (the canyons of the
  scenario: at most ``max_satellites`` usable satellites, none at 0, fix noise times
  ``noise_scale`` and lost fixes; buildings, terrain, an antenna under cover), manoeuvre
  bursts (inside a burst the vehicle's acceleration PSD grows by ``velocity_sigma^2 / dt``,
  i.e. its velocity changes by ``velocity_sigma`` [m/s] rms per step and axis on top of the
  nominal) and, where switched on (``multipath_probability``, off by default), biased segments
  (the scenario's multipath: a mean error ``bias`` plus noise ``sigma`` on one fix row).

**Truth** is the filter's own model with the step's true noise: ``x_{k+1} = F x_k + w_k``,
``w_k ~ N(0, Q(q_nom + q_burst,k))`` (:func:`~navgym.iridium.models.cv_process_noise`), from a
speed of 20-35 m/s in a uniform direction; so the filter is right except for the events.

With ``true_noise=True`` (the v2 ids) :meth:`IridiumPlatform.step_models` hands the evaluation
the noise the simulator used (``StepModels.truth``): ``Q`` with the burst's PSD, ``R`` with each
fix row's variance as drawn (outliers, impulsive ratio, canyon scale, jamming and a biased
segment's noise included) and each row's bias (0 outside biased segments).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
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
from navgym.geo.earth import meridian_radius, normal_radius
from navgym.iridium.constellation import elevations, serving_satellite
from navgym.iridium.models import BeaconFix, ConstantVelocity, cv_process_noise
from navgym.iridium.sensors import IridiumFixNoise, cep_sigma
from navgym.scenarios import (
    Scenario,
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

#: Measurement rows: the fix's north and east coordinates (one virtual beacon).
ROWS = ("fix_N", "fix_E")
#: Start region (Benzerrouk 2014's Belgium-France-Spain test): latitude, longitude ranges [deg].
START_LAT_DEG = (41.0, 51.0)
START_LON_DEG = (-4.0, 5.0)
#: Initial speed range [m/s] (motorway driving).
START_SPEED = (20.0, 35.0)
#: Log-sigma features of the filter's covariance.
COVARIANCE_BLOCKS = (
    CovarianceBlock("log_sigma_pos", (0, 1), 0.0, 6.0, "log10 m", "log10 sqrt(P_NN + P_EE)"),
    CovarianceBlock("log_sigma_vel", (2, 3), -2.0, 4.0, "log10 m/s", "log10 sqrt(P_vNvN + P_vEvE)"),
)
#: Uniforms per step: outlier kind, outlier size, impulsive draw, loss draw.
_UNIFORM_WIDTH = 4
#: (episode, step) pairs whose satellite geometry is computed at once (bounds the temporaries).
_CHUNK = 256


class IridiumEpisodes(NamedTuple):
    """Precomputed truth and fixes of B episodes (episode axis first, ``T + 1`` steps).

    Truth-only fields (evaluation; never in the observation): ``truth_pos``, ``truth_vel`` and,
    with ``true_noise``, ``true_q``, ``true_r``, ``true_bias``. Everything else is what the Iridium modem
    delivers (fixes, their CEP radius) and what follows from it.
    """

    truth_pos: np.ndarray  # (B, T+1, 2) north/east [m] (truth only)
    truth_vel: np.ndarray  # (B, T+1, 2) north/east velocity [m/s] (truth only)
    z: np.ndarray  # (B, T+1, 2) fixes (NaN where none)
    mask: np.ndarray  # (B, T+1, 2) delivered rows
    cep: np.ndarray  # (B, T+1) reported CEP radius [m] (0 where no fix)
    fix_age: np.ndarray  # (B, T+1) time since the last fix [s]
    m0: np.ndarray  # (B, 4) initial estimate (first fix, zero velocity)
    s0: np.ndarray  # (B,) sigma of the first fix [m] (from its CEP)
    #: (B, T+1) acceleration PSD the bursts add to step k -> k + 1 [m^2/s^3] (truth only, or None)
    true_q: np.ndarray | None = None
    #: (B, T+1, 2) per-axis variance of each fix as drawn [m^2] (truth only, or None)
    true_r: np.ndarray | None = None
    #: (B, T+1, 2) mean error of each fix row (a biased segment) [m] (truth only, or None)
    true_bias: np.ndarray | None = None


@dataclass(frozen=True)
class IridiumPlatform(PlatformBase):
    """Benzerrouk 2014's Iridium-only positioning (§2.7d, eq. 83; see the module docstring and the env card).

    Attributes:
        dt: Filter step [s], the fix period (Benzerrouk 2014: a fix every 10 s).
        fixes: CEP law and error model of the fixes.
        accel_psd: Nominal acceleration PSD ``q`` [m^2/s^3] of the truth and the filter's ``Q``
            (0.025: a velocity change of 0.5 m/s rms per 10 s step and axis, motorway bends).
        speed_sigma0: Prior sigma of each velocity component [m/s] (the filter starts at rest).
        error_scale_m: Position error giving reward -1 [m].
        divergence_m: Position error ending an episode [m].
        true_noise: Keep the noise the simulator used for ``StepModels.truth`` (the v2 ids).

    """

    dt: float = 10.0
    fixes: IridiumFixNoise = field(default_factory=IridiumFixNoise)
    accel_psd: float = 0.025
    speed_sigma0: float = 20.0
    scenarios: ScenarioDistribution = field(default_factory=ScenarioDistribution)
    error_scale_m: float = 1000.0
    divergence_m: float = 50e3
    true_noise: bool = False
    name: str = "Iridium"
    n: int = 4
    m_max: int = 2

    def __post_init__(self) -> None:
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be finite and > 0; got {self.dt!r}")
        for name in ("accel_psd", "speed_sigma0"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0; got {v!r}")
        self.check_reward_scales()

    # --------------------------------------------------------------------------------- setup
    def episode_bytes(self, T: int) -> int:
        """Bytes of one episode of ``T`` steps at reset (see the Platform protocol).

        The stored per-step arrays (truth, fixes, mask, CEP, fix age: 66 bytes a step, with
        ``true_noise`` 40 more) three times over with 120 bytes a step of scenario evaluations
        and draws (the measured peak is about 430 bytes a step), plus the satellite geometry of
        :data:`_CHUNK` (episode, step) pairs at a time: 8 kB a pair (measured: 450 kB for 64).
        """
        steps = int(T) + 1
        stored = steps * (8 * (2 + 2 + 2 + 1 + 1) + 2 + (40 if self.true_noise else 0))
        return 3 * stored + 120 * steps + 8_000 * _CHUNK

    def R_of(self, cep: np.ndarray) -> np.ndarray:
        """``R = sigma^2 I_2`` ``(..., 2, 2)``, fixes of CEP ``cep`` [m], ``sigma = CEP / 1.1774``."""
        s2 = cep_sigma(cep) ** 2
        return s2[..., None, None] * np.eye(2)

    # ------------------------------------------------------------------------------ simulate
    def simulate(
        self, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
    ) -> IridiumEpisodes:
        """Truth, constellation geometry and every fix of B episodes of T steps.

        Each episode draws, from its own generator, three child seeds (motion, fix normals and
        uniforms, start place and constellation phase), so B episodes at once equal B single ones.
        """
        B = len(rngs)
        dt = self.dt
        seeds = np.array([r.integers(0, 2**63 - 1, size=3) for r in rngs])
        g_motion = default_rngs(seeds[:, 0])
        g_fix = default_rngs(seeds[:, 1])
        g_place = default_rngs(seeds[:, 2])
        k = np.arange(T + 1)
        tt = np.broadcast_to(k * dt, (B, T + 1))
        batch = stack_scenarios(list(scenarios))

        # --- truth: white-noise acceleration with the bursts' extra PSD
        start = np.array([r.random(4) for r in g_motion])  # speed, heading, lat, lon
        speed = START_SPEED[0] + start[:, 0] * (START_SPEED[1] - START_SPEED[0])
        heading = 2.0 * np.pi * start[:, 1]
        lat0 = np.deg2rad(START_LAT_DEG[0] + start[:, 2] * (START_LAT_DEG[1] - START_LAT_DEG[0]))
        lon0 = np.deg2rad(START_LON_DEG[0] + start[:, 3] * (START_LON_DEG[1] - START_LON_DEG[0]))
        motion = standard_normal_batch(g_motion, (T + 1, 4))
        v_sig, _ = motion_burst(batch, tt)
        q_burst = v_sig**2 / dt
        q = self.accel_psd + q_burst  # (B, T+1) PSD of step k -> k + 1
        # per axis, w = sqrt(q) L n with L L^T = [[dt^3/3, dt^2/2], [dt^2/2, dt]]
        l11 = np.sqrt(dt**3 / 3.0)
        l21 = (dt**2 / 2.0) / l11
        l22 = np.sqrt(dt - l21**2)
        sq = np.sqrt(q)[..., None]
        w_pos = sq * l11 * motion[..., 0:2]
        w_vel = sq * (l21 * motion[..., 0:2] + l22 * motion[..., 2:4])
        vel = np.empty((B, T + 1, 2))
        vel[:, 0] = speed[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
        vel[:, 1:] = vel[:, :1] + np.cumsum(w_vel[:, :-1], axis=1)
        pos = np.zeros((B, T + 1, 2))
        pos[:, 1:] = np.cumsum(dt * vel[:, :-1] + w_pos[:, :-1], axis=1)

        # --- the constellation: satellites in view and the serving elevation at each step
        phase = np.array([r.random(2) for r in g_place]) * 2.0 * np.pi
        lat = lat0[:, None] + pos[..., 0] / meridian_radius(lat0)[:, None]
        lon = lon0[:, None] + pos[..., 1] / (normal_radius(lat0) * np.cos(lat0))[:, None]
        # every (episode, step) pair at once, in chunks of _CHUNK pairs: (_CHUNK, 66, 3) temporaries
        flat = lambda a: np.broadcast_to(a, (B, T + 1)).ravel()  # noqa: E731
        args = (
            flat(lat), flat(lon), flat(k * dt), flat(phase[:, :1]), flat(phase[:, 1:]),
            flat(batch.mask_deg[:, None]),
        )  # fmt: skip
        count, best = np.empty(B * (T + 1), dtype=np.int64), np.empty(B * (T + 1))
        for j in range(0, B * (T + 1), _CHUNK):
            lat_j, lon_j, t_j, raan_j, u_j, mask_j = (a[j : j + _CHUNK] for a in args)
            count[j : j + _CHUNK], best[j : j + _CHUNK] = serving_satellite(
                elevations(lat_j, lon_j, t_j, raan_j, u_j), mask_j
            )
        count, best = count.reshape(B, T + 1), best.reshape(B, T + 1)
        cep = self.fixes.cep(best)

        # --- the fixes and the scenario's degradations
        normals = standard_normal_batch(g_fix, (T + 1, 2))
        uniforms = np.stack([r.random((T + 1, _UNIFORM_WIDTH)) for r in g_fix])
        reg = noise_regime(batch, tt)
        c_scale, c_loss = canyon_regime(batch, tt)
        usable = np.minimum(count, max_satellites(batch, tt))
        fix_ok = gnss_available(batch, tt) & (usable >= 1)
        loss = reg.loss_prob + c_loss - reg.loss_prob * c_loss  # independent causes
        ok = fix_ok & ~(uniforms[..., 3] < loss)
        var = cep_sigma(cep) ** 2 * np.where(uniforms[..., 2] < reg.eps, reg.var_ratio, 1.0)
        var = var * c_scale**2 + reg.jam_sigma**2
        outlier = self.fixes.outlier_variance(uniforms[..., 0], uniforms[..., 1])
        var = np.where(outlier > 0, outlier, var)  # the source's outliers replace the error
        # the fix the filter starts from: nominal noise at t = 0 (its CEP from the geometry there)
        var[:, 0] = cep_sigma(cep[:, 0]) ** 2
        ok[:, 0] = True
        var = np.repeat(var[..., None], 2, axis=-1)  # per row
        bias = np.zeros((B, T + 1, 2))
        if np.isfinite(batch.multipath_start).any():  # biased segments on a fix row
            bias, mp_var = multipath_error(batch, tt, self.m_max)
            bias[:, 0], mp_var[:, 0] = 0.0, 0.0
            var = var + mp_var
        z = pos + bias + np.sqrt(var) * normals
        mask = np.repeat(ok[..., None], 2, axis=-1)
        z = np.where(mask, z, np.nan)
        last = np.maximum.accumulate(np.where(ok, k, 0), axis=1)
        fix_age = (k - last) * dt
        s0 = cep_sigma(cep[:, 0])
        m0 = np.concatenate([z[:, 0], np.zeros((B, 2))], axis=1)
        truth = {}
        if self.true_noise:
            truth = {"true_q": q_burst, "true_r": var, "true_bias": bias}
        return IridiumEpisodes(pos, vel, z, mask, np.where(ok, cep, 0.0), fix_age, m0, s0, **truth)

    def initial_belief(self, ep: IridiumEpisodes) -> GaussianState:
        """The first fix with its CEP's sigma, at rest with ``speed_sigma0`` per velocity axis."""
        B = ep.m0.shape[0]
        P = np.zeros((B, 4, 4))
        P[:, [0, 1], [0, 1]] = (ep.s0**2)[:, None]
        P[:, [2, 3], [2, 3]] = self.speed_sigma0**2
        return GaussianState(ep.m0.copy(), P)

    # ---------------------------------------------------------------------------------- step
    def step_models(self, ep: IridiumEpisodes, t: np.ndarray) -> StepModels:
        B = t.shape[0]
        rows = np.arange(B)
        last = ep.z.shape[1] - 1
        t = np.minimum(t, last - 1)
        k = t + 1  # measurement epoch
        Q = np.broadcast_to(cv_process_noise(self.accel_psd, self.dt), (B, 4, 4)).copy()
        cep = np.where(ep.cep[rows, k] > 0, ep.cep[rows, k], self.fixes.cep_zenith)  # masked: any R
        obs = BeaconFix(self.R_of(cep))
        truth = None
        if ep.true_r is not None:  # the v2 ids: what the simulator used (evaluation only)
            Q_true = cv_process_noise(self.accel_psd + ep.true_q[rows, t], self.dt)
            R_true = np.zeros((B, 2, 2))
            R_true[:, [0, 1], [0, 1]] = ep.true_r[rows, k]
            truth = TrueNoise(Q_true, R_true, ep.true_bias[rows, k].copy())
        return StepModels(ConstantVelocity(Q), obs, ep.z[rows, k], ep.mask[rows, k], self.dt, truth=truth)

    def position_error(
        self, mean: np.ndarray, ep: IridiumEpisodes, t: np.ndarray, P: np.ndarray
    ) -> PositionError:
        rows = np.arange(t.shape[0])
        truth = ep.truth_pos[rows, t]
        d = mean[:, :2] - truth
        err = np.concatenate([d, mean[:, 2:] - ep.truth_vel[rows, t]], axis=1)
        return PositionError(np.hypot(d[:, 0], d[:, 1]), truth, mean[:, :2].copy(), P[:, :2, :2].copy(), err)

    # ------------------------------------------------------------------------------ features
    def features(self) -> list[Feature]:
        return [
            *innovation_features(
                self.m_max, "innovations / sqrt(S_ii) of the fix's N/E rows; 0 where no fix",
                rows="rows used", unit_rows="fix rows used / 2",
            ),
            *(b.feature for b in COVARIANCE_BLOCKS),
            Feature("fix_cep", 0.0, 10.0, "km", "reported CEP radius of this step's fix (0: no fix)"),
            Feature("time_since_fix", 0.0, 30.0, "min", "time since the last Iridium fix / 60 s"),
        ]  # fmt: skip

    def initial_feature_values(self, belief: GaussianState, ep: IridiumEpisodes) -> dict[str, np.ndarray]:
        B = belief.m.shape[0]
        return {
            **innovation_initial_values(B, self.m_max),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
            "fix_cep": ep.cep[:, 0] / 1000.0,
            "time_since_fix": np.zeros(B),
        }

    def feature_values(
        self, belief: GaussianState, info: Any, models: StepModels, ep: IridiumEpisodes, t: np.ndarray
    ) -> dict[str, np.ndarray]:
        rows = np.arange(t.shape[0])
        k = np.minimum(t, ep.fix_age.shape[1] - 1)
        return {
            **innovation_values(info, models.mask, self.m_max),
            **covariance_values(belief.P, COVARIANCE_BLOCKS),
            "fix_cep": ep.cep[rows, k] / 1000.0,
            "time_since_fix": ep.fix_age[rows, k] / 60.0,
        }
