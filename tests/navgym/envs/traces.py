"""Reference traces of every registered id: what a refactoring must leave unchanged.

``python -m tests.navgym.envs.traces record`` writes ``tests/navgym/envs/traces/<id>.npz``
(observations, rewards, terminations, truncations and ``info["pos_err_m"]`` of a native vector
env with autoresets, and of a single ``gym.make`` env, under seeded random actions);
``python -m tests.navgym.envs.traces compare`` prints, per id, the largest differences of a
fresh run against the stored traces. ``test_traces.py`` holds them equal to rounding.
"""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import navgym  # noqa: F401  (registers the ids)
from navgym.envs.registration import ENVIRONMENTS, superseded_ids_quiet

TRACE_DIR = Path(__file__).with_name("traces")
NUM_ENVS = 3
STEPS = 40
#: The vector env truncates after this many steps, so each trace crosses an autoreset.
LIMIT = 25
SEED = 7
KEYS = ("obs", "reward", "terminated", "truncated", "pos_err_m")


def _actions(space: gym.Space, n: int, seed: int) -> list:
    space.seed(seed)
    return [space.sample() for _ in range(n)]


def run(env_id: str) -> dict[str, np.ndarray]:
    """Traces of ``env_id``: ``vec_*`` from the native vector env, ``single_*`` from gym.make."""
    out: dict[str, list] = {f"{p}_{k}": [] for p in ("vec", "single") for k in KEYS}
    with superseded_ids_quiet():
        venv = gym.make_vec(
            env_id, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point", max_episode_steps=LIMIT
        )
        env = gym.make(env_id, max_episode_steps=LIMIT)
    obs, _ = venv.reset(seed=SEED)
    out["vec_obs"].append(obs)
    for a in _actions(venv.action_space, STEPS, SEED):
        obs, r, term, trunc, info = venv.step(a)
        for k, v in zip(KEYS, (obs, r, term, trunc, info["pos_err_m"]), strict=True):
            out[f"vec_{k}"].append(np.asarray(v))
    obs, _ = env.reset(seed=SEED)
    out["single_obs"].append(obs)
    for a in _actions(env.action_space, STEPS, SEED + 1):
        obs, r, term, trunc, info = env.step(a)
        for k, v in zip(KEYS, (obs, r, term, trunc, info["pos_err_m"]), strict=True):
            out[f"single_{k}"].append(np.asarray(v))
        if term or trunc:
            obs, _ = env.reset()
            out["single_obs"].append(obs)
    venv.close()
    env.close()
    return {k: np.stack(v) for k, v in out.items()}


def path(env_id: str) -> Path:
    """Where the traces of ``env_id`` are stored."""
    return TRACE_DIR / (env_id.removeprefix("navgym/") + ".npz")


def differences(env_id: str) -> dict[str, float]:
    """Largest absolute difference per trace between a fresh run and the stored one."""
    ref = np.load(path(env_id))
    new = run(env_id)
    out = {}
    for k, a in new.items():
        b = ref[k]
        if a.shape != b.shape:
            out[k] = np.inf
            continue
        d = np.abs(a.astype(np.float64) - b.astype(np.float64))
        same_nonfinite = ~np.isfinite(a) & (a.astype(np.float64) == b.astype(np.float64))
        out[k] = float(np.max(np.where(same_nonfinite, 0.0, d), initial=0.0))
    return out


def main(argv: list[str]) -> None:
    mode = argv[0] if argv else "compare"
    ids = argv[1:] or [e[0] for e in ENVIRONMENTS]
    if mode == "record":
        TRACE_DIR.mkdir(exist_ok=True)
        for env_id in ids:
            np.savez_compressed(path(env_id), **run(env_id))
            print("recorded", env_id)
    elif mode == "compare":
        print(f"| id | {' | '.join(f'max abs diff {k}' for k in ('obs', 'reward', 'pos_err_m'))} |")
        print("|---|---|---|---|")
        for env_id in ids:
            d = differences(env_id)
            cols = [max(d[f"vec_{k}"], d[f"single_{k}"]) for k in ("obs", "reward", "pos_err_m")]
            flags = max(d[f"{p}_{k}"] for p in ("vec", "single") for k in ("terminated", "truncated"))
            note = "" if flags == 0 else " (episode ends differ)"
            print(f"| {env_id} | {' | '.join(f'{c:.3g}' for c in cols)} |{note}")
    else:
        raise SystemExit(f"usage: python -m tests.navgym.envs.traces [record|compare] [ID ...]; got {mode!r}")


if __name__ == "__main__":
    main(sys.argv[1:])
