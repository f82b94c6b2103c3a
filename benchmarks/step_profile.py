"""Where an environment step's time goes: microseconds per step by stage, on one core.

For each configuration ``ID:KIND:B`` (an env id, the shell that steps it and its batch) a run
of ``--steps`` steps with random actions (default: a whole episode and the step after it, so
the new episode's reset is in) is timed plain (the step time, no instrumentation) and with
explicit timers around the stages of the step, with the same seed and actions, the two
interleaved ``--repeats`` times and the fastest of each kept. Each stage is charged its own
time only (the time of the stages it calls is theirs), so the shares add up to the step:

=============  ==========================================================================
stage          what it times
=============  ==========================================================================
action         the action check and knob mapping (``NavCore.validate_action``, i.e. the
               task's ``knob``; the single env's shape check; the vector env checks once a step)
models         the platform's epoch: sensor inputs and models (``platform.step_models``)
filter         the filter's predict + update with the knob applied (``task.step`` inside
               ``NavCore._filter_step``, with its row isolation)
memory         the innovation memory of the v2/v3 observations (``memory_model.update``)
error          the position error against the truth (``platform.position_error``)
features       the observation's columns (``platform.feature_values``, ``task.feature_values``)
observation    stacking and clipping them into the observation (``FeatureSet.build``)
nees           the NEES (``eval_info`` only; off by default, as in training)
core           the rest of ``NavCore.advance``: divergence rules, reward, ``StepInfo``
info           the shell's view of ``info`` (``StepInfo.row`` / ``.vector`` / ``.sb3``)
autoreset      new episodes: ``NavCore.reset`` (the episode's simulation), the vector env's
               snapshot / restore, the single env's ``env.reset`` after an episode ends
shell          the rest: Gymnasium's wrappers (single env), the shells' copies and their
               per-sub-env loops (SB3's ``infos``)
=============  ==========================================================================

Kinds: ``single`` (``gym.make``, B = 1, with Gymnasium's wrappers), ``vector`` (the native
vector env, ``gym.make_vec(..., vectorization_mode="vector_entry_point")``) and ``sb3``
(:class:`navgym.envs.sb3.NavSB3VecEnv`, what ``navgym train`` steps). The timers wrap the
env's own objects (and, for the run, ``StepInfo``'s views and two module functions of
``navgym.envs``); nothing of navgym's code is changed. Each timed call (a dozen or so per
step) adds the timers' own small cost, spread over the stages; the plain and the instrumented
step times side by side show it. The stage times are the instrumented run's.

A last run under :mod:`cProfile` (:func:`benchmarks._calls.count_calls`) counts the calls per
step (Python functions, built-in functions and methods; not ufuncs, which it does not see) and
the calls into compiled Numba kernels with the time inside them: where the kernels' time is a
small part of the plain step, the step is bound by its calls, not by its arithmetic. That run
is on one thread whatever ``--threads`` (the profiler sees the calling thread only).

    navgym bench step_profile [--configs ID:KIND:B ...] [--steps N] [--repeats 3] [--eval-info]
                              [--clock wall|cpu] [--json results/bench/step_profile.json]
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from benchmarks._calls import count_calls
from benchmarks._timing import (
    CLOCKS,
    add_clock_argument,
    add_threads_argument,
    check_threads,
    single_core,
    write_json,
)
from filters.core.threads import num_threads
from navgym.tables import format_table

#: The stages, in table order, with what each times (module docstring).
STAGES: dict[str, str] = {
    "action": "action check, knob mapping",
    "models": "platform step models (sensors)",
    "filter": "filter predict + update",
    "memory": "innovation memory features",
    "error": "position error (truth)",
    "features": "feature values",
    "observation": "observation build (stack, clip)",
    "nees": "NEES (eval_info)",
    "core": "core: ends, reward, StepInfo",
    "info": "info view",
    "autoreset": "autoreset: new episodes",
    "shell": "shell: wrappers, copies",
}
#: Stages that may hold other stages' calls (their own time is what is left); every other
#: stage keeps the whole time of its call (e.g. a reset's observation build is autoreset's).
OPEN_STAGES = frozenset({"shell", "core"})
KINDS = ("single", "vector", "sb3")
DEFAULT_CONFIGS = (
    "navgym/GpsInsFading-v2:single:1",
    "navgym/GpsInsFading-v2:vector:16",
    "navgym/GpsInsFading-v2:sb3:16",
    "navgym/Robot2dRowScale-v3:vector:16",
)


@dataclass(frozen=True)
class Config:
    """One profiled configuration: env id, shell kind, batch B."""

    env_id: str
    kind: str
    B: int

    @property
    def label(self) -> str:
        return f"{self.env_id}:{self.kind}:{self.B}"


def parse_config(text: str) -> Config:
    """``"ID:KIND:B"`` -> :class:`Config` (``ValueError`` naming ``--configs``)."""
    parts = str(text).rsplit(":", 2)
    if len(parts) != 3:
        raise ValueError(f"--configs: {text!r} is not ID:KIND:B (e.g. navgym/GpsInsFading-v2:vector:16)")
    env_id, kind, b = parts
    if kind not in KINDS:
        raise ValueError(f"--configs: kind {kind!r} of {text!r} is not one of {list(KINDS)}")
    try:
        B = int(b)
    except ValueError:
        raise ValueError(f"--configs: batch {b!r} of {text!r} is not an integer") from None
    if B < 1:
        raise ValueError(f"--configs: batch of {text!r} must be >= 1; got {B}")
    if kind == "single" and B != 1:
        raise ValueError(f"--configs: a single env has B = 1; got {text!r}")
    return Config(env_id, kind, B)


def _config_arg(text: str) -> Config:
    try:
        return parse_config(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


class StageTimer:
    """Accumulates each stage's own time (its calls' time minus that of stages inside them)."""

    def __init__(self, now: Callable[[], float]) -> None:
        self.now = now
        self.seconds: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self.calls: dict[str, int] = dict.fromkeys(STAGES, 0)
        self._stack: list[list[Any]] = []  # [stage, time of the stages inside it]

    def call(self, stage: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """``fn(*args, **kwargs)``, timed as ``stage`` (untimed inside a closed stage)."""
        stack = self._stack
        if stack and stack[-1][0] not in OPEN_STAGES:
            return fn(*args, **kwargs)
        now = self.now
        frame: list[Any] = [stage, 0.0]
        stack.append(frame)
        t0 = now()
        try:
            return fn(*args, **kwargs)
        finally:
            dt = now() - t0
            stack.pop()
            self.seconds[stage] += dt - frame[1]
            self.calls[stage] += 1
            if stack:
                stack[-1][1] += dt

    def wrap(self, stage: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn`` timed as ``stage`` (a plain function: as a class attribute it binds ``self``)."""

        def timed(*args: Any, **kwargs: Any) -> Any:
            return self.call(stage, fn, *args, **kwargs)

        timed.__wrapped__ = fn  # type: ignore[attr-defined]
        return timed

    @property
    def total(self) -> float:
        return sum(self.seconds.values())


