"""Simulation throughput: episode-steps per second per platform (truth, sensors, INS, GNSS).

One *episode-step* advances one episode by one environment step, with everything a GNSS-aided
navigation environment simulates in that step (timings per component in the table):

* ``vehicle`` (Carvalho et al. 1997, §V, 1 s steps): truth of the land vehicle
  (:mod:`navgym.gps_ins.vehicle`), one step of the two-axis INS error model (eq. 13) and the
  INS-indicated position (eq. 14), scenario masks and noise regime, one GNSS epoch.
* ``quadrotor`` (Benzerrouk 2014, §2.7a, 0.1 s steps = one 10 Hz GNSS epoch): truth at the epoch and at
  the 20 midpoints of the 200 Hz IMU intervals, 20 consumer-MEMS IMU samples with errors,
  20 strapdown steps (Benzerrouk 2014, eq. 3-11), scenario, one GNSS epoch.
* ``robot`` (Benzerrouk 2014, eq. 77, 0.1 s steps = 5 odometry steps at 50 Hz): truth, wheel encoder,
  steering, GPS 10 Hz / GLONASS 5 Hz fixes and compass 5 Hz, 5 dead-reckoning steps of eq. 77,
  scenario, one GNSS epoch.

Truth trajectories are closed-form in time, and the environments evaluate them for the whole
episode at reset; here they are evaluated for a window of ``TRUTH_WINDOW`` environment steps at
a time (one call per window, timed and charged to its steps; rounds hold whole windows), so the
``truth`` column is the cost per step at that window. Everything recursive (INS, clock, sensor
noise, GNSS epoch) runs one step at a time.

A GNSS epoch is :func:`navgym.gnss.simulate_gnss_step` with up to 12 satellites (pseudo-ranges,
delta-ranges, troposphere, clock, the scenario's noise regime) on the packaged almanac, with
the scenario's satellite cap and outages applied to its mask. Per-episode random numbers come
from block-buffered streams, as in the environments. Timings: ``time.perf_counter``, warm-up,
best of ``--repeats`` rounds, one core (threadpoolctl).

    navgym bench sim [--batch 1 1024] [--platforms vehicle quadrotor robot] [--json PATH]
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from benchmarks._timing import single_core, write_json
from navgym import geo, gnss
from navgym.envs.registration import superseded_ids_quiet
from navgym.gnss.orbit_cache import default_orbit_cache
from navgym.gps_ins.platform import GpsInsPlatform
from navgym.gps_ins.vehicle import sample_vehicle_plans, vehicle_trajectory
from navgym.ins import (
    CONSUMER_MEMS,
    IMU_NOISE_WIDTH,
    ImuSample,
    InsErrorParams,
    imu_error_step,
    ins_error_initial_covariance,
    ins_error_transition,
    ins_indicated_position,
    sample_imu_bias,
    strapdown_step,
)
from navgym.motion.trajectory import nav_state_at, trajectory_heading
from navgym.quadrotor.flight import quadrotor_trajectory, sample_quadrotor_plans
from navgym.robot2d.robot import robot_trajectory, robot_transition, sample_robot_plans
from navgym.robot2d.sensors import ROBOT_NOISE_WIDTH, robot_measurements
from navgym.scenarios import (
    NormalStream,
    ScenarioDistribution,
    gnss_available,
    noise_regime,
    satellite_row_mask,
)
from navgym.tables import format_table

PLATFORMS = ("vehicle", "quadrotor", "robot")
DEFAULT_BATCH = [1, 1024]
PARTS = ("truth", "sensors", "ins", "scenario", "gnss")
M_MAX = 12
#: Environment step [s] and inner steps per environment step, per platform.
STEP = {"vehicle": (1.0, 1), "quadrotor": (0.1, 20), "robot": (0.1, 5)}
#: Spread of the episodes' GPS start times around the almanac epoch [s] (as the GpsIns envs).
START_SPREAD_S = GpsInsPlatform.start_spread_s
#: Environment steps per truth evaluation (the quadrotor's cost is per sample, not per call).
TRUTH_WINDOW = {"vehicle": 64, "quadrotor": 1, "robot": 32}
#: Steps drawn ahead by every per-episode random stream (one Python loop over the B generators
#: per refill, as the GpsIns envs' NOISE_BLOCK); timing rounds hold whole refill periods.
STREAM_CHUNK = 64
#: The environments whose filters consume each platform's simulation (their task.step is timed),
#: cheapest first: the Fading env's EKF, the Mixture env's Gaussian-sum CKF, the Resample env's
#: particle filter. The target ("the simulator costs less per step than the filter that consumes
#: it") is judged against the cheapest; the others show where the simulator stops mattering.
CONSUMERS = {
    "vehicle": ("navgym/GpsInsFading-v0", "navgym/GpsInsMixture-v0", "navgym/GpsInsResample-v1"),
    "quadrotor": ("navgym/QuadrotorFading-v0", "navgym/QuadrotorMixture-v0"),
    "robot": ("navgym/Robot2dFading-v0", "navgym/Robot2dMixture-v0", "navgym/Robot2dResample-v1"),
}
SCENARIOS = ScenarioDistribution(
    duration=3600.0,
    outage_probability=0.5,
    partial_probability=0.3,
    impulsive_probability=0.5,
    jamming_probability=0.3,
    outlier_probability=0.3,
)


class _TruthWindow:
    """Truth at the query times of ``window`` environment steps per evaluation.

    ``evaluate(times)`` maps ``(T,)`` times to a truth NamedTuple whose fields are ``(B, T, ...)``
    (``origin``: ``(B, 3)``; absent IMU outputs: None); ``offsets`` are the ``n_t`` query times
    of one step relative to its start ``k dt``.
    """

    def __init__(self, evaluate: Callable, dt: float, offsets: np.ndarray, window: int):
        self.evaluate, self.dt, self.offsets, self.window = evaluate, dt, np.asarray(offsets), window
        self.first, self.traj = None, None

    def at(self, k: int) -> tuple:
        if self.first is None or not self.first <= k < self.first + self.window:
            self.first = k - k % self.window
            steps = self.first + np.arange(self.window)
            self.traj = self.evaluate((steps[:, None] * self.dt + self.offsets).ravel())
        n = self.offsets.size
        j = (k - self.first) * n
        return type(self.traj)(
            *(
                f if f is None or name == "origin" else np.ascontiguousarray(f[:, j : j + n])
                for name, f in self.traj._asdict().items()
            )
        )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--batch", type=int, nargs="+", default=DEFAULT_BATCH, help="batch sizes B")
    parser.add_argument("--platforms", nargs="+", default=list(PLATFORMS), choices=PLATFORMS)
    parser.add_argument("--steps", type=int, default=None, help="steps per round (default: auto)")
    parser.add_argument("--repeats", type=int, default=3, help="timing rounds (best is kept)")
    parser.add_argument(
        "--shared-time",
        action="store_true",
        help="all episodes at the same GPS time (one constellation per step) instead of staggered",
    )
    parser.add_argument("--no-filter", action="store_true", help="skip timing the consuming filters")
    parser.add_argument("--json", default="results/bench/sim.json", help="where to write JSON")


class _Gnss:
    """GNSS epoch of B receivers through navgym.gnss's public API, with scenario masks."""

    def __init__(self, gens: list[np.random.Generator], scen, shared_time: bool = False):
        self.alm = gnss.load_default_almanac()
        self.shared_time = shared_time
        if shared_time:
            self.t0 = float(self.alm.t_ref[0])
        else:  # each episode at its own GPS time, as in the environments
            spread = [g.uniform(-START_SPREAD_S, START_SPREAD_S) for g in gens]
            self.t0 = float(self.alm.t_ref[0]) + np.array(spread)
            self.orbits = default_orbit_cache()
            self.orbit_buffer = self.orbits.new_buffer(len(gens))
        n_z = gnss.NORMALS_PER_ROW * M_MAX
        self.n_z = n_z
        self.streams = gnss.EpisodeStreams(gens, n_z + 2, gnss.UNIFORMS_PER_ROW * M_MAX, block=STREAM_CHUNK)
        z, _ = self.streams.step()
        self.clock = gnss.clock_init(z[:, n_z:])
        self.scen = scen

    def step(self, t: float, dt: float, lat, lon, h, v_ned, timer: dict[str, float]):
        c0 = time.perf_counter()
        b = lat.shape[0]
        avail = gnss_available(self.scen, t)
        rows = satellite_row_mask(self.scen, t, M_MAX)
        regime = gnss.make_regime(b, sigma=3.0, sigma_dr=0.1, **noise_regime(self.scen, t)._asdict())
        c1 = time.perf_counter()
        z, u = self.streams.step()
        self.clock = gnss.clock_step(self.clock, dt, z[:, self.n_z :])
        rx = geo.geodetic_to_ecef(lat, lon, h)
        v_e = np.einsum("bji,bj->bi", geo.ecef_to_ned_matrix(lat, lon), v_ned)
        tg = self.t0 + t
        meas = gnss.simulate_gnss_step(
            self.alm,
            tg,
            rx,
            v_e,
            self.clock,
            regime,
            z[:, : self.n_z],
            u,
            mask_deg=self.scen.mask_deg,
            m_max=M_MAX,
            orbit=(
                gnss.constellation(self.alm, tg)
                if self.shared_time
                else self.orbits.lookup(tg, self.orbit_buffer)
            ),
        )
        mask = meas.mask & rows & avail[:, None]
        c2 = time.perf_counter()
        timer["scenario"] += c1 - c0
        timer["gnss"] += c2 - c1
        return meas, mask


