"""Regenerate docs/benchmarks.md: every benchmark at quick settings, one current table each.

``python -m benchmarks.report`` (or ``navgym bench report``, ``make bench-report``) runs each
benchmark of :data:`ENTRIES` as the command the page shows (``navgym bench <target> ...``;
its JSON goes where that command writes it, ``results/bench/``) and rewrites the page: the
machine (CPU model, cores, Python, NumPy, SciPy, Numba, the BLAS that threadpoolctl finds),
then per benchmark one line on what it measures, the exact command and the tables it printed.
The page holds the current figures only; rerun the command to refresh it. The settings are
chosen so that the whole report takes a few minutes on a 2-core machine; each benchmark's own
defaults (``navgym bench <target> --help``) measure more.

    python -m benchmarks.report [--out docs/benchmarks.md] [--only filters particles ...]
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import os
import platform
import shlex
import sys
import time
from pathlib import Path
from typing import NamedTuple

DEFAULT_OUT = "docs/benchmarks.md"


class Entry(NamedTuple):
    """One benchmark of the report: ``navgym bench <target> <argv>``."""

    target: str
    argv: tuple[str, ...]
    measures: str
    title: str = ""  #: the section's heading (default: ``target``)


#: The report's benchmarks, in page order, with their quick settings.
ENTRIES: tuple[Entry, ...] = (
    Entry(
        "filters",
        ("--batch", "1", "64", "1024", "--repeats", "3"),
        "Gaussian filters (KF ... CIF) on a 9-state range-tracking problem: microseconds per "
        "filter-step (predict + update of one filter) at batch sizes B, the library's NumPy and "
        "compiled paths side by side, against filterpy 2.0.0 and (KF) simdkalman 1.0.4.",
    ),
    Entry(
        "gaussian_sum",
        (),
        "Gaussian-sum update with K noise components against its base filter, same problem, B = 1024.",
    ),
    Entry(
        "particles",
        ("--repeats", "3"),
        "Bootstrap particle filter (8 states, 8 pseudo-ranges, B = 256 filters x N = 1000 "
        "particles): particle-steps per second, NumPy vs compiled measurement function and the "
        "filters' NumPy vs compiled path, and the cost of each stage.",
    ),
    Entry(
        "sim",
        ("--repeats", "2"),
        "Simulation alone (truth, sensors, INS, scenario, GNSS epoch) per platform: episode-steps "
        "per second, against the cost of the filter that consumes it.",
    ),
    Entry(
        "envs",
        ("--batch", "1", "256", "4096", "--seconds", "1.5"),
        "Whole environments (random actions): env-steps per second of a single env, the native "
        "batched vector env and Gymnasium's SyncVectorEnv, with and without resets.",
    ),
    Entry(
        "step_profile",
        (),
        "Where an environment step's time goes (random actions, one episode and the autoreset "
        "after it): microseconds per step and share of each stage (action check, the platform's "
        "step models, the filter's predict + update, memory features, position error, observation, "
        "core bookkeeping, info, autoreset, the shell) for a Kalman id as a single env, a native "
        "vector env and the SB3 adapter, and a v3 RowScale id; and the calls per step against "
        "the time inside compiled kernels (what bounds a small batch's step).",
    ),
    Entry(
        "step_profile",
        (
            "--configs",
            "navgym/Robot2dResample-v2:vector:256",
            "navgym/GpsInsResample-v2:vector:256",
            "--threads",
            "2",
        ),
        "The particle ids at 256 sub-environments with the row-parallel particle passes on 2 "
        "threads (`filters.core.threads`, the default on a 2-core machine; wall clock); their "
        "one-thread figures: `--threads 1`.",
        title="step_profile (particle ids, 2 threads)",
    ),
    Entry(
        "step_profile",
        (
            "--configs",
            "navgym/Robot2dResample-v2:vector:256",
            "navgym/GpsInsResample-v2:vector:256",
        ),
        "The same on one thread (the per-core figures).",
        title="step_profile (particle ids, one thread)",
    ),
    Entry(
        "train",
        ("--timesteps", "16384"),
        "PPO training throughput (SB3, zoo hyperparameters, one torch thread): the headline ids "
        "trained as `navgym train` trains them against SB3 PPO on Pendulum-v1 (DummyVecEnv, same "
        "hyperparameters as GpsInsFading-v2) in the same run, with the share of the training "
        "time spent in the env, in PPO's update and in the rest of the rollout.",
    ),
    Entry(
        "train",
        ("--timesteps", "16384", "--n-envs", "256"),
        "The same with 256 sub-environments for every run (the reference's too) and the same "
        "rollout size (n_steps scaled down): the env's fixed cost per step spread over a wider "
        "batch. Whether that hurts learning: `python -m experiments.batch_width`.",
        title="train (256 sub-environments)",
    ),
)


def command(entry: Entry) -> str:
    """The command line that runs ``entry``."""
    return shlex.join(["navgym", "bench", entry.target, *entry.argv])


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``; the platform's word for it elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_lines() -> list[str]:
    """The machine, one markdown bullet per fact."""
    import numba
    import numpy as np
    import scipy
    from threadpoolctl import threadpool_info

    cores = os.cpu_count()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else cores
    blas = sorted(
        {
            f"{i.get('internal_api', '?')} {i.get('version') or ''} ({i.get('architecture') or '?'}, "
            f"threading: {i.get('threading_layer', '?')})".replace("  ", " ")
            for i in threadpool_info()
            if i.get("user_api") == "blas"
        }
    )
    return [
        f"- CPU: {cpu_model()}, {cores} logical cores ({usable} usable by the process)",
        f"- OS: {platform.system()} {platform.release()} ({platform.machine()})",
        f"- Python {platform.python_version()}, NumPy {np.__version__}, SciPy {scipy.__version__}, "
        f"Numba {numba.__version__}",
        f"- BLAS (threadpoolctl): {'; '.join(blas) or 'none found'}",
    ]


class _Tee(io.TextIOBase):
    """Collects what a benchmark prints and echoes it (progress) to ``echo``."""

    def __init__(self, echo) -> None:
        self.parts: list[str] = []
        self.echo = echo

    def write(self, s: str) -> int:
        self.parts.append(s)
        self.echo.write(s)
        self.echo.flush()
        return len(s)


def tables_of(output: str) -> str:
    """The tables part of a benchmark's output: after its progress lines, without the JSON note."""
    _, sep, rest = output.partition("\n\n")
    body = rest if sep else output
    lines = [ln for ln in body.strip().splitlines() if not ln.startswith("JSON written to")]
    return "\n".join(lines).strip()


