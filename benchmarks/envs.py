"""Environment throughput: env-steps per second, single, native vector and SyncVectorEnv.

For one environment per task (GpsInsFading with the EKF, GpsInsMixture with the GS-CKF,
GpsInsResample with N = 1000 particles), on one core: a single ``gym.make`` env, the native
batched vector env (``gym.make_vec``, ``vector_entry_point``) at B = 1, 256, 4096, and
Gymnasium's ``SyncVectorEnv`` over single envs at B = ``SYNC_B`` = 256 (the issue's comparison
point) as the comparison. Random actions, ``eval_info=False`` (no NEES). Each figure is given
between resets (steps only) and over whole episodes with the measured reset time (median of
``RESET_REPEATS`` resets; :func:`amortized_rate`), which is what a run of full episodes gets;
targets are checked on the latter.

The native env's steps are timed over a whole episode (steps 2 to T - 1) whatever
``--seconds`` says: the step cost grows through an episode (with random actions more
sub-envs diverge and are reset inside ``step``), so the first steps alone would flatter large
B. ``--seconds`` caps only the single and SyncVectorEnv timings (a SyncVectorEnv episode at
B = 256 would take minutes; the cap biases the native / sync ratio down, not up).

    navgym bench envs [--batch 1 256 4096] [--envs ...] [--clock wall|cpu] [--json PATH]

``--clock cpu`` times with the CPU time of the timing thread (a machine shared with other work).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import gymnasium as gym
import numpy as np

from benchmarks._timing import (
    CLOCKS,
    add_clock_argument,
    add_threads_argument,
    check_threads,
    single_core,
    write_json,
)
from navgym.envs.registration import superseded_ids_quiet
from navgym.tables import format_table

DEFAULT_ENVS = ["navgym/GpsInsFading-v0", "navgym/GpsInsMixture-v0", "navgym/GpsInsResample-v1"]
#: Issue targets (env-steps/s on one core): id -> (B, target).
TARGETS = {
    "navgym/GpsInsFading-v0": (4096, 200_000),
    "navgym/GpsInsFading-v1": (4096, 200_000),
    "navgym/GpsInsResample-v0": (256, 20_000),
    "navgym/GpsInsResample-v1": (256, 20_000),
}
#: Largest native batch per env: the particle-filter envs at B = 4096 (4096 x 1000 particles)
#: take about 1 s per step and 6.5 s per reset, minutes per whole-episode measurement.
MAX_B = {
    "navgym/GpsInsResample-v0": 256,
    "navgym/GpsInsResample-v1": 256,
    "navgym/Robot2dResample-v0": 256,
    "navgym/Robot2dResample-v1": 256,
}
#: SyncVectorEnv is timed at this B (the issue's comparison point) only.
SYNC_B = 256


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--envs", nargs="+", default=DEFAULT_ENVS, help="environment ids")
    parser.add_argument("--batch", type=int, nargs="+", default=[1, 256, 4096], help="native batch sizes")
    parser.add_argument(
        "--seconds",
        type=float,
        default=3.0,
        help="time budget of the single-env and SyncVectorEnv timings (native: a whole episode)",
    )
    parser.add_argument("--json", default="results/bench/envs.json", help="where to write JSON")
    add_clock_argument(parser)
    add_threads_argument(parser)


def _episode_steps(env_id: str) -> int:
    """Steps per episode of the registered id (``max_episode_steps``)."""
    return int(gym.spec(env_id).max_episode_steps)


#: A clock of :data:`benchmarks._timing.CLOCKS` (``--clock``): seconds as a float.
Clock = Callable[[], float]


def _rate(step, B: int, seconds: float, max_steps: int, now: Clock) -> float:
    """Env-steps per second of ``step`` (B env-steps each) over at most ``max_steps`` calls."""
    step()  # warm-up
    n, t0 = 0, now()
    while True:
        step()
        n += 1
        dt = now() - t0
        if dt > seconds or n >= max_steps:
            return n * B / dt


#: Timed resets per measurement (the median is reported).
RESET_REPEATS = 3


def _timed_reset(env, seed: int, now: Clock, repeats: int = RESET_REPEATS) -> float:
    """Median seconds of ``repeats`` ``env.reset(seed=seed + r)`` calls (single or vector env).

    The median, not the best: a run of full episodes pays every reset, and one sample alone
    varies by about 30 % on a shared machine (allocation of the episode arrays).
    """
    times = []
    for r in range(repeats):
        t0 = now()
        env.reset(seed=seed + r)
        times.append(now() - t0)
    return float(np.median(times))


def _native(env_id: str, B: int, now: Clock) -> tuple[float, float]:
    """``(steps-only env-steps/s over a whole episode, reset seconds)`` of the native vector env."""
    venv = gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point", eval_info=False)
    venv.reset(seed=0)  # warm-up (caches, allocator)
    reset_s = _timed_reset(venv, 10**6, now)
    venv.action_space.seed(0)
    acts = [venv.action_space.sample() for _ in range(16)]
    k = iter(range(10**9))
    # a whole episode, not ``seconds`` (module docstring)
    rate = _rate(lambda: venv.step(acts[next(k) % 16]), B, float("inf"), _episode_steps(env_id) - 2, now)
    venv.close()
    return rate, reset_s


def _single(env_id: str, seconds: float, now: Clock) -> tuple[float, float]:
    env = gym.make(env_id, eval_info=False)
    env.reset(seed=0)
    reset_s = _timed_reset(env, 10**6, now)
    env.action_space.seed(0)

    def step():
        _, _, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:  # an early termination (divergence): keep stepping a fresh episode
            env.reset()

    return _rate(step, 1, seconds, _episode_steps(env_id) - 2, now), reset_s


def _sync(env_id: str, B: int, seconds: float, now: Clock) -> tuple[float, float]:
    venv = gym.make_vec(env_id, num_envs=B, vectorization_mode="sync", eval_info=False)
    venv.reset(seed=0)
    reset_s = _timed_reset(venv, 10**6, now)
    venv.action_space.seed(0)
    a = venv.action_space.sample()
    rate = _rate(lambda: venv.step(a), B, seconds, _episode_steps(env_id) - 2, now)
    venv.close()
    return rate, reset_s


def amortized_rate(steps_per_s: float, reset_s: float, B: int, T: int) -> float:
    """Env-steps per second over whole episodes: ``B T / (t_reset + B T / rate)``.

    Every environment here simulates an episode's truth and sensor inputs at reset (fixed-length
    episodes of ``T`` steps), so a run of full episodes pays one reset per ``B T`` env-steps.
    """
    return B * T / (reset_s + B * T / steps_per_s)


def _verdict(value: float, target: float) -> str:
    return f">= {target:,.0f}: " + ("met" if value >= target else f"MISSED ({value / target:.2f} of target)")


def _add(rows, records, env_id, T, kind, B, rate, reset_s, amort, extra="", verdict="") -> None:
    """Append one table row and JSON record (``amort``: the rate with resets)."""
    rows.append([env_id, kind, B, f"{rate:,.0f}", f"{reset_s:.2f}", f"{amort:,.0f}", extra, verdict])
    records.append(
        {
            "env": env_id,
            "kind": kind,
            "B": B,
            "episode_steps": T,
            "steps_per_s": rate,
            "reset_s": reset_s,
            "steps_per_s_with_reset": amort,
        }
    )


def run(args: argparse.Namespace) -> int:
    cores = check_threads(args.threads, args.clock)
    now = CLOCKS[args.clock]
    rows, records = [], []
    with single_core(args.threads), superseded_ids_quiet():  # the targets were set on the -v0 ids
        for env_id in args.envs:
            T = _episode_steps(env_id)

            single, reset1 = _single(env_id, args.seconds, now)
            _add(
                rows,
                records,
                env_id,
                T,
                "single (gym.make)",
                1,
                single,
                reset1,
                amortized_rate(single, reset1, 1, T),
            )
            native_at: dict[int, float] = {}
            for B in args.batch:
                if B > MAX_B.get(env_id, 10**9):
                    rows.append(
                        [env_id, "native vector", B, "skipped (run time: B x N particles)", "", "", "", ""]
                    )
                    continue
                r, reset_s = _native(env_id, B, now)
                tgt = TARGETS.get(env_id)
                amort = amortized_rate(r, reset_s, B, T)
                verdict = _verdict(amort, tgt[1]) if tgt and tgt[0] == B else ""
                native_at[B] = amort
                _add(rows, records, env_id, T, "native vector", B, r, reset_s, amort, "", verdict)
                print(
                    f"  {env_id} native B={B}: {r:,.0f} env-steps/s, reset {reset_s:.2f} s, "
                    f"{amort:,.0f} with resets",
                    flush=True,
                )
            sync, reset_sync = _sync(env_id, SYNC_B, args.seconds, now)
            sync_amort = amortized_rate(sync, reset_sync, SYNC_B, T)
            ratio = native_at.get(SYNC_B, float("nan")) / sync_amort
            measured = np.isfinite(ratio)  # the native env at B = SYNC_B is in --batch
            _add(
                rows,
                records,
                env_id,
                T,
                "SyncVectorEnv",
                SYNC_B,
                sync,
                reset_sync,
                sync_amort,
                f"{ratio:.1f}x" if measured else "-",
                (">= 20x: " + ("met" if ratio >= 20 else "MISSED"))
                if measured
                else f"(native B = {SYNC_B} not run)",
            )
            records[-1]["native_speedup"] = ratio if measured else None
            print(f"  {env_id} SyncVectorEnv B={SYNC_B}: {sync:,.0f} env-steps/s", flush=True)
    print()
    print(
        f"Environment throughput ({cores}, random actions, {args.clock} clock). "
        "'steps': env-steps/s between resets; "
        "'with resets': over whole episodes of the registered length, the measured reset included "
        "(every env simulates an episode's truth and sensor inputs at reset); targets and the "
        "native / sync ratio use the latter."
    )
    headers = [
        "env",
        "kind",
        "B",
        "env-steps/s (steps)",
        "reset s",
        "env-steps/s (with resets)",
        "native / sync",
        "target",
    ]
    print(format_table(headers, rows))
    path = write_json(args.json, {"clock": args.clock, "threads": args.threads, "results": records})
    print(f"\nJSON written to {path}")
    return 0


__all__ = ["add_arguments", "run", "np"]
