"""Particle-filter throughput: particle-steps per second for an 8-state GPS PF on one core.

Problem (self-contained, :class:`PseudorangePF`): state ``[p (3), v (3), b, d]`` (position and
velocity in a local frame [m, m/s], receiver clock bias and drift [m, m/s]) with constant-velocity
dynamics driven by white acceleration (3) and clock-drift noise (1), and 8 pseudo-ranges
``rho_j = |p - s_j| + b`` to fixed satellites ~20 000 km away (seed 000 eq. 10 without the
atmosphere; seed 002 eq. 5). One particle-step is one particle through one bootstrap
``predict`` plus ``update`` (Gaussian likelihood of the 8 pseudo-ranges, the diagnostics of
``UpdateInfo`` included), optionally followed by resampling every step.

Single core: BLAS/OpenMP pools are limited to one thread with threadpoolctl (NumPy's own
element-wise loops are single-threaded); the CPUs the process may use are reported from
``os.sched_getaffinity``. Float64 throughout.

    navgym bench particles [--batch 256] [--particles 1000] [--methods none systematic]
                           [--bit-generator PCG64] [--json results/bench/particles.json]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from filters.core.normal import standard_normal_block
from filters.core.resampling import RESAMPLERS
from filters.core.types import ParticleState
from filters.particle import bootstrap
from navgym.bench._timing import format_table, single_core, write_json

#: Issue target: particle-steps per second per core.
TARGET_PARTICLE_STEPS_PER_S = 20e6


class PseudorangePF:
    """8-state GPS model for the benchmark (constant velocity, clock bias/drift, 8 pseudo-ranges).

    Process noise ``w = G e``, ``e ~ N(0, diag(sigma_a^2 I_3, sigma_d^2))`` (rank 4: acceleration
    and clock-drift rate, the discrete white-noise-acceleration model of Bar-Shalom et al. 2001
    §6.3.3), sampled by :meth:`sample_noise`; ``Q = G diag(.) G^T`` for reference. Pseudo-ranges
    use ``|p - s|^2 = |p|^2 - 2 p.s + |s|^2`` (one small matrix product instead of a
    ``(B, N, 8, 3)`` difference array; for ``|p|`` of kilometres and ``|s| ~ 2.6e7`` m its
    rounding error is below 1e-8 m).

    Memory layout: with ``layout="soa"`` (default) particles live in a ``(B, n, N)`` buffer and
    the filter sees its ``(B, N, n)`` transposed view (structure of arrays); ``f``,
    ``sample_noise`` and ``h`` return the same layout, so every element-wise pass of the filter
    runs along the N particles (NumPy keeps the layout, ``order="K"``). With ``layout="aos"``
    arrays are C-ordered ``(B, N, n)`` and broadcasts over the last axis (length 8) pay NumPy's
    per-inner-loop overhead.
    """

    n, m = 8, 8

    def __init__(
        self,
        dt: float = 1.0,
        sigma_a: float = 0.5,
        sigma_d: float = 0.1,
        sigma_rho: float = 3.0,
        layout: str = "soa",
    ):
        if layout not in ("soa", "aos"):
            raise ValueError(f"layout must be 'soa' or 'aos'; got {layout!r}")
        self.dt, self.layout = dt, layout
        G = np.zeros((8, 4))
        for i in range(3):
            G[i, i] = 0.5 * dt**2
            G[3 + i, i] = dt
        G[6, 3] = 0.5 * dt**2
        G[7, 3] = dt
        self.G = G * np.array([sigma_a] * 3 + [sigma_d])  # (8, 4)
        self.Q = self.G @ self.G.T
        self.R = np.eye(8) * sigma_rho**2
        self.F = np.eye(8)
        self.F[0, 3] = self.F[1, 4] = self.F[2, 5] = self.F[6, 7] = dt
        az = np.deg2rad(np.arange(8) * 45.0 + 10.0)
        el = np.deg2rad(np.array([15.0, 70.0, 35.0, 50.0, 20.0, 80.0, 40.0, 60.0]))
        rng_m = 2.0e7 + 3.0e6 * (1.0 - np.sin(el))  # slant range grows towards the horizon
        self.sats = rng_m[:, None] * np.stack(
            [np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=1
        )  # (8, 3) in the local east-north-up frame
        self._minus_2_sats = -2.0 * self.sats  # (8, 3)
        self._sats_sq = (self.sats**2).sum(axis=1)  # (8,)
        self._range_matrix = np.concatenate(
            [self._minus_2_sats, self._sats_sq[:, None], np.ones((8, 1))], axis=1
        )  # (8, 5)

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        """Constant velocity and clock drift: ``p += v dt``, ``b += d dt`` (``x F^T``)."""
        if dt is not None and dt != self.dt:
            raise ValueError(f"dt must be the model's {self.dt}; got {dt}")
        if self.layout == "soa":
            return (self.F @ x.transpose(0, 2, 1)).transpose(0, 2, 1)
        return x @ self.F.T

    def sample_noise(self, g: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        """``G e`` for ``e ~ N(0, diag(sigma^2))``, shape ``(*shape, 8)`` in the model's layout."""
        k, N = shape
        if self.layout == "soa":
            return (self.G @ standard_normal_block(g, (k, 4, N))[0]).transpose(0, 2, 1)
        return standard_normal_block(g, (k, N, 4))[0] @ self.G.T

    def h(self, x: np.ndarray) -> np.ndarray:
        """Pseudo-ranges ``|p - s_j| + b`` to the 8 satellites, shape ``(B, N, 8)``."""
        if self.layout == "aos":
            p = x[..., 0:3]
            r = p @ self._minus_2_sats.T
            r += self._sats_sq
            r += np.einsum("...i,...i->...", p, p)[..., None]
            np.sqrt(r, out=r)
            r += x[..., 6:7]
            return r
        xt = x.transpose(0, 2, 1)  # (B, 8, N)
        B, _, N = xt.shape
        # |p - s|^2 = [-2 s, |s|^2, 1] . [p, 1, |p|^2]: one (8 x 5) @ (5 x N) product per filter
        aug = np.empty((B, 5, N))
        aug[:, 0:3] = xt[:, 0:3]
        aug[:, 3] = 1.0
        pp = aug[:, 4]
        np.multiply(xt[:, 0], xt[:, 0], out=pp)
        pp += xt[:, 1] * xt[:, 1]
        pp += xt[:, 2] * xt[:, 2]
        r = self._range_matrix @ aug
        np.sqrt(r, out=r)
        r += xt[:, 6:7, :]
        return r.transpose(0, 2, 1)

    def scenario(self, B: int, N: int, steps: int, rng: np.random.Generator):
        """Initial particles around the truth, and ``steps`` pseudo-range epochs ``(steps, B, 8)``."""
        truth = np.zeros((B, 8))
        truth[:, 0:3] = rng.normal(0.0, 50.0, (B, 3))
        truth[:, 3:6] = rng.normal(0.0, 10.0, (B, 3))
        truth[:, 6] = rng.normal(0.0, 100.0, B)
        truth[:, 7] = rng.normal(0.0, 1.0, B)
        sd0 = np.array([10.0] * 3 + [1.0] * 3 + [10.0, 0.5])
        x0 = truth[:, :, None] + sd0[:, None] * rng.standard_normal((B, 8, N))  # (B, 8, N)
        x0 = x0.transpose(0, 2, 1) if self.layout == "soa" else np.ascontiguousarray(x0.transpose(0, 2, 1))
        zs = []
        x = truth
        for _ in range(steps):
            x = x @ self.F.T + rng.standard_normal((B, 4)) @ self.G.T
            p = x[:, 0:3]
            rho = np.sqrt(((p[:, None, :] - self.sats) ** 2).sum(axis=2)) + x[:, 6:7]
            zs.append(rho + 3.0 * rng.standard_normal((B, 8)))
        return ParticleState(x0, np.full((B, N), -np.log(N))), np.array(zs)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--batch", type=int, default=256, help="filters B (default 256)")
    parser.add_argument("--particles", type=int, default=1000, help="particles N per filter (default 1000)")
    parser.add_argument(
        "--methods",
        nargs="+",
        default=["none", "systematic"],
        choices=["none", *sorted(RESAMPLERS)],
        help="resampling at every step ('none': never)",
    )
    parser.add_argument(
        "--layout",
        nargs="+",
        default=["soa", "aos"],
        choices=["soa", "aos"],
        help="particle memory layout: (B, n, N) buffer seen as (B, N, n) ('soa') or C-ordered ('aos')",
    )
    parser.add_argument(
        "--bit-generator",
        nargs="+",
        default=["PCG64"],
        choices=["PCG64", "SFC64", "Philox", "MT19937"],
        help="NumPy bit generator(s) of the rng (the normals use its raw 64-bit words)",
    )
    parser.add_argument("--steps", type=int, default=10, help="filter steps per timing round")
    parser.add_argument("--repeats", type=int, default=5, help="timing rounds (best is kept)")
    parser.add_argument("--no-breakdown", action="store_true", help="skip the per-stage timing")
    parser.add_argument("--json", default="results/bench/particles.json", help="where to write JSON")


