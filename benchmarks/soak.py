"""Soak test: step a native vector env for many env-steps and count what went wrong.

``navgym soak ID [ID ...] --steps N [--num-envs B] [--seed S] [--all] [--json PATH]`` runs the
native batched vector env of each id (``gym.make_vec(..., vectorization_mode=
"vector_entry_point")``, the id's default arguments) for N env-steps (``ceil(N / B)`` calls of
``step``) with random valid actions drawn from its seeded action space, and counts:

* non-finite observations and rewards (env-steps whose observation row, or whose reward, has a
  NaN or inf), and observations outside the observation space's bounds;
* exceptions raised by ``step``, by type: each is caught, the env is reset (seed ``S + call``)
  and the run goes on;
* episodes (terminated or truncated rows) and divergences (``info["diverged"]``);
* warnings raised inside ``step``, by category (printed under the table);
* resident memory (``/proc/self/statm``, ``resource`` elsewhere) after a warm-up of
  ``--warmup`` of the steps (default 10 %) and at the end, after a garbage collection each: the
  growth between the two is what the run leaked (episode arrays reallocated at autoreset come
  and go; a leak grows with the steps). The JSON also holds ``rss_samples``, ``(env-steps,
  MB)`` at every tenth of the run, which tell a one-off step (a new episode's arrays allocated
  before the old ones are freed) from a steady climb.

It prints one table row per id (and a progress bar on a terminal for runs of more than a few
seconds) and writes the figures as JSON (``--json``). ``--all`` soaks every registered navgym
id; ``--max-seconds`` stops an id early and reports the steps it did. Allocator tuning
(:func:`navgym.tune_malloc`) is off unless ``--tune-malloc`` is given, so the memory figures are
those of the library's default process. Also reachable as ``navgym bench soak``.

    navgym soak navgym/Robot2dFading-v1 --steps 200000 --num-envs 256
    navgym soak --all --steps 200000 --num-envs 256 --max-seconds 60 --json results/soak.json
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import resource
import sys
import time
import warnings
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

#: Default batch of the native vector env.
DEFAULT_NUM_ENVS = 64
#: Fraction of the steps run before the first memory sample.
DEFAULT_WARMUP = 0.1
#: Resident memory is also sampled at this many evenly spaced points (the JSON's ``rss_samples``).
RSS_SAMPLES = 10
#: A progress bar is shown on a terminal when the run is expected to take longer than this.
PROGRESS_AFTER_S = 3.0


def rss_bytes() -> int:
    """Resident set size of this process in bytes (``/proc/self/statm``; peak RSS elsewhere)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return int(peak) * (1 if sys.platform == "darwin" else 1024)


def navgym_ids() -> list[str]:
    """Every registered ``navgym/`` id, in registration order."""
    import gymnasium as gym

    import navgym  # noqa: F401  (registers the ids)

    return [k for k in gym.registry if k.startswith("navgym/")]


@dataclass
class SoakResult:
    """The figures of one soak run (see the module docstring)."""

    env_id: str
    num_envs: int
    seed: int
    steps_requested: int
    env_steps: int = 0
    calls: int = 0
    episodes: int = 0
    terminations: int = 0
    truncations: int = 0
    divergences: int = 0
    nonfinite_obs: int = 0
    nonfinite_rewards: int = 0
    obs_out_of_bounds: int = 0
    exceptions: dict[str, int] = field(default_factory=dict)
    exception_messages: dict[str, str] = field(default_factory=dict)
    warnings: dict[str, int] = field(default_factory=dict)
    warning_messages: dict[str, str] = field(default_factory=dict)
    rss_warm_mb: float = 0.0
    rss_end_mb: float = 0.0
    rss_growth_mb: float = 0.0
    rss_samples: list[tuple[int, float]] = field(default_factory=list)
    warmup_env_steps: int = 0
    seconds: float = 0.0
    env_steps_per_s: float = 0.0
    stopped_early: bool = False
    aborted: bool = False

    @property
    def n_exceptions(self) -> int:
        return sum(self.exceptions.values())

    def clean(self) -> bool:
        """No non-finite value, no observation outside its box, no exception."""
        return (
            self.nonfinite_obs == 0
            and self.nonfinite_rewards == 0
            and self.obs_out_of_bounds == 0
            and self.n_exceptions == 0
        )


def _memory_mb() -> float:
    gc.collect()
    return rss_bytes() / 2**20