def _vehicle(seeds: list[int], shared_time: bool = False) -> Callable[[int, dict], None]:
    gens = [np.random.default_rng(s) for s in seeds]
    plan = sample_vehicle_plans(gens)
    scen = SCENARIOS.sample_batch(gens)
    params = InsErrorParams()
    p0 = np.sqrt(np.diag(ins_error_initial_covariance(params)))
    ins_noise = NormalStream(gens, 2 + 6, chunk=STREAM_CHUNK)
    e = ins_noise.next()[:, :6] * p0
    g = _Gnss(gens, scen, shared_time)
    dt = STEP["vehicle"][0]
    sig = np.array([params.sigma_x, params.sigma_y]) * np.sqrt(dt)
    state = {"e": e}
    # as the GpsIns envs: no IMU samples
    truth = _TruthWindow(lambda t: vehicle_trajectory(plan, t, imu=False), dt, [0.0], TRUTH_WINDOW["vehicle"])

    def step(k: int, timer: dict[str, float]) -> None:
        t = k * dt
        c0 = time.perf_counter()
        tr = truth.at(k)
        c1 = time.perf_counter()
        heading = trajectory_heading(tr)[:, 0]
        e = np.einsum("bij,bj->bi", ins_error_transition(heading, dt, params.K), state["e"])
        e[:, 4:] += sig * ins_noise.next()[:, :2]
        state["e"] = e
        ins_indicated_position(tr.lat[:, 0], tr.lon[:, 0], e, tr.h[:, 0])
        c2 = time.perf_counter()
        timer["truth"] += c1 - c0
        timer["ins"] += c2 - c1
        g.step(t, dt, tr.lat[:, 0], tr.lon[:, 0], tr.h[:, 0], tr.v_ned[:, 0], timer)

    return step