def run_entry(entry: Entry, echo=sys.stderr) -> str:
    """Run one benchmark as :func:`command` does; return its tables."""
    module = importlib.import_module(f"benchmarks.{entry.target}")
    parser = argparse.ArgumentParser(prog=f"navgym bench {entry.target}")
    module.add_arguments(parser)
    args = parser.parse_args(list(entry.argv))
    tee = _Tee(echo)
    with contextlib.redirect_stdout(tee):
        status = module.run(args)
    if status:
        raise RuntimeError(f"{command(entry)} exited with status {status}")
    return tables_of("".join(tee.parts))


def render(machine: list[str], sections: list[tuple[Entry, str]]) -> str:
    """The page: header, machine, then one section per benchmark."""
    out = [
        "# Benchmarks",
        "",
        "Current figures of the benchmark commands (`navgym bench <target>`), generated by "
        "`python -m benchmarks.report` (`make bench-report`); do not edit by hand. Each section "
        "says what it measures and the exact command; the figures are single-core (BLAS limited "
        "to one thread) and depend on the machine and its load. The commands' own defaults "
        "(`--help`) measure more sizes and variants than these quick settings.",
        "",
        "## Machine",
        "",
        *machine,
    ]
    for entry, tables in sections:
        out += [
            "",
            f"## {entry.title or entry.target}",
            "",
            entry.measures,
            "",
            "```",
            command(entry),
            "```",
            "",
            tables,
        ]
    return "\n".join(out) + "\n"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default=DEFAULT_OUT, help=f"page to write (default {DEFAULT_OUT})")
    parser.add_argument(
        "--only", nargs="+", default=None, choices=[e.target for e in ENTRIES], help="benchmarks to run"
    )


def run(args: argparse.Namespace) -> int:
    """Run the benchmarks and write the page; progress and timings go to stderr."""
    import navgym

    navgym.tune_malloc()
    entries = [e for e in ENTRIES if args.only is None or e.target in args.only]
    sections = []
    t_all = time.perf_counter()
    for entry in entries:
        print(f"== {command(entry)}", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        sections.append((entry, run_entry(entry)))
        print(f"== {entry.target}: {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(render(machine_lines(), sections))
    print(f"wrote {path} in {time.perf_counter() - t_all:.0f} s", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.report``."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.report", description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