def soak(
    env_id: str,
    steps: int,
    num_envs: int = DEFAULT_NUM_ENVS,
    seed: int = 0,
    warmup: float = DEFAULT_WARMUP,
    max_seconds: float | None = None,
    progress: bool | None = None,
    env_kwargs: dict | None = None,
) -> SoakResult:
    """Soak ``env_id``'s native vector env for ``steps`` env-steps (module docstring).

    Args:
        env_id: a registered id.
        steps: env-steps to run (rounded up to whole calls of ``num_envs``).
        num_envs: batch of the native vector env.
        seed: seed of ``reset`` (sub-env i gets ``seed + i``) and of the action space.
        warmup: fraction of the calls before the first memory sample (at least one call).
        max_seconds: stop after this many seconds of stepping (``stopped_early``).
        progress: show a progress bar; None shows one on a terminal for long runs.
        env_kwargs: keyword arguments of ``gym.make_vec`` (variants of the id).

    Returns:
        The :class:`SoakResult`.
    """
    import gymnasium as gym

    import navgym  # noqa: F401  (registers the ids)
    from navgym.envs.registration import superseded_ids_quiet

    if steps < 1 or num_envs < 1:
        raise ValueError(f"steps and num_envs must be >= 1; got {steps}, {num_envs}")
    if not 0.0 <= warmup < 1.0:
        raise ValueError(f"warmup must lie in [0, 1); got {warmup}")
    result = SoakResult(env_id, num_envs, seed, steps)
    with superseded_ids_quiet():
        env = gym.make_vec(
            env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **(env_kwargs or {})
        )
    space = env.single_observation_space
    low = np.asarray(getattr(space, "low", -np.inf))
    high = np.asarray(getattr(space, "high", np.inf))
    calls = math.ceil(steps / num_envs)
    warm_call = max(1, min(calls - 1, round(warmup * calls))) if calls > 1 else 0
    sample_calls = {round(calls * i / RSS_SAMPLES) for i in range(RSS_SAMPLES)} | {warm_call}
    exceptions: Counter[str] = Counter()
    caught_warnings: Counter[str] = Counter()
    messages: dict[str, str] = {}
    warning_messages: dict[str, str] = {}

    def caught(exc: Exception, where: str) -> None:
        name = type(exc).__name__ + where
        exceptions[name] += 1
        messages.setdefault(name, " ".join(str(exc).split())[:300])

    env.reset(seed=seed)
    env.action_space.seed(seed)
    bar = None
    t0 = time.perf_counter()
    try:
        for k in range(calls):
            if k == warm_call:
                result.rss_warm_mb = _memory_mb()
                result.warmup_env_steps = result.env_steps
            if k in sample_calls:
                result.rss_samples.append((result.env_steps, _memory_mb()))
            actions = env.action_space.sample()
            result.calls += 1
            result.env_steps += num_envs
            out, seen = _guarded_step(env, actions, seed + k + 1, caught)
            if seen is None:  # a reset that fails too ends this id's run
                result.aborted = True
                break
            for w in seen:
                name = w.category.__name__
                caught_warnings[name] += 1
                warning_messages.setdefault(name, f"{w.message} ({os.path.basename(w.filename)}:{w.lineno})")
            if out is not None:
                _count(result, *out, low, high)
            elapsed = time.perf_counter() - t0
            if bar is None and k == 0 and _show_progress(progress, elapsed * calls):
                from tqdm import tqdm

                bar = tqdm(total=calls * num_envs, desc=env_id, unit="env-step", unit_scale=True, leave=False)
            if bar is not None:
                bar.update(num_envs)
            if max_seconds is not None and elapsed > max_seconds and k + 1 < calls:
                result.stopped_early = True
                break
        result.seconds = time.perf_counter() - t0
        if result.calls <= warm_call:  # stopped before the warm-up ended: no warm sample yet
            result.warmup_env_steps = result.env_steps
            result.rss_warm_mb = _memory_mb()
        result.rss_end_mb = _memory_mb()  # with the env alive: what it holds counts
        result.rss_samples.append((result.env_steps, result.rss_end_mb))
    finally:
        result.seconds = result.seconds or time.perf_counter() - t0
        if bar is not None:
            bar.close()
        env.close()
    result.rss_growth_mb = result.rss_end_mb - result.rss_warm_mb
    result.env_steps_per_s = result.env_steps / max(result.seconds, 1e-9)
    result.exceptions = dict(exceptions)
    result.exception_messages = messages
    result.warnings = dict(caught_warnings)
    result.warning_messages = warning_messages
    return result


def _guarded_step(
    env, actions, reset_seed: int, caught: Callable[[Exception, str], None]
) -> tuple[tuple | None, list[warnings.WarningMessage] | None]:
    """One ``env.step`` with its warnings recorded; an exception is counted and the env reset.

    Returns:
        The step's ``(obs, reward, terminated, truncated, info)`` (None if it raised) and the
        warnings it emitted; None for the warnings if the reset after an exception raised too.
    """
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        try:
            return env.step(actions), seen
        except Exception as exc:  # counted by type; the run goes on from a reset
            caught(exc, "")
            try:
                env.reset(seed=reset_seed)
            except Exception as exc2:
                caught(exc2, " (in reset)")
                return None, None
    return None, seen