def _quadrotor(seeds: list[int], shared_time: bool = False) -> Callable[[int, dict], None]:
    gens = [np.random.default_rng(s) for s in seeds]
    plan = sample_quadrotor_plans(gens)
    scen = SCENARIOS.sample_batch(gens)
    dt_env, n_sub = STEP["quadrotor"]
    dt = dt_env / n_sub
    state = {
        "nav": nav_state_at(quadrotor_trajectory(plan, 0.0)),
        "bias": sample_imu_bias(CONSUMER_MEMS, gens),
    }
    noise = NormalStream(gens, IMU_NOISE_WIDTH * n_sub, chunk=STREAM_CHUNK)
    g = _Gnss(gens, scen, shared_time)
    offsets = np.concatenate([[0.0], (np.arange(n_sub) + 0.5) * dt])  # epoch + 20 IMU midpoints
    truth = _TruthWindow(lambda t: quadrotor_trajectory(plan, t), dt_env, offsets, TRUTH_WINDOW["quadrotor"])

    def step(k: int, timer: dict[str, float]) -> None:
        t = k * dt_env
        c0 = time.perf_counter()
        tr = truth.at(k)
        c1 = time.perf_counter()
        z = noise.next().reshape(-1, n_sub, IMU_NOISE_WIDTH)
        samples = []
        bias = state["bias"]
        for j in range(n_sub):  # per sample: (B, 3) slices beat one (B, 20, 3) block here
            ideal = ImuSample(tr.specific_force[:, 1 + j], tr.angular_rate[:, 1 + j])
            meas, bias = imu_error_step(ideal, bias, CONSUMER_MEMS, dt, z[:, j])
            samples.append(meas)
        state["bias"] = bias
        c2 = time.perf_counter()
        nav = state["nav"]
        for meas in samples:
            nav = strapdown_step(nav, meas, dt)
        state["nav"] = nav
        c3 = time.perf_counter()
        timer["truth"] += c1 - c0
        timer["sensors"] += c2 - c1
        timer["ins"] += c3 - c2
        g.step(t, dt_env, tr.lat[:, 0], tr.lon[:, 0], tr.h[:, 0], tr.v_ned[:, 0], timer)

    return step


