"""GpsIns episodes: the truth and sensor inputs of B episodes, simulated at reset.

:func:`simulate_episodes` draws everything an episode needs before its first step (the
vehicle's track, the true INS errors, the receiver clock, the scenario's events, the noise
regime per epoch, the multipath segments) into one :class:`GpsInsEpisodes`; the step
(:meth:`navgym.gps_ins.platform.GpsInsPlatform.step_models`) only reads it, but for the
buffered per-episode noise (:func:`next_noise`) and the estimator-side cursors.

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

With ``true_noise`` the episodes keep the process noise the bursts add (and the bias walk of a
true IMU other than the filter's, ``true_bias_limit_ug``) in ``true_q``. With ``context`` (v3)
they also hold the inputs of the receiver's C/N0 chain and the IMU's window statistics
(:mod:`navgym.gps_ins.context`), drawn from generators of their own: the v0-v2 draws are unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from scipy.signal import lfilter

from navgym.geo import geodetic_to_ecef, north_east_axes
from navgym.geo.frames import up_axis
from navgym.gnss import default_critical_window
from navgym.gnss.clock import DEFAULT_CLOCK, clock_transition
from navgym.gnss.orbit_cache import OrbitBuffer, default_orbit_cache
from navgym.gnss.visibility import rank_satellites
from navgym.gps_ins.vehicle import LAND_VEHICLE, SHIP, sample_vehicle_plans, vehicle_track
from navgym.ins.error_model import InsErrorParams, ins_indicated_position, simulate_ins_errors
from navgym.scenarios import (
    Scenario,
    ScenarioBatch,
    canyon_regime,
    default_rngs,
    gnss_available,
    motion_burst,
    noise_regime,
    satellite_row_mask,
    stack_scenarios,
)

if TYPE_CHECKING:
    from navgym.gps_ins.context import GpsInsContext
    from navgym.gps_ins.platform import GpsInsPlatform

__all__ = [
    "MULTIPATH_SLOTS",
    "NOISE_BLOCK",
    "REGIME_COLUMNS",
    "GpsInsEpisodes",
    "fill_noise",
    "next_noise",
    "refill_noise",
    "simulate_episodes",
]

#: Steps of per-episode noise drawn at a time (one Python loop over episodes per block).
NOISE_BLOCK = 64
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
    #: The v3 context's inputs (:class:`navgym.gps_ins.context.GpsInsContext`; None unless ``context``)
    context: GpsInsContext | None = None


def simulate_episodes(
    p: GpsInsPlatform, rngs: Sequence[np.random.Generator], scenarios: Sequence[Scenario], T: int
) -> GpsInsEpisodes:
    """B episodes of ``T`` steps of the problem ``p`` (what :meth:`GpsInsPlatform.simulate` returns).

    Each episode draws from its own generator in ``rngs`` only; ``scenarios`` holds its events.
    """
    B = len(rngs)
    dt = p.dt
    times = np.arange(T + 1) * dt
    crit = np.array([s.critical for s in scenarios])
    window = default_critical_window(p.almanac) if crit.any() else None
    base = LAND_VEHICLE if p.vehicle == "land" else SHIP
    base = replace(base, duration=max(float(T * dt), 60.0))
    # One child generator per episode and purpose keeps the draw order fixed per episode.
    seeds = np.array([r.integers(0, 2**63 - 1, size=4) for r in rngs])
    g_plan = default_rngs(seeds[:, 0])
    g_ins = default_rngs(seeds[:, 1])
    g_clock = default_rngs(seeds[:, 2])
    gens = np.empty(B, dtype=object)
    for i, g in enumerate(default_rngs(seeds[:, 3])):
        gens[i] = g
    t_start = np.array([r.uniform(-p.start_spread_s, p.start_spread_s) for r in rngs])
    if p.true_bias_limit_ug is not None:  # model mismatch: the true IMU is drawn per episode
        lo, hi = np.log(p.true_bias_limit_ug[0]), np.log(p.true_bias_limit_ug[1])
        true_limit = np.exp(np.array([r.uniform(lo, hi) for r in rngs])) * 1e-6 * 9.80665
    else:
        true_limit = np.full(B, p.ins.bias_limit)
    gps_t0 = float(p.almanac.t_ref[0]) + t_start
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
    plans = sample_vehicle_plans([g_plan[i] for i in np.flatnonzero(~crit)], base) if (~crit).any() else None
    traj = _merge_trajectories(plans, plans_c if crit.any() else None, crit, times)
    heading = traj.heading
    ins_err = _simulate_ins(heading, dt, p.ins, true_limit, g_ins)
    batch = stack_scenarios(list(scenarios))
    tt = np.broadcast_to(times, (B, T + 1))
    burst_var = None
    if np.isfinite(batch.burst_start).any():  # unmodelled manoeuvres: the INS errors grow
        ins_err, burst_var = _manoeuvre(ins_err, batch, tt, seeds[:, 1], dt, p.ins.K)
    lat_i, lon_i = ins_indicated_position(traj.lat, traj.lon, ins_err, traj.h)
    p_ins = geodetic_to_ecef(lat_i, lon_i, traj.h)
    north, east = north_east_axes(lat_i, lon_i)
    rx = traj.ecef  # geodetic_to_ecef(traj.lat, traj.lon, traj.h)
    clock = _simulate_clock(g_clock, T, dt)
    gnss_ok = gnss_available(batch, tt)
    row_cap = satellite_row_mask(batch, tt, p.m_max).sum(axis=-1)
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
    k = 3 * p.m_max
    noise_n = np.empty((B, NOISE_BLOCK, k))
    noise_u = np.empty((B, NOISE_BLOCK, k))
    for i in range(B):
        fill_noise(gens[i], noise_n[i], noise_u[i])
    up = up_axis(traj.lat, traj.lon)
    mp = _multipath_segments(batch, p.m_max, dt, rx, up, gps_t0, sin_mask * np.abs(sin_mask))
    truth = {}
    if p.true_noise:
        q = np.zeros((B, T + 1, 4))
        if burst_var is not None:
            q[..., 0:2] = burst_var[..., None]
        k = true_limit / p.ins.bias_limit  # a true IMU of another grade walks k times as fast
        q[..., 2] = ((k**2 - 1.0) * p.ins.sigma_x**2 * dt)[:, None]
        q[..., 3] = ((k**2 - 1.0) * p.ins.sigma_y**2 * dt)[:, None]
        truth["true_q"] = q
    if p.bias_features:
        truth["bias_est"] = np.zeros((B, 3))
    if p.context:  # v3: the receiver's C/N0 chain and the IMU (their own generators)
        from navgym.gps_ins import context as cx

        rec = cx.draw_receiver_context(
            seeds[:, 3], p.almanac.prn.shape[0], p.m_max, mp[0], scale, reg.jam_sigma, p.sigma_pr
        )
        v_sig, _ = motion_burst(batch, tt)
        imu = cx.imu_window_statistics(seeds[:, 1], traj.position_ned[..., :2], heading, v_sig, dt)
        truth["context"] = cx.GpsInsContext(*rec, imu)
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


def fill_noise(gen: np.random.Generator, normals: np.ndarray, uniforms: np.ndarray) -> None:
    """One block of an episode's normals then uniforms, drawn straight into its buffers."""
    gen.standard_normal(out=normals)
    gen.random(out=uniforms)


def refill_noise(ep: GpsInsEpisodes) -> None:
    """Draw the next block of the episodes whose buffered noise is used up."""
    for i in np.flatnonzero(ep.noise_ptr >= NOISE_BLOCK):  # once per NOISE_BLOCK steps
        fill_noise(ep.gens[i], ep.noise_n[i], ep.noise_u[i])
        ep.noise_ptr[i] = 0


def next_noise(ep: GpsInsEpisodes) -> tuple[np.ndarray, np.ndarray]:
    """The step's normals and uniforms ``(B, 3 m_max)`` of every episode; advances the cursor."""
    B = ep.noise_ptr.shape[0]
    refill_noise(ep)
    rows = np.arange(B)
    n, u = ep.noise_n[rows, ep.noise_ptr], ep.noise_u[rows, ep.noise_ptr]
    np.add(ep.noise_ptr, 1, out=ep.noise_ptr)
    return n, u


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
    ``b_{k+1} = (b_k + c d_k) + w0_k`` in that order (``np.add.accumulate``), not a Python loop
    over the T steps, whose cost every reset would pay whatever B.
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