def _count(result: SoakResult, obs, reward, terminated, truncated, info, low, high) -> None:
    """Add one step's figures to ``result``."""
    B = result.num_envs
    obs = np.asarray(obs)
    finite = np.isfinite(obs).reshape(B, -1).all(axis=1)
    result.nonfinite_obs += int((~finite).sum())
    result.nonfinite_rewards += int((~np.isfinite(np.asarray(reward, dtype=np.float64))).sum())
    inside = ((obs >= low) & (obs <= high)).reshape(B, -1).all(axis=1)
    result.obs_out_of_bounds += int((finite & ~inside).sum())
    term, trunc = np.asarray(terminated, bool), np.asarray(truncated, bool)
    result.terminations += int(term.sum())
    result.truncations += int(trunc.sum())
    result.episodes += int((term | trunc).sum())
    if "diverged" in info:
        valid = np.asarray(info.get("_diverged", True), bool)
        result.divergences += int((np.asarray(info["diverged"], bool) & valid).sum())


def _show_progress(progress: bool | None, expected_s: float) -> bool:
    if progress is not None:
        return progress
    return sys.stderr.isatty() and expected_s > PROGRESS_AFTER_S


HEADERS = [
    "id",
    "B",
    "env-steps",
    "episodes",
    "diverged",
    "non-finite obs",
    "non-finite reward",
    "obs out of box",
    "exceptions",
    "RSS warm MB",
    "RSS growth MB",
    "env-steps/s",
    "s",
]


def table_row(r: SoakResult) -> list[object]:
    """One row of the printed table."""
    exc = ", ".join(f"{k} x{v}" for k, v in sorted(r.exceptions.items())) or "0"
    steps = f"{r.env_steps:,}" + (" (time limit)" if r.stopped_early else "")
    return [
        r.env_id,
        r.num_envs,
        steps,
        f"{r.episodes:,}",
        f"{r.divergences:,}",
        r.nonfinite_obs,
        r.nonfinite_rewards,
        r.obs_out_of_bounds,
        exc,
        f"{r.rss_warm_mb:.0f}",
        f"{r.rss_growth_mb:+.1f}",
        f"{r.env_steps_per_s:,.0f}",
        f"{r.seconds:.1f}",
    ]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("ids", nargs="*", metavar="ID", help="environment ids (or --all)")
    parser.add_argument("--all", action="store_true", help="soak every registered navgym id")
    parser.add_argument("--steps", type=int, default=10_000, help="env-steps per id (default 10000)")
    parser.add_argument(
        "--num-envs", type=int, default=DEFAULT_NUM_ENVS, help=f"native batch B (default {DEFAULT_NUM_ENVS})"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of reset and of the random actions")
    parser.add_argument(
        "--warmup",
        type=float,
        default=DEFAULT_WARMUP,
        help="fraction of the steps before the first memory sample (default 0.1)",
    )
    parser.add_argument("--max-seconds", type=float, default=None, help="stop an id after this many seconds")
    parser.add_argument("--json", default=None, help="write the figures to this JSON file")
    parser.add_argument("--tune-malloc", action="store_true", help="call navgym.tune_malloc() first")
    bar = parser.add_mutually_exclusive_group()
    bar.add_argument("--progress", dest="progress", action="store_true", default=None, help="progress bar")
    bar.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Soak the ids, print the table, write the JSON; exit status 1 when a run was not clean."""
    from navgym.tables import format_table

    if args.tune_malloc:
        import navgym

        navgym.tune_malloc()
    ids = navgym_ids() if args.all else list(args.ids)
    if not ids:
        raise ValueError("name at least one environment id, or --all")
    known = set(navgym_ids())
    unknown = [i for i in ids if i not in known]
    if unknown:
        raise ValueError(f"unknown environment ids {unknown}; `navgym list` prints them")
    results = []
    for env_id in ids:
        r = soak(
            env_id,
            args.steps,
            num_envs=args.num_envs,
            seed=args.seed,
            warmup=args.warmup,
            max_seconds=args.max_seconds,
            progress=args.progress,
        )
        results.append(r)
        print(f"  {env_id}: {r.env_steps:,} env-steps in {r.seconds:.1f} s", flush=True)
    print()
    warm = f"{args.warmup:.0%}"
    print(f"Soak: random valid actions, seed {args.seed}; RSS growth from after {warm} of the steps")
    print(format_table(HEADERS, [table_row(r) for r in results]))
    for r in results:
        for name, msg in r.exception_messages.items():
            print(f"{r.env_id}: {name}: {msg}")
        for name, count in sorted(r.warnings.items()):
            print(f"{r.env_id}: {name} x{count} in step, first: {r.warning_messages[name]}")
    if args.json:
        from benchmarks._timing import write_json

        path = write_json(
            args.json,
            {"soak": [{**asdict(r), "n_exceptions": r.n_exceptions, "clean": r.clean()} for r in results]},
        )
        print(f"\nJSON written to {path}")
    return 0 if all(r.clean() for r in results) else 1


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``soak`` to the ``navgym`` command's sub-parsers (entry point ``navgym.commands``)."""
    parser = subparsers.add_parser(
        "soak", help="step envs with random actions; count NaNs, exceptions, divergences, RSS growth"
    )
    add_arguments(parser)
    parser.set_defaults(_run=run)