def _robot(seeds: list[int], shared_time: bool = False) -> Callable[[int, dict], None]:
    gens = [np.random.default_rng(s) for s in seeds]
    plan = sample_robot_plans(gens)
    scen = SCENARIOS.sample_batch(gens)
    dt_env, n_sub = STEP["robot"]
    dt = dt_env / n_sub
    noise = NormalStream(gens, ROBOT_NOISE_WIDTH * n_sub, chunk=STREAM_CHUNK)
    g = _Gnss(gens, scen, shared_time)
    tr0 = robot_trajectory(plan, 0.0)
    state = {"x": np.concatenate([tr0.position[:, 0], tr0.heading], axis=-1)}
    o = plan.origin
    truth = _TruthWindow(
        lambda t: robot_trajectory(plan, t), dt_env, np.arange(n_sub) * dt, TRUTH_WINDOW["robot"]
    )

    def step(k: int, timer: dict[str, float]) -> None:
        t = k * dt_env
        c0 = time.perf_counter()
        tr = truth.at(k)
        c1 = time.perf_counter()
        z = noise.next().reshape(-1, n_sub, ROBOT_NOISE_WIDTH)
        meas = robot_measurements(tr, k * n_sub + np.arange(n_sub)[None, :], z, dt)
        c2 = time.perf_counter()
        x = state["x"]
        for j in range(n_sub):
            u = np.stack([meas.encoder[:, j], meas.steering[:, j]], axis=-1)
            x = robot_transition(x, u, dt)
        state["x"] = x
        c3 = time.perf_counter()
        ned = np.concatenate([tr.position[:, 0], np.zeros((len(seeds), 1))], axis=-1)
        lat, lon, h = geo.ecef_to_geodetic(geo.ned_to_ecef(ned, o[:, 0], o[:, 1], o[:, 2]))
        c4 = time.perf_counter()
        v = tr.v_c[:, 0, None] * np.stack(
            [np.cos(tr.heading[:, 0]), np.sin(tr.heading[:, 0]), np.zeros(len(seeds))], axis=-1
        )
        timer["truth"] += (c1 - c0) + (c4 - c3)
        timer["sensors"] += c2 - c1
        timer["ins"] += c3 - c2
        g.step(t, dt_env, lat, lon, h, v, timer)

    return step


