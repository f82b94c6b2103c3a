"""Particle-filter throughput: particle-steps per second for an 8-state GPS PF on one core.

Problem (self-contained, :class:`PseudorangePF`): state ``[p (3), v (3), b, d]`` (position and
velocity in a local frame [m, m/s], receiver clock bias and drift [m, m/s]) with constant-velocity
dynamics driven by white acceleration (3) and clock-drift noise (1), and 8 pseudo-ranges
``rho_j = |p - s_j| + b`` to fixed satellites ~20 000 km away (Carvalho et al. 1997, eq. 10 without the
atmosphere; Touil & Ghadi 2012, eq. 5). One particle-step is one particle through one bootstrap
``predict`` plus ``update`` (Gaussian likelihood of the 8 pseudo-ranges, the diagnostics of
``UpdateInfo`` included), optionally followed by resampling every step. The state estimate
(weighted mean and covariance, :func:`filters.particle.estimates.mean_and_covariance`, which the
Resample environments compute every step for their observation) is not part of a particle-step;
its cost is the breakdown's ``estimate`` row.

The measurement function is the model's, not the filter's: ``--h numpy`` evaluates it with
NumPy passes, ``--h compiled`` with one loop compiled by Numba (:func:`_reduced_ranges`), as
the GpsIns Resample environments do (:mod:`navgym.gps_ins.pseudorange_kernel`). The filter's
own path is ``--path``: ``numpy`` forces the NumPy code of ``filters/``
(:func:`filters.core.compiled.numpy_only`), ``compiled`` lets the step functions choose their
Numba kernels (:mod:`filters.particle.kernels`, the Box-Muller kernel of
:mod:`filters.core.normal`) where the layout and dtype allow, as they do by default; both
paths run in the same process, side by side.

Single core: BLAS/OpenMP pools are limited to one thread with threadpoolctl (NumPy's own
element-wise loops are single-threaded); the CPUs the process may use are reported from
``os.sched_getaffinity``. Particles in float64 or float32 (``--dtype``; log-weights, ``S`` and
NIS stay float64).

    navgym bench particles [--batch 256] [--particles 1000] [--methods none systematic]
                           [--dtype float64 float32] [--layout soa aos] [--h numpy compiled]
                           [--path numpy compiled] [--bit-generator PCG64]
                           [--json results/bench/particles.json]
"""

from __future__ import annotations

import argparse
import os

import numpy as np
from numba import njit

from benchmarks._timing import (
    add_clock_and_path_arguments,
    add_threads_argument,
    best_time,
    check_threads,
    single_core,
    write_json,
)
from filters.core.compiled import numpy_only
from filters.core.normal import standard_normal_block
from filters.core.resampling import RESAMPLERS
from filters.core.threads import matmul, over_rows
from filters.core.types import ParticleState
from filters.particle import bootstrap, estimates
from navgym.tables import format_table

#: Issue #4's target: particle-steps per second per core (the stage budget row).
TARGET_PARTICLE_STEPS_PER_S = 20e6
#: Issue #24's targets, float32, one core: without resampling and with resampling every step.
TARGETS_PARTICLE_STEPS_PER_S = {"none": 35e6, "resampled": 25e6}


def target_rate(method: str) -> float:
    """Issue #24's particle-steps/s target for a resampling ``method`` (``"none"``: never)."""
    return TARGETS_PARTICLE_STEPS_PER_S["none" if method == "none" else "resampled"]


