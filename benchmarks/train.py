"""PPO training throughput: the headline ids against a trivial reference env, in one run.

Each navgym id is trained as ``navgym train`` trains it: :func:`agents.training.train.train`
with the id's entry of ``agents/configs/ppo.yml`` (zoo hyperparameters, ``NavSB3VecEnv`` with
the entry's ``n_envs``, ``VecMonitor``, ``VecNormalize``, a residual's ``ResidualVecEnv``, the
``RowSharedPolicy`` of the v3 ids, the navigation-metrics callback), one torch thread, seed 0,
into a temporary folder; only the periodic evaluation on tuning episodes (``eval_freq`` of the
v3 entries) is left out (``eval_freq=0``), since it is not training. The reference is SB3 PPO
on Gymnasium's ``Pendulum-v1`` (a few lines of NumPy per step) in a ``DummyVecEnv``
with the hyperparameters, ``n_envs``, policy network and normalization of one headline id's
entry (``--reference-like``, default ``navgym/GpsInsFading-v2``: 16 sub-envs, ``n_steps``
128, ``batch_size`` 512, 5 epochs), so the two differ in the env only.

Steps per second are ``model.num_timesteps`` over the wall time of ``model.learn`` (rollouts
with the initial reset, PPO updates, callbacks; not the model's construction; ``meta.json``'s
``steps_per_s``, which includes it, is in the JSON). The ratio is a row's rate over the
reference's in the same run. Where the time goes, from timers put around SB3's calls for the
run (``PPO.learn``, ``PPO.train``, the outer vec env's ``step`` and ``reset``, the innermost
vec env's ``step_wait`` and ``reset``), as shares of the learn time: ``env`` the vec env
stack's step and reset (wrappers, a residual's base agent, the env); ``base env``, a part of
it, the innermost env's ``step_wait`` and ``reset`` alone (``NavSB3VecEnv`` / ``DummyVecEnv``,
autoresets included); ``update`` PPO's gradient epochs; ``rollout other`` the rest (policy
forward passes, the rollout buffer and GAE, callbacks). ``env + update + rollout other`` is
the whole learn time.

Before its timed run, each env is reset and stepped once (compiled kernels loaded from Numba's
cache), and the reference is run for one rollout (torch's first passes).

``--timesteps`` are rounded up by SB3 to whole rollouts (``n_envs x n_steps``: 2048 for every
default id); ``--quick`` asks for 1, i.e. one rollout and one update per id (for tests).
``--n-envs N`` runs every entry (the reference's too) with ``N`` sub-environments and
``n_steps = n_envs x n_steps // N`` (the same rollout size, so the same number of updates per
step): how much of the env's fixed per-step cost a wider batch amortizes.

    navgym bench train [--timesteps 65536] [--ids ID ...] [--reference-like ID] [--n-envs N]
                       [--quick] [--out results/bench]     # writes train.json and train.md there
"""

from __future__ import annotations

import argparse
import contextlib
import json
import tempfile
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from benchmarks._timing import add_threads_argument, check_threads, single_core, write_json
from navgym.tables import format_table

DEFAULT_IDS = (
    "navgym/GpsInsFading-v2",
    "navgym/Robot2dMixture-v2",
    "navgym/QuadrotorNoiseScale-v2",
    "navgym/Robot2dResample-v2",
    "navgym/Robot2dRowScale-v3",
)
REFERENCE_ENV = "Pendulum-v1"
REFERENCE_LIKE = "navgym/GpsInsFading-v2"
DEFAULT_TIMESTEPS = 65536
SEED = 0

HEADERS = [
    "environment",
    "vec env",
    "n_envs",
    "timesteps",
    "steps/s",
    "ratio to reference",
    "env %",
    "base env %",
    "update %",
    "rollout other %",
]


@dataclass
class LearnTiming:
    """The timers of one ``model.learn`` (seconds)."""

    learn_s: float = 0.0
    env_s: float = 0.0  # the outer vec env's step and reset
    base_env_s: float = 0.0  # the innermost vec env's step_wait and reset
    update_s: float = 0.0  # PPO.train
    timesteps: int = 0
    wrappers: list[str] = field(default_factory=list)  # outer first
    settings: dict[str, Any] = field(default_factory=dict)  # n_envs, n_steps, batch_size, ...

    def shares(self) -> dict[str, float]:
        """Shares of the learn time: env (base env a part of it), update, rollout other."""
        t = self.learn_s
        return {
            "env": self.env_s / t,
            "base_env": self.base_env_s / t,
            "update": self.update_s / t,
            "rollout_other": (t - self.env_s - self.update_s) / t,
        }


