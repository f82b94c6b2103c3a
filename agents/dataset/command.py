"""``navgym dataset ID --policy SPEC --episodes N --out DIR [--seed-offset K]``: a Minari dataset.

Rolls out one policy (a spec of ``navgym eval --policies``: a baseline name, ``NAME:k=v,...``,
``[LABEL=]ALGO:PATH``) on a single ``gym.make`` env, one episode per seed, and writes the episodes
through Minari's own API (``minari.create_dataset_from_buffers``): observations, actions,
rewards, terminations, truncations and the step infos (the truth metrics such as ``pos_err_m``).
Each episode's reset seed is stored with it (``EpisodeData.seed`` / the episode metadata).
The seeds are the tuning seeds by default (``agents.seeds.seeds("tune", N, K)``), never the
held-out evaluation seeds. Minari's data lie under ``--out`` (``MINARI_DATASETS_PATH`` is set
to it), nothing goes to the user's home; load with
``MINARI_DATASETS_PATH=DIR python -c "import minari; minari.load_dataset('navgym/ID-LABEL-v0')"``.
"""

from __future__ import annotations

import argparse
import os
import re
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.seeds import check_seeds, seeds


def _stack_infos(infos: Sequence[Mapping[str, Any]]) -> dict[str, np.ndarray]:
    """Numeric step infos, one array per key of every step (the reset entry NaN where it lacks it)."""
    steps = infos[1:]
    keys = [k for k in steps[0] if all(k in i for i in steps)] if steps else []
    out = {}
    for k in keys:
        try:
            arr = np.asarray([i[k] for i in steps], dtype=np.float64)
        except (TypeError, ValueError):
            continue
        first = np.asarray(infos[0].get(k, np.full(arr.shape[1:], np.nan)), dtype=np.float64)
        if first.shape == arr.shape[1:]:
            out[k] = np.concatenate([first[None], arr])
    return out


def rollout(env: Any, policy: Any, seed: int) -> dict[str, Any]:
    """One episode of ``policy`` (SB3 ``predict``, batch of one) on ``env`` from ``reset(seed)``."""
    obs, info = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset()
    observations, actions, rewards, terms, truncs, infos = [obs], [], [], [], [], [info]
    state, start, done = None, np.ones(1, dtype=bool), False
    while not done:
        act, state = policy.predict(obs[None], state=state, episode_start=start, deterministic=True)
        start = np.zeros(1, dtype=bool)
        action = np.asarray(act)[0]
        obs, reward, terminated, truncated, info = env.step(action)
        observations.append(obs)
        actions.append(action)
        rewards.append(float(reward))
        terms.append(bool(terminated))
        truncs.append(bool(truncated))
        infos.append(info)
        done = terminated or truncated
    return {
        "observations": np.asarray(observations),
        "actions": np.asarray(actions),
        "rewards": np.asarray(rewards),
        "terminations": np.asarray(terms),
        "truncations": np.asarray(truncs),
        "infos": _stack_infos(infos),
    }


def dataset_id(env_id: str, label: str) -> str:
    """Minari's ``namespace/name-vK`` id of a dataset of ``label`` on ``env_id``."""
    name = re.sub(r"[^A-Za-z0-9_]+", "_", label).strip("_") or "policy"
    return f"navgym/{env_id.removeprefix('navgym/')}-{name}-v0"


def write_dataset(
    env_id: str,
    policy_spec: str,
    episodes: int,
    out: str | Path,
    *,
    seed_offset: int = 0,
    seed_list: Sequence[int] | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    trust: bool = False,
) -> Any:
    """Write and return the Minari dataset of ``episodes`` episodes of ``policy_spec`` on ``env_id``.

    Seeds: ``seed_list`` if given (never evaluation seeds), else the tuning seeds from
    ``seed_offset``. ``out`` receives Minari's data (``MINARI_DATASETS_PATH``).
    """
    import gymnasium as gym
    import minari
    from minari.data_collector.episode_buffer import EpisodeBuffer

    import navgym  # noqa: F401
    from agents.baselines.registry import load_tuned
    from agents.evaluation.cli import parse_policies

    run_seeds = list(seed_list) if seed_list is not None else seeds("tune", episodes, seed_offset)
    check_seeds("tune", run_seeds) if seed_list is None else _not_eval(run_seeds)
    kwargs = dict(env_kwargs or {})
    policies = parse_policies(
        [policy_spec], env_id, kwargs, load_tuned(env_id) if not kwargs else {}, trust=trust
    )
    if len(policies) != 1:
        raise ValueError(f"--policy takes one policy; {policy_spec!r} gives {sorted(policies)}")
    ((label, policy),) = policies.items()
    if not hasattr(policy, "predict"):
        raise ValueError(f"{policy_spec!r} is not a predict policy (oracles need the batched evaluation)")
    Path(out).mkdir(parents=True, exist_ok=True)
    os.environ["MINARI_DATASETS_PATH"] = str(Path(out).resolve())
    env = gym.make(env_id, **kwargs)
    buffers = []
    for i, seed in enumerate(run_seeds):
        ep = rollout(env, policy, seed)
        buffers.append(EpisodeBuffer(id=i, seed=seed, **ep))
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=UserWarning, module="minari")
        ds = minari.create_dataset_from_buffers(
            dataset_id=dataset_id(env_id, label),
            buffer=buffers,
            env=env,
            algorithm_name=policy_spec,
            author="navgym dataset",
            description=f"{len(run_seeds)} episodes of {policy_spec} on {env_id} "
            f"(env kwargs {kwargs}), seeds {run_seeds}",
        )
    env.close()
    return ds


def _not_eval(values: Sequence[int]) -> None:
    from agents.seeds import EVAL_START

    bad = [s for s in values if int(s) >= EVAL_START]
    if bad:
        raise ValueError(
            f"seeds {bad[:5]} are held-out evaluation seeds (>= {EVAL_START}); use tuning or training seeds"
        )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("env_id", help="registered env id")
    parser.add_argument("--policy", required=True, help="one policy spec of navgym eval --policies")
    parser.add_argument("--episodes", type=int, default=10, help="number of episodes (default 10)")
    parser.add_argument("--out", required=True, help="folder of Minari's data (MINARI_DATASETS_PATH)")
    parser.add_argument("--seed-offset", type=int, default=0, help="offset into the tuning seeds")
    parser.add_argument("--seeds", type=int, nargs="+", help="explicit reset seeds (not evaluation seeds)")
    parser.add_argument("--env-kwargs", default=None, help="env keyword arguments (as navgym eval)")
    parser.add_argument("--trust", action="store_true", help="allow SB3's own loader (as navgym eval)")


def run(args: argparse.Namespace) -> int:
    from agents.evaluation.cli import parse_env_kwargs

    kwargs = parse_env_kwargs(args.env_kwargs) if args.env_kwargs else {}
    ds = write_dataset(
        args.env_id,
        args.policy,
        args.episodes,
        args.out,
        seed_offset=args.seed_offset,
        seed_list=args.seeds,
        env_kwargs=kwargs,
        trust=args.trust,
    )
    print(
        f"wrote {ds.spec.dataset_id} ({ds.total_episodes} episodes, {ds.total_steps} steps) under {args.out}"
    )
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym dataset`` to the ``navgym`` command line."""
    parser = subparsers.add_parser("dataset", help="write a Minari dataset of episodes of one policy")
    add_arguments(parser)
    parser.set_defaults(_run=run)