class PseudorangePF:
    """8-state GPS model for the benchmark (constant velocity, clock bias/drift, 8 pseudo-ranges).

    Process noise ``w = G e``, ``e ~ N(0, diag(sigma_a^2 I_3, sigma_d^2))`` (rank 4: acceleration
    and clock-drift rate, the discrete white-noise-acceleration model of Bar-Shalom et al. 2001
    §6.3.3), sampled by :meth:`sample_noise` (Box-Muller normals, :mod:`filters.core.normal`);
    ``Q = G diag(.) G^T`` for reference.

    Measurements are *reduced* pseudo-ranges ``y_j = rho_j - |s_j| = |p - s_j| - |s_j| + b``
    ("observed minus computed" about the local origin, the receiver's a-priori position), so
    that every number the filter handles is of the size of the position offsets (metres to
    kilometres), not of the 2e7 m ranges.

    * float64: ``|p - s|^2 = [-2 s, |s|^2, 1] . [p, 1, |p|^2]`` as one ``(8 x 5) @ (5 x N)``
      product per filter, then ``sqrt`` and ``- |s|`` (for ``|p|`` of kilometres the rounding
      error is below 1e-8 m).
    * float32: the cancellation-free form ``|p - s| - |s| = q / (sqrt(|s|^2 + q) + |s|)`` with
      ``q = |p|^2 - 2 p . s``; every factor keeps float32's relative precision (6e-8), i.e.
      better than 1e-4 m for offsets of a kilometre (``navgym bench particles`` reports the
      position RMSE of both precisions side by side).

    Memory layout: with ``layout="soa"`` (default) particles live in a ``(B, n, N)`` buffer and
    the filter sees its ``(B, N, n)`` transposed view (structure of arrays); ``f``,
    ``sample_noise`` and ``h`` return the same layout, so every element-wise pass of the filter
    runs along the N particles (NumPy keeps the layout, ``order="K"``). With ``layout="aos"``
    arrays are C-ordered ``(B, N, n)`` and broadcasts over the last axis (length 8) pay NumPy's
    per-inner-loop overhead.

    ``h_impl="compiled"`` evaluates the cancellation-free form above in one Numba loop per
    filter and satellite along the particles (``soa`` layout only; any precision).
    """

    n, m = 8, 8

    def __init__(
        self,
        dt: float = 1.0,
        sigma_a: float = 0.5,
        sigma_d: float = 0.1,
        sigma_rho: float = 3.0,
        layout: str = "soa",
        dtype: str = "float64",
        h_impl: str = "numpy",
    ):
        if layout not in ("soa", "aos"):
            raise ValueError(f"layout must be 'soa' or 'aos'; got {layout!r}")
        if h_impl not in ("numpy", "compiled"):
            raise ValueError(f"h_impl must be 'numpy' or 'compiled'; got {h_impl!r}")
        if h_impl == "compiled" and layout != "soa":
            raise ValueError("h_impl='compiled' needs layout='soa'")
        self.h_impl = h_impl
        if dtype not in ("float64", "float32"):
            raise ValueError(f"dtype must be 'float64' or 'float32'; got {dtype!r}")
        self.dt, self.layout, self.dtype = dt, layout, np.dtype(dtype)
        G = np.zeros((8, 4))
        for i in range(3):
            G[i, i] = 0.5 * dt**2
            G[3 + i, i] = dt
        G[6, 3] = 0.5 * dt**2
        G[7, 3] = dt
        G *= np.array([sigma_a] * 3 + [sigma_d])  # (8, 4)
        self.Q = G @ G.T
        self.R = np.eye(8) * sigma_rho**2
        F = np.eye(8)
        F[0, 3] = F[1, 4] = F[2, 5] = F[6, 7] = dt
        self.F64, self.G64 = F, G
        self.F, self.G = F.astype(self.dtype), G.astype(self.dtype)
        az = np.deg2rad(np.arange(8) * 45.0 + 10.0)
        el = np.deg2rad(np.array([15.0, 70.0, 35.0, 50.0, 20.0, 80.0, 40.0, 60.0]))
        rng_m = 2.0e7 + 3.0e6 * (1.0 - np.sin(el))  # slant range grows towards the horizon
        self.sats = rng_m[:, None] * np.stack(
            [np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=1
        )  # (8, 3) in the local east-north-up frame
        sats_sq = (self.sats**2).sum(axis=1)  # (8,)
        self.sat_range = np.sqrt(sats_sq)  # |s_j|: the computed range at the origin
        #: ``(-2 s (3, 8), |s|^2 (8,), |s| (8,))`` in the particles' precision (the compiled ``h``)
        self.range_coefficients = (
            np.ascontiguousarray((-2.0 * self.sats).T, dtype=self.dtype),
            sats_sq.astype(self.dtype),
            self.sat_range.astype(self.dtype),
        )
        if self.dtype == np.float64:
            # [-2 s, |s|^2, 1] . [p, 1, |p|^2] = |p - s|^2
            self._range_matrix = np.concatenate([-2.0 * self.sats, sats_sq[:, None], np.ones((8, 1))], axis=1)
        else:
            # [-2 s, 1] . [p, |p|^2] = q
            self._range_matrix = np.concatenate([-2.0 * self.sats, np.ones((8, 1))], axis=1).astype(
                np.float32
            )
            self._sats_sq32 = sats_sq.astype(np.float32)[:, None]
            self._sat_range32 = self.sat_range.astype(np.float32)[:, None]

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        """Constant velocity and clock drift: ``p += v dt``, ``b += d dt`` (``x F^T``)."""
        if dt is not None and dt != self.dt:
            raise ValueError(f"dt must be the model's {self.dt}; got {dt}")
        if self.layout == "soa":  # the stack split over threads (filters.core.threads)
            return matmul(self.F, x.transpose(0, 2, 1)).transpose(0, 2, 1)
        return x @ self.F.T

    def sample_noise(self, g: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        """``G e`` for ``e ~ N(0, diag(sigma^2))``, shape ``(*shape, 8)`` in the model's layout."""
        k, N = shape
        if self.layout == "soa":
            return matmul(self.G, standard_normal_block(g, (k, 4, N), self.dtype)[0]).transpose(0, 2, 1)
        return standard_normal_block(g, (k, N, 4), self.dtype)[0] @ self.G.T

    def h(self, x: np.ndarray) -> np.ndarray:
        """Reduced pseudo-ranges ``|p - s_j| - |s_j| + b`` to the 8 satellites, ``(B, N, 8)``."""
        if self.h_impl == "compiled":
            xT = x.transpose(0, 2, 1)
            if not xT.flags.c_contiguous:
                raise ValueError("h_impl='compiled' needs the (B, N, 8) view of a (B, 8, N) buffer")
            out = np.empty(xT.shape, dtype=self.dtype)
            coefficients = self.range_coefficients

            def filters(a: int, b: int) -> None:  # each filter's ranges from its own cloud
                _reduced_ranges(xT[a:b], *coefficients, out[a:b])

            over_rows(xT.shape[0], xT.shape[1] * xT.shape[2], filters)
            return out.transpose(0, 2, 1)
        xT = x.transpose(0, 2, 1) if self.layout == "soa" else np.ascontiguousarray(x.transpose(0, 2, 1))
        B, _, N = xT.shape
        wide = self.dtype == np.float64
        aug = np.empty((B, 5 if wide else 4, N), dtype=self.dtype)
        aug[:, 0:3] = xT[:, 0:3]
        pp = aug[:, -1]
        np.multiply(xT[:, 0], xT[:, 0], out=pp)
        pp += xT[:, 1] * xT[:, 1]
        pp += xT[:, 2] * xT[:, 2]
        if wide:
            aug[:, 3] = 1.0
            r = self._range_matrix @ aug  # |p - s|^2, (B, 8, N)
            np.sqrt(r, out=r)
            r -= self.sat_range[:, None]
        else:
            q = self._range_matrix @ aug  # |p|^2 - 2 p.s
            r = q + self._sats_sq32
            np.sqrt(r, out=r)
            r += self._sat_range32
            np.divide(q, r, out=r)
        r += xT[:, 6:7, :]
        r = r.transpose(0, 2, 1)
        return r if self.layout == "soa" else np.ascontiguousarray(r)

    def scenario(self, B: int, N: int, steps: int, rng: np.random.Generator):
        """Initial particles around the truth, reduced pseudo-ranges ``(steps, B, 8)``, truth.

        Returns:
            ``(ParticleState, zs, truth)`` with the true states ``(steps, B, 8)`` (float64).
        """
        truth = np.zeros((B, 8))
        truth[:, 0:3] = rng.normal(0.0, 50.0, (B, 3))
        truth[:, 3:6] = rng.normal(0.0, 10.0, (B, 3))
        truth[:, 6] = rng.normal(0.0, 100.0, B)
        truth[:, 7] = rng.normal(0.0, 1.0, B)
        sd0 = np.array([10.0] * 3 + [1.0] * 3 + [10.0, 0.5])
        x0 = (truth[:, :, None] + sd0[:, None] * rng.standard_normal((B, 8, N))).astype(self.dtype)
        x0 = x0.transpose(0, 2, 1) if self.layout == "soa" else np.ascontiguousarray(x0.transpose(0, 2, 1))
        zs, xs = [], []
        x = truth
        for _ in range(steps):
            x = x @ self.F64.T + rng.standard_normal((B, 4)) @ self.G64.T
            p = x[:, 0:3]
            rho = np.sqrt(((p[:, None, :] - self.sats) ** 2).sum(axis=2)) + x[:, 6:7]
            zs.append(rho - self.sat_range + 3.0 * rng.standard_normal((B, 8)))
            xs.append(x)
        return ParticleState(x0, np.full((B, N), -np.log(N))), np.array(zs), np.array(xs)


@njit(cache=True, error_model="numpy", inline="always")
def reduced_range(sx, sy, sz, s2, s1, x, y, z):  # pragma: no cover - compiled
    """``|p - s| - |s| = q / (sqrt(|s|^2 + q) + |s|)``, ``q = |p|^2 - 2 p . s``, for one particle.

    ``(sx, sy, sz) = -2 s``, ``s2 = |s|^2``, ``s1 = |s|`` (:attr:`PseudorangePF.range_coefficients`);
    the cancellation-free form of the class docstring, inlined into :func:`_reduced_ranges`.
    """
    q = (sx * x + sy * y + sz * z) + (x * x + y * y + z * z)
    return q / (np.sqrt(s2 + q) + s1)


@njit(cache=True, error_model="numpy", nogil=True)
def _reduced_ranges(xT, m2s, sats_sq, sat_range, out):  # pragma: no cover - compiled
    """``out[b, j] = reduced_range(s_j, p_i) + b_i`` in the particles' precision.

    One pass along the particles per filter and satellite (``error_model="numpy"`` lets it
    vectorise).
    """
    B, _, N = xT.shape
    m = m2s.shape[1]
    for b in range(B):
        px, py, pz, clock = xT[b, 0], xT[b, 1], xT[b, 2], xT[b, 6]
        for j in range(m):
            sx, sy, sz = m2s[0, j], m2s[1, j], m2s[2, j]
            s2, s1 = sats_sq[j], sat_range[j]
            o = out[b, j]
            for i in range(N):
                o[i] = reduced_range(sx, sy, sz, s2, s1, px[i], py[i], pz[i]) + clock[i]


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
    parser.add_argument(
        "--dtype",
        nargs="+",
        default=["float64", "float32"],
        choices=["float64", "float32"],
        help="particle precision (the weights stay float64)",
    )
    parser.add_argument(
        "--h",
        nargs="+",
        default=["numpy", "compiled"],
        choices=["numpy", "compiled"],
        dest="h_impl",
        help="the model's measurement function: NumPy passes or one compiled loop (soa only)",
    )
    add_clock_and_path_arguments(parser)
    add_threads_argument(parser)
    parser.add_argument("--steps", type=int, default=10, help="filter steps per timing round")
    parser.add_argument("--repeats", type=int, default=5, help="timing rounds (best is kept)")
    parser.add_argument("--no-breakdown", action="store_true", help="skip the per-stage timing")
    parser.add_argument("--json", default="results/bench/particles.json", help="where to write JSON")


def run_steps(
    state: ParticleState, zs: np.ndarray, model, rng: np.random.Generator, method: str
) -> ParticleState:
    """The benchmark's step for each measurement of ``zs``: predict + update (+ resampling).

    ``method`` resamples every filter after every update (``"none"``: never).
    """
    for z in zs:
        state = bootstrap.predict(state, model, None, model.dt, rng)
        if method == "none":
            state, _ = bootstrap.update(state, z, model)
        else:
            state, _ = bootstrap.update(state, z, model, decision=True, rng=rng, method=method)
    return state


class _FreeModel:
    """The benchmark model with its work taken away: the filter's own cost, a lower bound.

    ``f`` returns its input, ``sample_noise`` a fixed noise array and ``h`` fixed predictions
    (copied into a buffer each call, because the update centres and squares them in place;
    the copy's time is measured and subtracted). What remains of a step is the filter's NumPy
    work in :mod:`filters.particle.bootstrap`: adding the noise, the weights, the predictive
    moments and ``S``, NIS, ESS and, with resampling, ancestors and gather.
    """

    def __init__(self, model: PseudorangePF, x: np.ndarray, rng: np.random.Generator):
        self.dt, self.Q, self.R = model.dt, model.Q, model.R
        B, N, _ = x.shape
        self._w = model.sample_noise(rng, (B, N))
        self._zhat = model.h(x)
        self._buf = np.empty_like(self._zhat)  # same layout

    def f(self, x: np.ndarray, u=None, dt=None) -> np.ndarray:
        return x

    def sample_noise(self, g: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        return self._w

    def h(self, x: np.ndarray) -> np.ndarray:
        np.copyto(self._buf, self._zhat)
        return self._buf


def _breakdown(model: PseudorangePF, B: int, N: int, repeats: int, clock: str = "wall") -> dict[str, float]:
    """Milliseconds per step of each stage, timed in isolation (state after a few steps)."""
    rng = np.random.Generator(np.random.PCG64(0))
    state, zs, _ = model.scenario(B, N, 3, rng)
    state = run_steps(state, zs[:2], model, rng, "systematic")
    z, mask = zs[2], np.ones((B, 8), dtype=bool)
    w = np.exp(state.log_w)
    zhat = model.h(state.x)
    soa = model.layout == "soa"
    compiled = PseudorangePF(layout="soa", dtype=str(model.dtype), h_impl="compiled") if soa else None

    def ms(fn):
        return best_time(fn, repeats, clock=clock) * 1e3

    free = _FreeModel(model, state.x, rng)
    copy_ms = ms(lambda: np.copyto(free._buf, free._zhat))

    def alone(method: str) -> float:
        return ms(lambda: run_steps(state, [z], free, rng, method)) - copy_ms

    return {
        "predict: process noise (4 normals per particle, G e)": ms(lambda: model.sample_noise(rng, (B, N))),
        "  of which the normals (Box-Muller, filters.core.normal)": ms(
            lambda: standard_normal_block(rng, (B, 4, N), model.dtype)
        ),
        "  (NumPy's ziggurat, rng.standard_normal, for comparison)": ms(
            lambda: rng.standard_normal((B, 4, N), dtype=model.dtype)
        ),
        "predict: f (constant velocity)": ms(lambda: model.f(state.x)),
        "predict: total": ms(lambda: bootstrap.predict(state, model, None, model.dt, rng)),
        "update: h (8 pseudo-ranges)": ms(lambda: model.h(state.x)),
        **(
            {"update: h compiled (--h compiled)": ms(lambda: compiled.h(state.x))}
            if compiled is not None
            else {}
        ),
        "update: Gaussian log-likelihood of 8 rows": ms(
            lambda: bootstrap._gaussian_loglik(
                zhat - z[:, None, :].astype(model.dtype),
                None,
                np.full((B, 8), 1 / 3.0),
                True,
                np.zeros(B),
                np.full(B, 8),
            )
        ),
        "update: total (h, weights, S, NIS, ESS)": ms(lambda: bootstrap.update(state, z, model, mask)),
        "estimate: weighted mean and covariance (not in the step)": ms(
            lambda: estimates.mean_and_covariance(state)
        ),
        "resample: systematic ancestors": ms(lambda: RESAMPLERS["systematic"].kernel(w, rng.random((B, 1)))),
        "resample: total (ancestors + gather)": ms(
            lambda: bootstrap.resample(state, True, rng, "systematic", weights=w)
        ),
        "filter alone (f, noise, h free): no resampling": alone("none"),
        "filter alone (f, noise, h free): systematic every step": alone("systematic"),
        f"budget of the 20 M/s target at B x N = {B * N}": B * N / TARGET_PARTICLE_STEPS_PER_S * 1e3,
    }


def _position_rmse(state: ParticleState, truth: np.ndarray) -> float:
    """RMSE [m] over the filters of the weighted-mean position against the true ``(B, 8)``."""
    p = estimates.mean(state)[:, 0:3]
    return float(np.sqrt(((p - truth[:, 0:3]) ** 2).sum(axis=1).mean()))


def run(args: argparse.Namespace) -> int:
    cores = check_threads(args.threads, args.clock)
    B, N = args.batch, args.particles
    rows, records = [], []
    try:
        cpus = sorted(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - non-Linux
        cpus = list(range(os.cpu_count() or 1))
    stages: dict[str, dict[str, float]] = {}
    with single_core(args.threads):
        for dtype in args.dtype:
            for layout, h_impl in [(lay, hi) for lay in args.layout for hi in args.h_impl]:
                if h_impl == "compiled" and layout != "soa":
                    continue  # the compiled loop runs along a (B, 8, N) buffer
                model = PseudorangePF(layout=layout, dtype=dtype, h_impl=h_impl)
                for bitgen, method, path in [
                    (g, m, p) for g in args.bit_generator for m in args.methods for p in args.path
                ]:
                    rng = np.random.Generator(getattr(np.random, bitgen)(12345))
                    state, zs, truth = model.scenario(B, N, args.steps, rng)

                    def steps(s=state, zz=zs, m=method, g=rng, mdl=model):
                        return run_steps(s, zz, mdl, g, m)

                    with numpy_only(path == "numpy"):
                        sec = best_time(steps, args.repeats, min_time=0.0, clock=args.clock) / args.steps
                        rmse = _position_rmse(steps(), truth[-1])
                    rate = B * N / sec
                    target = target_rate(method)
                    verdict = "met" if rate >= target else "missed"
                    share = rate / target
                    rows.append(
                        [
                            method,
                            path,
                            dtype,
                            layout,
                            h_impl,
                            bitgen,
                            B,
                            N,
                            f"{sec * 1e3:.1f}",
                            f"{rate / 1e6:.2f} M",
                            f"{target / 1e6:.0f} M: {verdict} ({share:.0%})",
                            f"{rmse:.2f}",
                        ]
                    )
                    records.append(
                        {
                            "method": method,
                            "path": path,
                            "dtype": dtype,
                            "layout": layout,
                            "h": h_impl,
                            "bit_generator": bitgen,
                            "B": B,
                            "N": N,
                            "ms_per_step": sec * 1e3,
                            "particle_steps_per_s": rate,
                            "target_particle_steps_per_s": target,
                            "position_rmse_m": rmse,
                        }
                    )
                    print(
                        f"  {method:12s} {path:8s} {dtype} {layout} {h_impl:8s} {bitgen:7s} B={B} N={N}: "
                        f"{sec * 1e3:8.2f} ms/step, position RMSE {rmse:.2f} m",
                        flush=True,
                    )
            if not args.no_breakdown:
                for path in args.path:
                    with numpy_only(path == "numpy"):
                        stages[f"{dtype} {path}"] = _breakdown(
                            PseudorangePF(layout=args.layout[0], dtype=dtype), B, N, args.repeats, args.clock
                        )
    print()
    print(
        f"Bootstrap PF throughput, 8 states / 8 pseudo-ranges, {cores}, {args.clock} clock "
        f"(BLAS threads limited to 1; process affinity: {len(cpus)} CPU(s) {cpus}); "
        f"RMSE: weighted-mean position after {args.steps} steps, over the {B} filters"
    )
    headers = [
        "resampling",
        "filters path",
        "dtype",
        "layout",
        "h",
        "bit generator",
        "B",
        "N",
        "ms/step",
        "particle-steps/s",
        "target",
        "RMSE m",
    ]
    print(format_table(headers, rows))
    if stages:
        names = list(next(iter(stages.values())))
        print(
            f"\nStages ({args.layout[0]} layout), ms per step of B x N = {B * N} particles, timed separately:"
        )
        print(
            format_table(
                ["stage", *(f"{d} ms" for d in stages)],
                [[k, *(f"{stages[d][k]:.2f}" for d in stages)] for k in names],
            )
        )
    path = write_json(
        args.json,
        {
            "problem": "PseudorangePF(n=8, m=8): bootstrap predict + update (+ resample every step)",
            "h": "numpy: NumPy passes; compiled: one Numba loop (the model's, not the filter's)",
            "single_core": "threadpoolctl.threadpool_limits(1) around every timed call",
            "threads": args.threads,
            "cpu_affinity": cpus,
            "results": records,
            "stages_ms": stages,
        },
    )
    print(f"\nJSON written to {path}")
    return 0
