"""Environment throughput: env-steps per second, single, native vector and SyncVectorEnv.

For one environment per task (GpsInsFading with the EKF, GpsInsMixture with the GS-CKF,
GpsInsResample with N = 1000 particles), on one core: a single ``gym.make`` env, the native
batched vector env (``gym.make_vec``, ``vector_entry_point``) at B = 1, 256, 4096, and
Gymnasium's ``SyncVectorEnv`` over single envs at the same B as the comparison. Random actions,
``eval_info=False`` (no NEES), autoreset included.

    navgym bench envs [--batch 1 256 4096] [--envs ...] [--json PATH]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

from navgym.bench._timing import format_table, single_core, write_json

DEFAULT_ENVS = ["navgym/GpsInsFading-v0", "navgym/GpsInsMixture-v0", "navgym/GpsInsResample-v1"]
#: Issue targets (env-steps/s on one core): id -> (B, target).
TARGETS = {
    "navgym/GpsInsFading-v0": (4096, 200_000),
    "navgym/GpsInsResample-v0": (256, 20_000),
    "navgym/GpsInsResample-v1": (256, 20_000),
}
#: Largest native batch per env (particle filters hold B x N x n particles).
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
    parser.add_argument("--seconds", type=float, default=3.0, help="time budget per measurement")
    parser.add_argument("--json", default="results/bench/envs.json", help="where to write JSON")


def _rate(step, B: int, seconds: float) -> float:
    step()  # warm-up
    n, t0 = 0, time.perf_counter()
    while True:
        step()
        n += 1
        dt = time.perf_counter() - t0
        if dt > seconds or n >= 2000:
            return n * B / dt


def _native(env_id: str, B: int, seconds: float) -> float:
    venv = gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point", eval_info=False)
    venv.reset(seed=0)
    venv.action_space.seed(0)
    acts = [venv.action_space.sample() for _ in range(16)]
    k = iter(range(10**9))
    rate = _rate(lambda: venv.step(acts[next(k) % 16]), B, seconds)
    venv.close()
    return rate


def _single(env_id: str, seconds: float) -> float:
    env = gym.make(env_id, eval_info=False)
    env.reset(seed=0)
    env.action_space.seed(0)

    def step():
        _, _, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:
            env.reset()

    return _rate(step, 1, seconds)


def _sync(env_id: str, B: int, seconds: float) -> float:
    venv = gym.make_vec(env_id, num_envs=B, vectorization_mode="sync", eval_info=False)
    venv.reset(seed=0)
    venv.action_space.seed(0)
    a = venv.action_space.sample()
    rate = _rate(lambda: venv.step(a), B, seconds)
    venv.close()
    return rate


def run(args: argparse.Namespace) -> int:
    rows, records = [], []
    with single_core():
        for env_id in args.envs:
            single = _single(env_id, args.seconds)
            rows.append([env_id, "single (gym.make)", 1, f"{single:,.0f}", "", ""])
            records.append({"env": env_id, "kind": "single", "B": 1, "steps_per_s": single})
            native_at: dict[int, float] = {}
            for B in args.batch:
                if B > MAX_B.get(env_id, 10**9):
                    rows.append([env_id, "native vector", B, "skipped (memory: B x N particles)", "", ""])
                    continue
                r = _native(env_id, B, args.seconds)
                native_at[B] = r
                tgt = TARGETS.get(env_id)
                verdict = ""
                if tgt and tgt[0] == B:
                    verdict = f">= {tgt[1]:,}: " + (
                        "met" if r >= tgt[1] else f"MISSED ({r / tgt[1]:.2f} of target)"
                    )
                rows.append([env_id, "native vector", B, f"{r:,.0f}", "", verdict])
                records.append({"env": env_id, "kind": "native", "B": B, "steps_per_s": r})
                print(f"  {env_id} native B={B}: {r:,.0f} env-steps/s", flush=True)
            sync = _sync(env_id, SYNC_B, args.seconds)
            ratio = native_at.get(SYNC_B, float("nan")) / sync
            rows.append(
                [
                    env_id,
                    "SyncVectorEnv",
                    SYNC_B,
                    f"{sync:,.0f}",
                    f"{ratio:.1f}x",
                    ">= 20x: " + ("met" if ratio >= 20 else "MISSED"),
                ]
            )
            records.append(
                {"env": env_id, "kind": "sync", "B": SYNC_B, "steps_per_s": sync, "native_speedup": ratio}
            )
            print(f"  {env_id} SyncVectorEnv B={SYNC_B}: {sync:,.0f} env-steps/s", flush=True)
    print()
    print("Environment throughput (one core, random actions, autoreset included)")
    print(format_table(["env", "kind", "B", "env-steps/s", "native / sync", "target"], rows))
    path = write_json(args.json, {"results": records})
    print(f"\nJSON written to {path}")
    return 0


__all__ = ["add_arguments", "run", "np"]
