"""``python -m experiments.compiled_pf [--batch 256] [--particles 1000] [--quick]``.

What DESIGN.md's NumPy-only ``filters/`` costs the particle-filter throughput target of 20 M
particle-steps/s per core: the benchmark problem of ``navgym bench particles``
(:class:`benchmarks.particles.PseudorangePF`, float32 particles in a ``(B, 8, N)`` buffer,
its measurement function compiled) filtered by :mod:`filters.particle.bootstrap` and by the
compiled step of :mod:`experiments.compiled_pf.kernel`, on the same scenario, each without
resampling and with systematic resampling of every filter at every step. One core (BLAS pools
limited to one thread); best of ``--repeats`` rounds of ``--steps`` steps.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from benchmarks._timing import best_time, single_core
from benchmarks.particles import TARGET_PARTICLE_STEPS_PER_S, PseudorangePF, run_steps
from experiments.compiled_pf.kernel import compiled_step
from experiments.outputs import markdown_table, write_csv, write_manifest


def _compiled_steps(xT: np.ndarray, log_w: np.ndarray, zs: np.ndarray, model, rng, resample: bool):
    for z in zs:
        out = compiled_step(xT, log_w, z, model, rng, resample)
        xT, log_w = out.xT, out.log_w
    return xT, log_w


def _rmse(xT: np.ndarray, log_w: np.ndarray, truth: np.ndarray) -> float:
    """Weighted-mean position RMSE [m] over the filters against the true ``(B, 8)`` state."""
    w = np.exp(log_w - log_w.max(axis=1, keepdims=True))
    w /= w.sum(axis=1, keepdims=True)
    p = np.einsum("bn,bkn->bk", w, xT[:, 0:3].astype(np.float64))
    return float(np.sqrt(((p - truth[:, 0:3]) ** 2).sum(axis=1).mean()))


def measure(B: int, N: int, steps: int, repeats: int, seed: int = 12345) -> list[dict]:
    """One row per (implementation, resampling): ms per step, particle-steps/s, RMSE."""
    model = PseudorangePF(layout="soa", dtype="float32", h_impl="compiled")
    rows = []
    with single_core():
        for method in ("none", "systematic"):
            for impl in ("filters.particle.bootstrap (NumPy)", "experiments.compiled_pf (Numba)"):
                rng = np.random.Generator(np.random.PCG64(seed))
                state, zs, truth = model.scenario(B, N, steps, rng)
                if impl.startswith("filters"):

                    def run(s=state, zz=zs, g=rng, m=method):
                        out = run_steps(s, zz, model, g, m)
                        return out.x.transpose(0, 2, 1), out.log_w

                else:
                    xT0 = np.ascontiguousarray(state.x.transpose(0, 2, 1))

                    def run(x=xT0, lw=state.log_w, zz=zs, g=rng, r=method != "none"):
                        return _compiled_steps(x, lw, zz, model, g, r)

                sec = best_time(run, repeats, min_time=0.0) / steps
                rate = B * N / sec
                rows.append(
                    {
                        "filter step": impl,
                        "resampling": method,
                        "B": B,
                        "N": N,
                        "ms/step": f"{sec * 1e3:.2f}",
                        "particle-steps/s": f"{rate / 1e6:.2f} M",
                        "target 20 M/s": f"{'met' if rate >= TARGET_PARTICLE_STEPS_PER_S else 'missed'} "
                        f"({rate / TARGET_PARTICLE_STEPS_PER_S:.0%})",
                        "position RMSE m": f"{_rmse(*run(), truth[-1]):.2f}",
                    }
                )
                print(f"  {impl:38s} {method:10s} {sec * 1e3:7.2f} ms/step", flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.compiled_pf", description=__doc__)
    p.add_argument("--batch", type=int, default=256, help="filters B")
    p.add_argument("--particles", type=int, default=1000, help="particles N per filter")
    p.add_argument("--steps", type=int, default=10, help="filter steps per timing round")
    p.add_argument("--repeats", type=int, default=5, help="timing rounds (best is kept)")
    p.add_argument("--quick", action="store_true", help="B = 8, N = 64, 2 steps, 1 round (the test)")
    p.add_argument("--out", default="results/compiled_pf")
    args = p.parse_args(argv)
    if args.quick:
        args.batch, args.particles, args.steps, args.repeats = 8, 64, 2, 1
    if min(args.batch, args.particles, args.steps, args.repeats) < 1:
        p.error("--batch, --particles, --steps and --repeats must be >= 1")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = measure(args.batch, args.particles, args.steps, args.repeats)
    try:
        cpus = sorted(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - non-Linux
        cpus = list(range(os.cpu_count() or 1))
    table = markdown_table(rows)
    write_csv(out / "table.csv", rows)
    (out / "report.md").write_text(
        "# What the NumPy-only filters cost: a compiled bootstrap step\n\n"
        f"`python -m experiments.compiled_pf`, B = {args.batch}, N = {args.particles}, "
        f"{args.steps} steps per round, best of {args.repeats}, one core "
        f"(process affinity {len(cpus)} CPU(s)); float32 particles, the model's `h` compiled in "
        "both rows. RMSE: weighted-mean position after the last step over the filters (the two "
        "implementations follow the same draws; rounding-level weight differences move a few "
        "systematic-resampling ancestors, so the clouds are not bit-identical).\n\n" + table
    )
    write_manifest(
        out,
        "experiments.compiled_pf",
        argv,
        batch=args.batch,
        particles=args.particles,
        steps=args.steps,
        repeats=args.repeats,
        cpu_affinity=cpus,
    )
    print(table)
    print(f"written to {out}/")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