@contextlib.contextmanager
def instrumented(core: Any, timer: StageTimer) -> Iterator[None]:
    """Timers around the stages of ``core``'s steps (module docstring), removed on exit.

    Instance attributes shadow the methods of the core, its platform, task, feature set and
    memory model (``object.__setattr__``: the platforms are frozen dataclasses);
    ``StepInfo``'s views and ``navgym.envs.core._nees`` / ``navgym.envs.base.check_single_shape``
    are replaced for the duration.
    """
    from navgym.envs import base
    from navgym.envs import core as core_module
    from navgym.envs.step_info import StepInfo

    undo: list[Callable[[], None]] = []

    def on_instance(obj: Any, attr: str, stage: str) -> None:
        object.__setattr__(obj, attr, timer.wrap(stage, getattr(obj, attr)))
        undo.append(lambda: object.__delattr__(obj, attr))

    def on_owner(owner: Any, attr: str, stage: str) -> None:
        original = owner.__dict__[attr]
        setattr(owner, attr, timer.wrap(stage, original))
        undo.append(lambda: setattr(owner, attr, original))

    try:
        for attr, stage in [
            ("validate_action", "action"),
            ("advance", "core"),
            ("_filter_step", "filter"),
            ("reset", "autoreset"),
            ("snapshot", "autoreset"),
            ("restore", "autoreset"),
        ]:
            on_instance(core, attr, stage)
        for attr, stage in [
            ("step_models", "models"),
            ("position_error", "error"),
            ("feature_values", "features"),
        ]:
            on_instance(core.platform, attr, stage)
        on_instance(core.task, "feature_values", "features")
        on_instance(core.obs_features, "build", "observation")
        if core.memory_model is not None:
            on_instance(core.memory_model, "update", "memory")
        on_owner(core_module, "_nees", "nees")
        on_owner(base, "check_single_shape", "action")
        for attr in ("row", "vector", "sb3", "as_dict"):
            on_owner(StepInfo, attr, "info")
        yield
    finally:
        for fn in reversed(undo):
            fn()