def _run_steps(state, zs, model, rng, method):
    for z in zs:
        state = bootstrap.predict(state, model, None, model.dt, rng)
        if method == "none":
            state, _ = bootstrap.update(state, z, model)
        else:
            state, _ = bootstrap.update(state, z, model, decision=True, rng=rng, method=method)
    return state


def _best(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _breakdown(model: PseudorangePF, B: int, N: int, repeats: int) -> dict[str, float]:
    """Milliseconds per step of each stage, timed in isolation (state after a few steps)."""
    rng = np.random.Generator(np.random.PCG64(0))
    state, zs = model.scenario(B, N, 3, rng)
    state = _run_steps(state, zs[:2], model, rng, "systematic")
    z, mask = zs[2], np.ones((B, 8), dtype=bool)
    w = np.exp(state.log_w)
    zhat = model.h(state.x)
    k = 3

    def ms(fn):
        return _best(lambda: [fn() for _ in range(k)], repeats) / k * 1e3

    return {
        "predict: process noise (4 normals per particle, G e)": ms(lambda: model.sample_noise(rng, (B, N))),
        "  of which the normals (Box-Muller, filters.core.normal)": ms(
            lambda: standard_normal_block(rng, (B, 4, N))
        ),
        "  (NumPy's ziggurat, rng.standard_normal, for comparison)": ms(
            lambda: rng.standard_normal((B, 4, N))
        ),
        "predict: f (constant velocity)": ms(lambda: model.f(state.x)),
        "predict: total": ms(lambda: bootstrap.predict(state, model, None, model.dt, rng)),
        "update: h (8 pseudo-ranges)": ms(lambda: model.h(state.x)),
        "update: Gaussian log-likelihood of 8 rows": ms(
            lambda: bootstrap._gaussian_loglik(
                zhat - z[:, None, :], None, np.full((B, 8), 1 / 3.0), True, np.zeros(B), np.full(B, 8)
            )
        ),
        "update: total (h, weights, S, NIS, ESS)": ms(lambda: bootstrap.update(state, z, model, mask)),
        "resample: systematic ancestors": ms(lambda: RESAMPLERS["systematic"].kernel(w, rng.random((B, 1)))),
        "resample: total (ancestors + gather)": ms(
            lambda: bootstrap.resample(state, True, rng, "systematic", weights=w)
        ),
    }


def run(args: argparse.Namespace) -> int:
    B, N = args.batch, args.particles
    rows, records = [], []
    try:
        cpus = sorted(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - non-Linux
        cpus = list(range(os.cpu_count() or 1))
    stages: dict[str, float] = {}
    with single_core():
        for layout in args.layout:
            model = PseudorangePF(layout=layout)
            for bitgen in args.bit_generator:
                for method in args.methods:
                    rng = np.random.Generator(getattr(np.random, bitgen)(12345))
                    state, zs = model.scenario(B, N, args.steps, rng)
                    _run_steps(state, zs[:1], model, rng, method)  # warm-up

                    def steps(s=state, zz=zs, m=method, g=rng, mdl=model):
                        return _run_steps(s, zz, mdl, g, m)

                    sec = _best(steps, args.repeats) / args.steps
                    rate = B * N / sec
                    verdict = "met" if rate >= TARGET_PARTICLE_STEPS_PER_S else "missed"
                    share = rate / TARGET_PARTICLE_STEPS_PER_S
                    rows.append(
                        [
                            method,
                            layout,
                            bitgen,
                            B,
                            N,
                            f"{sec * 1e3:.1f}",
                            f"{rate / 1e6:.2f} M",
                            f"{verdict} ({share:.0%})",
                        ]
                    )
                    records.append(
                        {
                            "method": method,
                            "layout": layout,
                            "bit_generator": bitgen,
                            "B": B,
                            "N": N,
                            "ms_per_step": sec * 1e3,
                            "particle_steps_per_s": rate,
                            "target_particle_steps_per_s": TARGET_PARTICLE_STEPS_PER_S,
                        }
                    )
                    print(
                        f"  {method:12s} {layout} {bitgen:7s} B={B} N={N}: {sec * 1e3:8.2f} ms/step",
                        flush=True,
                    )
        if not args.no_breakdown:
            stages = _breakdown(PseudorangePF(layout=args.layout[0]), B, N, args.repeats)
    print()
    print(
        "Bootstrap PF throughput, 8 states / 8 pseudo-ranges, float64, one core "
        f"(BLAS threads limited to 1; process affinity: {len(cpus)} CPU(s) {cpus})"
    )
    headers = [
        "resampling",
        "layout",
        "bit generator",
        "B",
        "N",
        "ms/step",
        "particle-steps/s",
        "target 20 M/s",
    ]
    print(format_table(headers, rows))
    if stages:
        print(
            f"\nStages ({args.layout[0]} layout), ms per step of B x N = {B * N} particles, timed separately:"
        )
        print(format_table(["stage", "ms"], [[k, f"{v:.2f}"] for k, v in stages.items()]))
    path = write_json(
        args.json,
        {
            "problem": "PseudorangePF(n=8, m=8): bootstrap predict + update (+ resample every step)",
            "single_core": "threadpoolctl.threadpool_limits(1) around every timed call",
            "cpu_affinity": cpus,
            "results": records,
            "stages_ms": stages,
        },
    )
    print(f"\nJSON written to {path}")
    return 0