BUILDERS = {"vehicle": _vehicle, "quadrotor": _quadrotor, "robot": _robot}


def measure(
    platform: str, batch: int, steps: int, repeats: int, shared_time: bool = False
) -> dict[str, float]:
    """Best-of-``repeats`` timing of ``steps`` environment steps of ``batch`` episodes.

    ``steps`` is rounded up to whole periods of the truth windows (:data:`TRUTH_WINDOW`) and of
    the random streams' refills (:data:`STREAM_CHUNK`), and every round starts at a period
    boundary, so each round pays its share of both.

    Returns:
        ``{"total_ms", "<part>_ms" ...}`` per environment step (of the best round) and
        ``episode_steps_per_s = batch / total``.

    """
    step = BUILDERS[platform](list(range(batch)), shared_time)
    period = math.lcm(TRUTH_WINDOW[platform], STREAM_CHUNK)
    steps = -(-steps // period) * period
    k = 0
    for _ in range(period):  # warm-up: one period
        step(k, dict.fromkeys(PARTS, 0.0))
        k += 1
    best_total, best_parts = np.inf, {}
    for _ in range(repeats):
        timer = dict.fromkeys(PARTS, 0.0)
        c0 = time.perf_counter()
        for _ in range(steps):
            step(k, timer)
            k += 1
        total = time.perf_counter() - c0
        if total < best_total:
            best_total, best_parts = total, timer
    out = {"total_ms": best_total / steps * 1e3}
    out.update({f"{p}_ms": best_parts[p] / steps * 1e3 for p in PARTS})
    out["episode_steps_per_s"] = batch / (best_total / steps)
    return out


class ConsumerCost(NamedTuple):
    """Milliseconds per batched step in a consuming environment (see :func:`consumer_cost`)."""

    filter_ms: float
    reset_ms: float  # the reset's simulation of the episode, per episode step
    step_models_ms: float  # the platform's per-step simulation (measurements, models)

    @property
    def env_sim_ms(self) -> float:
        """What the environment itself spends on simulation per step."""
        return self.reset_ms + self.step_models_ms


def consumer_cost(env_id: str, batch: int, steps: int, repeats: int) -> ConsumerCost:
    """The filter step and the simulation of the environment ``env_id`` at B = ``batch``.

    After a warm-up reset at B = 1, the native vector env is reset ``repeats`` times (the best
    is kept: the reset simulates the whole episode, charged per step over its
    ``episode_steps``) and stepped with neutral actions; then its platform's ``step_models``
    (the per-step simulation) and its task's ``step`` (filter predict + update with the task's
    knob) are timed alone, best of ``repeats`` rounds of ``steps`` calls.
    """
    import gymnasium as gym

    # one-time costs out of the timing: a B = 1 reset first (imports, orbit tables, the Quadrotor
    # kernel's compilation, about 6 s when Numba's on-disk cache is cold, 0.3 s to load it)
    warm = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point", eval_info=False)
    warm.reset(seed=0)
    warm.close()
    venv = gym.make_vec(env_id, num_envs=batch, vectorization_mode="vector_entry_point", eval_info=False)
    reset_s = np.inf
    for r in range(repeats):  # best of repeats, like the other columns (seeds r: the same work)
        c0 = time.perf_counter()
        venv.reset(seed=r)
        reset_s = min(reset_s, time.perf_counter() - c0)
    core = venv.core
    action = np.broadcast_to(core.task.neutral_action(), (batch, *np.shape(core.task.neutral_action())))
    for _ in range(3):
        venv.step(action.copy())
    knob, _ = core.task.knob(action.copy(), batch)
    best_models = best_filter = np.inf
    with np.errstate(all="ignore"):
        for _ in range(repeats):
            c0 = time.perf_counter()
            for _ in range(steps):
                models = core.platform.step_models(core.episodes, core.t)
            best_models = min(best_models, (time.perf_counter() - c0) / steps)
            c0 = time.perf_counter()
            for _ in range(steps):
                core.task.step(core.state, knob, models, venv.rngs)
            best_filter = min(best_filter, (time.perf_counter() - c0) / steps)
    episode_steps = core.T
    venv.close()
    return ConsumerCost(best_filter * 1e3, reset_s / episode_steps * 1e3, best_models * 1e3)


def run(args: argparse.Namespace) -> int:
    rows, records, env_rows = [], [], []
    with single_core(), superseded_ids_quiet():  # the targets were set on the -v0 ids
        for platform in args.platforms:
            dt_env, n_sub = STEP[platform]
            for b in args.batch:
                steps = args.steps or (200 if b <= 16 else 20)
                r = measure(platform, b, steps, args.repeats, args.shared_time)
                rate = r["episode_steps_per_s"]
                consumers = () if args.no_filter else CONSUMERS[platform]
                cc = {c: consumer_cost(c, b, steps, args.repeats) for c in consumers}
                costs = {c: v.filter_ms for c, v in cc.items()}
                r["filter_ms"] = costs[consumers[0]] if consumers else np.nan  # the cheapest: the target
                r["consumer_filter_ms"] = costs
                r["consumer_env_sim_ms"] = {
                    c: {**v._asdict(), "env_sim_ms": v.env_sim_ms} for c, v in cc.items()
                }
                for c, v in cc.items():
                    env_rows.append(
                        [
                            c,
                            b,
                            f"{v.reset_ms:.2f}",
                            f"{v.step_models_ms:.2f}",
                            f"{v.env_sim_ms:.2f}",
                            f"{v.filter_ms:.2f}",
                            "yes" if v.env_sim_ms < v.filter_ms else "NO",
                        ]
                    )
                f_cols = " / ".join(f"{v:.2f}" for v in costs.values()) or "-"
                verdict = " / ".join("yes" if r["total_ms"] < v else "NO" for v in costs.values()) or "-"
                rows.append(
                    [
                        platform,
                        b,
                        f"{dt_env:g} s ({n_sub}x)",
                        f"{rate:,.0f}",
                        f"{rate * n_sub:,.0f}",
                        *(f"{r[p + '_ms']:.2f}" for p in PARTS),
                        f"{r['total_ms']:.2f}",
                        f_cols,
                        verdict,
                    ]
                )
                records.append(
                    {"platform": platform, "B": b, "env_step_s": dt_env, "inner_steps": n_sub, **r}
                )
                print(f"  {platform:9s} B={b:<5d} {rate:12,.0f} episode-steps/s", flush=True)
    print()
    print(
        "Simulation throughput (one core; episode-step = one environment step of one episode, "
        "GNSS epoch of up to 12 satellites included; part columns in ms per batched step; "
        + ("all episodes at one GPS time" if args.shared_time else "each episode at its own GPS time")
        + "; filter ms: the consuming envs' task.step, "
        + "; ".join(f"{k}: " + " / ".join(v.split("/")[1] for v in ids) for k, ids in CONSUMERS.items())
        + "; the target is the first, the cheapest)"
    )
    headers = ["platform", "B", "env step (inner)", "episode-steps/s", "inner steps/s"]
    headers += [f"{p} ms" for p in PARTS] + ["total ms", "filter ms", "sim < filter"]
    print(format_table(headers, rows))
    if env_rows:
        print(
            "\nThe same target inside the environments, which simulate what their filters consume "
            "(the GpsIns envs a pseudo-range epoch per step, the Quadrotor and Robot2d envs position "
            "fixes, the Quadrotor's IMU preintegrated at reset), ms per batched step: the reset's "
            "simulation of the episode per step, the platform's step_models, their sum, and task.step"
        )
        print(
            format_table(
                ["env", "B", "reset / step", "step_models", "env sim", "filter", "env sim < filter"],
                env_rows,
            )
        )
    path = write_json(
        args.json,
        {
            "description": "episode-steps per second: truth, sensors, INS, scenario, GNSS epoch",
            "m_max": M_MAX,
            "results": records,
        },
    )
    print(f"\nJSON written to {path}")
    return 0