@dataclass
class _Shell:
    """A configuration's env as the profile drives it."""

    core: Any
    step: Callable[[Any], bool]  # one step; True when a single env must be reset
    reset: Callable[[int | None], None]
    close: Callable[[], None]
    T: int


def _make(cfg: Config, eval_info: bool) -> _Shell:
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the ids
    from navgym.envs.base import navigation_env

    if cfg.kind == "single":
        env = gym.make(cfg.env_id, eval_info=eval_info)

        def step(a: Any) -> bool:
            _, _, term, trunc, _ = env.step(a)
            return bool(term or trunc)

        def reset(seed: int | None) -> None:
            env.reset(seed=seed)

        core = navigation_env(env).core
        return _Shell(core, step, reset, env.close, int(core.truncate_steps))
    if cfg.kind == "vector":
        venv = gym.make_vec(
            cfg.env_id, num_envs=cfg.B, vectorization_mode="vector_entry_point", eval_info=eval_info
        )

        def vstep(a: Any) -> bool:
            venv.step(a)
            return False

        def vreset(seed: int | None) -> None:
            venv.reset(seed=seed)

        core = navigation_env(venv).core
        return _Shell(core, vstep, vreset, venv.close, int(core.truncate_steps))
    from navgym.envs.sb3 import NavSB3VecEnv

    senv = NavSB3VecEnv(cfg.env_id, num_envs=cfg.B, eval_info=eval_info)

    def sstep(a: Any) -> bool:
        senv.step(a)
        return False

    def sreset(seed: int | None) -> None:
        if seed is not None:
            senv.seed(seed)
        senv.reset()

    return _Shell(senv.core, sstep, sreset, senv.close, int(senv.core.truncate_steps))


def _actions(core: Any, cfg: Config, n: int) -> list[Any]:
    """``n`` random actions (seeded): single-env actions, or ``(B, ...)`` batches."""
    space = core.action_space
    space.seed(0)
    if cfg.kind == "single":
        return [space.sample() for _ in range(n)]
    return [np.stack([space.sample() for _ in range(cfg.B)]) for _ in range(n)]


def profile(
    cfg: Config, steps: int | None, eval_info: bool, now: Callable[[], float], repeats: int = 1
) -> dict[str, Any]:
    """The plain and the instrumented runs of ``cfg``, the fastest of ``repeats`` each; a JSON record.

    See the module docstring for the stages.
    """
    if repeats < 1:
        raise ValueError(f"--repeats must be >= 1; got {repeats}")
    shell = _make(cfg, eval_info)
    try:
        n = shell.T + 1 if steps is None else int(steps)
        if n < 1:
            raise ValueError(f"--steps must be >= 1; got {n}")
        actions = _actions(shell.core, cfg, n)
        shell.reset(0)  # warm-up: caches, lazy imports, Gymnasium's first-step checks
        for a in actions[:3]:
            if shell.step(a):
                shell.reset(None)

        def run_all() -> None:  # the plain run: every action, a single env reset when it ends
            for a in actions:
                if shell.step(a):
                    shell.reset(None)

        plain, timer = np.inf, None
        for _ in range(repeats):  # plain and instrumented runs interleaved; the fastest of each kept
            shell.reset(0)
            t0 = now()
            run_all()
            plain = min(plain, now() - t0)

            shell.reset(0)
            this = StageTimer(now)
            with instrumented(shell.core, this):
                for a in actions:
                    if this.call("shell", shell.step, a):
                        this.call("autoreset", shell.reset, None)
            if timer is None or this.total < timer.total:
                timer = this
        shell.reset(0)
        with num_threads(1):  # the profiler sees the calling thread only
            counted = count_calls(run_all)
    finally:
        shell.close()
    assert timer is not None
    total = timer.total
    stages = {
        s: {
            "us_per_step": 1e6 * timer.seconds[s] / n,
            "share": timer.seconds[s] / total if total > 0 else float("nan"),
            "calls": timer.calls[s],
        }
        for s in STAGES
    }
    return {
        "env": cfg.env_id,
        "kind": cfg.kind,
        "B": cfg.B,
        "steps": n,
        "repeats": repeats,
        "eval_info": eval_info,
        "plain_us_per_step": 1e6 * plain / n,
        "instrumented_us_per_step": 1e6 * total / n,
        "env_steps_per_s": cfg.B * n / plain,
        "stages": stages,
        "calls_per_step": counted.calls / n,
        "kernel_calls_per_step": counted.kernel_calls / n,
        "kernel_us_per_step": 1e6 * counted.kernel_seconds / n,
        "profiled_us_per_step": 1e6 * counted.seconds / n,
    }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--configs",
        nargs="+",
        type=_config_arg,
        default=[parse_config(c) for c in DEFAULT_CONFIGS],
        metavar="ID:KIND:B",
        help=f"env id, shell ({', '.join(KINDS)}) and batch; default {' '.join(DEFAULT_CONFIGS)}",
    )
    parser.add_argument(
        "--steps",
        type=int,
        default=None,
        help="steps per run (default: the episode's steps + 1, so one autoreset is in)",
    )
    parser.add_argument(
        "--repeats", type=int, default=3, help="runs of each kind, the fastest kept (default 3)"
    )
    parser.add_argument("--eval-info", action="store_true", help="compute the NEES (training: off)")
    parser.add_argument("--json", default="results/bench/step_profile.json", help="where to write JSON")
    add_clock_argument(parser)
    add_threads_argument(parser)