def _accumulate(fn, rec: LearnTiming, attr: str):
    def timed(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            setattr(rec, attr, getattr(rec, attr) + time.perf_counter() - t0)

    return timed


@contextlib.contextmanager
def timed_ppo() -> Iterator[list[LearnTiming]]:
    """Timers around SB3 PPO's ``learn`` and ``train`` and the learning env's steps, for the block.

    Yields the list to which every ``PPO.learn`` call in the block appends its
    :class:`LearnTiming`. The class attributes are put back on exit; the env's timers
    (instance attributes) are removed when ``learn`` returns.
    """
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecEnvWrapper

    runs: list[LearnTiming] = []
    active: list[LearnTiming] = []
    original_learn, original_train = PPO.__dict__["learn"], PPO.__dict__["train"]

    def learn(self, *args, **kwargs):
        rec = LearnTiming()
        runs.append(rec)
        active.append(rec)
        env = self.get_env()
        chain = [env]
        while isinstance(chain[-1], VecEnvWrapper):
            chain.append(chain[-1].venv)
        rec.wrappers = [type(e).__name__ for e in chain]
        rec.settings = {
            "n_envs": int(self.n_envs),
            "n_steps": int(self.n_steps),
            "batch_size": int(self.batch_size),
            "n_epochs": int(self.n_epochs),
            "policy": type(self.policy).__name__,
        }
        base = chain[-1]
        timers = [
            (env, "step", "env_s"),
            (env, "reset", "env_s"),
            (base, "step_wait", "base_env_s"),
            (base, "reset", "base_env_s"),
        ]
        for obj, attr, slot in timers:
            setattr(obj, attr, _accumulate(getattr(obj, attr), rec, slot))
        t0 = time.perf_counter()
        try:
            return original_learn(self, *args, **kwargs)
        finally:
            rec.learn_s = time.perf_counter() - t0
            rec.timesteps = int(self.num_timesteps)
            for obj, attr, _ in timers:
                obj.__dict__.pop(attr, None)
            active.pop()

    def train(self):
        t0 = time.perf_counter()
        try:
            return original_train(self)
        finally:
            if active:
                active[-1].update_s += time.perf_counter() - t0

    setattr(PPO, "learn", learn)  # noqa: B010 - class attributes replaced for the block
    setattr(PPO, "train", train)  # noqa: B010
    try:
        yield runs
    finally:
        setattr(PPO, "learn", original_learn)  # noqa: B010
        setattr(PPO, "train", original_train)  # noqa: B010


def with_n_envs(entry: dict[str, Any], n_envs: int | None) -> dict[str, Any]:
    """``entry`` with ``n_envs`` sub-environments and the same rollout size (module docstring).

    ``None`` leaves it as it is. ``n_steps`` becomes ``old n_envs x old n_steps // n_envs``
    (at least 1).
    """
    if n_envs is None:
        return entry
    if n_envs < 1:
        raise ValueError(f"--n-envs must be >= 1; got {n_envs}")
    out = dict(entry)
    rollout = int(entry.get("n_envs", 8)) * int(entry.get("n_steps", 2048))
    out["n_envs"], out["n_steps"] = int(n_envs), max(1, rollout // int(n_envs))
    return out


def reference_run(like_id: str, timesteps: int, seed: int = SEED, n_envs: int | None = None) -> None:
    """SB3 PPO on :data:`REFERENCE_ENV` with ``like_id``'s entry (module docstring)."""
    import gymnasium as gym
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

    from agents.training.config import build_hyperparameters, load_config, normalize_options, split_entry
    from agents.training.train import quiet_logger

    run, hyper = split_entry(with_n_envs(load_config(like_id, "ppo"), n_envs))
    policy = run.get("policy", "MlpPolicy")
    if policy != "MlpPolicy":
        raise ValueError(
            f"--reference-like: {like_id}'s entry uses policy {policy}; "
            "the reference takes an MlpPolicy entry"
        )
    n_envs = int(run.get("n_envs", 8))
    venv: Any = DummyVecEnv([lambda: gym.make(REFERENCE_ENV) for _ in range(n_envs)])
    venv.seed(seed)
    venv = VecMonitor(venv)
    norm = normalize_options(run.get("normalize"))
    if norm is not None:
        if norm.get("norm_reward") and "gamma" not in norm:
            norm["gamma"] = float(hyper.get("gamma", 0.99))  # as agents.training.train does
        venv = VecNormalize(venv, **norm)
    torch.set_num_threads(1)
    set_random_seed(seed)
    model = PPO(policy, venv, seed=seed, device="cpu", verbose=0, **build_hyperparameters(hyper))
    with tempfile.TemporaryDirectory() as folder:  # no SB3-<date> folder left in the temp directory
        model.set_logger(quiet_logger(folder, 0))
        model.learn(total_timesteps=timesteps)
    venv.close()


def warm_up(env_id: str) -> None:
    """Step ``env_id``'s native vector env once, so that the timed run loads no compiled kernels."""
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the ids

    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", eval_info=False)
    venv.reset(seed=0)
    venv.action_space.seed(0)
    for _ in range(2):
        venv.step(venv.action_space.sample())
    venv.close()


def navgym_run(env_id: str, timesteps: int, seed: int = SEED, n_envs: int | None = None) -> dict[str, Any]:
    """``navgym train``'s path for ``env_id`` (module docstring); its ``meta.json``."""
    from agents.training.config import load_config
    from agents.training.train import train

    config = None if n_envs is None else with_n_envs(load_config(env_id, "ppo"), n_envs)
    with tempfile.TemporaryDirectory(prefix="navgym-bench-train-") as tmp:
        out = train(
            env_id,
            "ppo",
            config=config,
            seed=seed,
            total_timesteps=timesteps,
            out_dir=Path(tmp) / "run",
            progress=False,
            torch_threads=1,
            tensorboard=False,
            eval_freq=0,
        )
        return json.loads((out / "meta.json").read_text())


def record(name: str, timing: LearnTiming, reference_rate: float | None) -> dict[str, Any]:
    """One JSON record (the reference's ratio is 1 by definition)."""
    rate = timing.timesteps / timing.learn_s
    return {
        "env": name,
        "vec_env": timing.wrappers[-1] + (" + residual" if "ResidualVecEnv" in timing.wrappers else ""),
        **timing.settings,
        "timesteps": timing.timesteps,
        "learn_s": timing.learn_s,
        "steps_per_s": rate,
        "ratio": 1.0 if reference_rate is None else rate / reference_rate,
        "shares": timing.shares(),
        "timing": asdict(timing),
    }


def row(rec: dict[str, Any]) -> list[object]:
    s = rec["shares"]
    return [
        rec["env"],
        rec["vec_env"],
        rec["n_envs"],
        f"{rec['timesteps']:,}",
        f"{rec['steps_per_s']:,.0f}",
        f"{rec['ratio']:.2f}",
        f"{100 * s['env']:.1f}",
        f"{100 * s['base_env']:.1f}",
        f"{100 * s['update']:.1f}",
        f"{100 * s['rollout_other']:.1f}",
    ]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--timesteps",
        type=int,
        default=DEFAULT_TIMESTEPS,
        help=f"environment steps per run (default {DEFAULT_TIMESTEPS}; SB3 rounds up to whole rollouts)",
    )
    parser.add_argument("--ids", nargs="+", default=list(DEFAULT_IDS), help="navgym ids to train")
    parser.add_argument(
        "--reference-like",
        default=REFERENCE_LIKE,
        help=f"the id whose PPO entry the {REFERENCE_ENV} reference uses (default {REFERENCE_LIKE})",
    )
    parser.add_argument(
        "--n-envs",
        type=int,
        default=None,
        help="sub-environments of every run, the reference's too, with the same rollout size "
        "(n_steps scaled; default: each entry's own)",
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="one rollout and one update per run (tests; overrides --timesteps)",
    )
    parser.add_argument("--out", default="results/bench", help="folder for train.json and train.md")
    add_threads_argument(parser)


def run(args: argparse.Namespace) -> int:
    timesteps = 1 if args.quick else int(args.timesteps)
    if timesteps < 1:
        raise ValueError(f"--timesteps must be >= 1; got {timesteps}")
    cores = check_threads(args.threads)  # model.learn is timed by the wall clock
    records: list[dict[str, Any]] = []
    metas: dict[str, dict[str, Any]] = {}
    with single_core(args.threads), timed_ppo() as runs:
        n_envs = args.n_envs
        reference_run(args.reference_like, 1, n_envs=n_envs)  # warm-up (torch's first passes), not reported
        reference_run(args.reference_like, timesteps, n_envs=n_envs)
        ref = record(f"{REFERENCE_ENV} (like {args.reference_like})", runs[-1], None)
        records.append(ref)
        print(f"  {ref['env']}: {ref['steps_per_s']:,.0f} steps/s", flush=True)
        for env_id in args.ids:
            warm_up(env_id)
            metas[env_id] = navgym_run(env_id, timesteps, n_envs=n_envs)
            rec = record(env_id, runs[-1], ref["steps_per_s"])
            rec["meta_steps_per_s"] = metas[env_id].get("steps_per_s")
            records.append(rec)
            print(
                f"  {env_id}: {rec['steps_per_s']:,.0f} steps/s ({rec['ratio']:.2f} x reference)", flush=True
            )
    caption = (
        f"PPO training throughput (SB3 PPO, zoo hyperparameters, one torch thread, "
        f"{cores}, seed {SEED}, "
        "wall clock): steps/s = timesteps / wall time of model.learn; ratio to the "
        f"{REFERENCE_ENV} reference (DummyVecEnv, the PPO entry of {args.reference_like}) in the same "
        "run; shares of the learn time: env = the vec env stack's step and reset, base env = of it "
        "the innermost env's step_wait and reset, update = PPO's gradient epochs, rollout other = "
        "policy forward, rollout buffer, callbacks."
    )
    table = format_table(HEADERS, [row(r) for r in records])
    print()
    print(caption)
    print(table)
    out = Path(args.out)
    path = write_json(
        out / "train.json",
        {
            "reference_env": REFERENCE_ENV,
            "reference_like": args.reference_like,
            "timesteps_asked": timesteps,
            "n_envs": n_envs,
            "threads": args.threads,
            "seed": SEED,
            "results": records,
        },
    )
    (out / "train.md").write_text(caption + "\n\n" + table + "\n")
    print(f"\nJSON written to {path} (markdown: {out / 'train.md'})")
    return 0