def stage_table(rec: dict[str, Any]) -> str:
    """One configuration's table: stage, microseconds per step, share, calls."""
    rows = [
        [name, what, f"{v['us_per_step']:,.1f}", f"{100 * v['share']:.1f}%", v["calls"]]
        for (name, what), v in zip(STAGES.items(), rec["stages"].values(), strict=True)
    ]
    rows.append(["total", "instrumented step", f"{rec['instrumented_us_per_step']:,.1f}", "100.0%", ""])
    return format_table(["stage", "what", "us / step", "share", "calls"], rows)


def run(args: argparse.Namespace) -> int:
    if args.steps is not None and args.steps < 1:
        raise ValueError(f"--steps must be >= 1; got {args.steps}")
    if args.repeats < 1:
        raise ValueError(f"--repeats must be >= 1; got {args.repeats}")
    cores = check_threads(args.threads, args.clock)
    now = CLOCKS[args.clock]
    records = []
    with single_core(args.threads):
        for cfg in args.configs:
            rec = profile(cfg, args.steps, args.eval_info, now, args.repeats)
            records.append(rec)
            print(
                f"  {cfg.label}: {rec['steps']} steps, {rec['plain_us_per_step']:,.1f} us per step plain, "
                f"{rec['instrumented_us_per_step']:,.1f} instrumented",
                flush=True,
            )
    print()
    print(
        f"Per-step profile ({cores}, random actions, {args.clock} clock, eval_info "
        f"{'on' if args.eval_info else 'off'}): microseconds per env step (all B sub-envs) by stage, "
        "each stage its own time; the step of a run of whole episodes, resets included."
    )
    summary = [
        [
            r["env"],
            r["kind"],
            r["B"],
            r["steps"],
            f"{r['plain_us_per_step']:,.1f}",
            f"{r['instrumented_us_per_step']:,.1f}",
            f"{r['env_steps_per_s']:,.0f}",
        ]
        for r in records
    ]
    print(
        format_table(
            ["env", "kind", "B", "steps", "us / step (plain)", "us / step (instrumented)", "env-steps/s"],
            summary,
        )
    )
    print(
        "\nCalls per step (one more run under cProfile, one thread): Python functions, built-in "
        "functions and methods (NumPy's array functions and methods; not ufuncs such as "
        "np.maximum, which the profiler does not see), and the calls into compiled Numba kernels "
        "with their time (dispatch included; the profiler does not slow a compiled loop). Where "
        "the kernels' time is a small part of the plain step, the step is bound by its calls, "
        "not by its arithmetic."
    )
    print(
        format_table(
            [
                "env",
                "kind",
                "B",
                "calls / step",
                "kernel calls / step",
                "kernel us / step",
                "us / step (plain)",
            ],
            [
                [
                    r["env"],
                    r["kind"],
                    r["B"],
                    f"{r['calls_per_step']:,.0f}",
                    f"{r['kernel_calls_per_step']:,.1f}",
                    f"{r['kernel_us_per_step']:,.1f}",
                    f"{r['plain_us_per_step']:,.1f}",
                ]
                for r in records
            ],
        )
    )
    for r in records:
        print(f"\n{r['env']}, {r['kind']}, B = {r['B']}:")
        print(stage_table(r))
    meta = {"clock": args.clock, "threads": args.threads, "stages": STAGES}
    path = write_json(args.json, {**meta, "results": records})
    print(f"\nJSON written to {path}")
    return 0
