"""Gaussian filter throughput: microseconds per filter-step, batched vs filterpy.

Problem: :class:`filters.examples.RangeTracking` (9 states, 4 range measurements, nonlinear
dynamics with drag); the KF runs its linear counterpart. One filter-step is one predict plus one
update of one filter; batched figures divide the time of a B-filter call by B. filterpy 2.0.0
runs the same problem one filter at a time in the same process; simdkalman 1.0.4 (when
installed: the ``test`` extra) runs the KF batched, B filters per call of its
``primitives.predict`` and ``primitives._update(..., log_likelihood=True)`` (mean, covariance,
gain and log-likelihood; ours also returns the innovation, ``S``, NIS and the health flag).
``--path`` runs the library's NumPy path (forced by :func:`filters.core.compiled.numpy_only`)
and its compiled kernels (:mod:`filters.core.gaussian_kernels`, chosen by the KF/EKF steps;
:mod:`filters.core.sigma_point_kernels`, chosen by the UKF/CKF steps around the model's
``f``/``h``) side by side. Single core (threadpoolctl).

    navgym bench filters [--batch 1 64 1024 8192] [--filters kf ekf ukf ...]
                         [--path numpy compiled] [--clock wall|cpu] [--malloc default|retain]
                         [--json PATH]
"""

from __future__ import annotations

import argparse
import math
import warnings

import numpy as np

from benchmarks._timing import add_clock_and_path_arguments, best_time, single_core, write_json
from filters import information, registry
from filters.core.compiled import numpy_only
from filters.core.types import GaussianState
from filters.examples import RangeTracking
from navgym.tables import format_table

DEFAULT_FILTERS = ["kf", "ekf", "iekf", "ukf", "ckf", "ghkf", "dd1", "dd2", "eif", "cif"]
DEFAULT_BATCH = [1, 64, 1024, 8192]
#: Sigma-point evaluations per call above which a batch is split into chunks (memory bound;
#: matters for the GHKF's 3^9 = 19683 points only).
MAX_POINTS_PER_CALL = 2_000_000
#: Issue #24's targets, us per filter-step at B = 1024 on one core.
TARGETS_US = {"kf": 1.0, "ekf": 1.5, "ukf": 4.0, "ckf": 4.0}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--batch", type=int, nargs="+", default=DEFAULT_BATCH, help="batch sizes B")
    parser.add_argument("--filters", nargs="+", default=DEFAULT_FILTERS, help="filters to time")
    parser.add_argument("--no-filterpy", action="store_true", help="skip the filterpy reference")
    add_clock_and_path_arguments(parser)
    parser.add_argument("--repeats", type=int, default=5, help="timing rounds (best is kept)")
    parser.add_argument(
        "--malloc",
        default="default",
        choices=["default", "retain"],
        help="glibc's allocator as it is, or told to keep freed memory (no trimming, no mmap per "
        "large array) so that fresh arrays do not page-fault; see retain_heap",
    )
    parser.add_argument("--json", default="results/bench/filters.json", help="where to write JSON")


#: glibc ``mallopt`` parameters (malloc.h) and the values :func:`retain_heap` sets.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_RETAIN = {_M_MMAP_THRESHOLD: 32 << 20, _M_TRIM_THRESHOLD: 1 << 30}


def retain_heap() -> bool:
    """Tell glibc's allocator to keep freed memory in the process (``--malloc retain``).

    By default glibc serves arrays above a dynamic threshold (128 kB rising to the largest
    freed one) from fresh ``mmap`` pages and returns the heap's free top to the system above
    twice that threshold, so a step that frees a few MB of arrays (1024 filters: 0.66 MB per
    ``(B, 9, 9)`` covariance, 1.4 MB per ``(B, 19, 9)`` sigma-point set) page-faults them back
    in the next call, at a cost that varies with what the process did before
    (``docs/performance.md``, "Figures behind the code").
    A 32 MB mmap threshold and a 1 GB trim threshold keep those pages (what
    ``MALLOC_MMAP_THRESHOLD_`` / ``MALLOC_TRIM_THRESHOLD_`` do for a whole process). Returns
    False where ``mallopt`` is not available (not glibc).
    """
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    return all(mallopt(param, value) == 1 for param, value in _RETAIN.items())


def _step_fn(name: str, problem: RangeTracking, B: int, rng: np.random.Generator):
    """A closure running one predict + update of B filters, and the points per filter."""
    model = problem.linear() if name == "kf" else problem
    _, m0, P0 = problem.initial_state(B, rng)
    state = GaussianState(m0, P0)
    z = model.h(m0) + rng.standard_normal((B, problem.m))
    if name in ("eif", "cif"):
        istate = information.to_information(state)
        if name == "eif":
            return (lambda: information.eif_update(information.eif_predict(istate, model), z, model)), 1
        return (
            lambda: information.cif_update(information.cif_predict(istate, model), z, model)
        ), 2 * problem.n
    flt = registry.get(name)
    points = {
        "ukf": 2 * problem.n + 1,
        "ckf": 2 * problem.n,
        "ghkf": 3**problem.n,
        "ghkf5": 5**problem.n,
    }.get(name, 1)
    chunk = max(1, MAX_POINTS_PER_CALL // points)
    if B <= chunk:
        return (lambda: flt.update(flt.predict(state, model), z, model)), points
    parts = [
        (GaussianState(m0[i : i + chunk], P0[i : i + chunk]), z[i : i + chunk]) for i in range(0, B, chunk)
    ]
    return (lambda: [flt.update(flt.predict(s, model), zz, model) for s, zz in parts]), points


def _filterpy_times(problem: RangeTracking, repeats: int, clock: str = "wall") -> dict[str, float]:
    """Seconds per step of filterpy's KF, EKF, UKF and CKF on the same problem (one filter)."""
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    from filterpy.kalman import (
        CubatureKalmanFilter,
        ExtendedKalmanFilter,
        KalmanFilter,
        MerweScaledSigmaPoints,
        UnscentedKalmanFilter,
    )

    rng = np.random.default_rng(0)
    _, m0, P0 = problem.initial_state(1, rng)
    x0, P = m0[0], P0[0]
    z = problem.h(x0) + rng.standard_normal(problem.m)
    lin = problem.linear()
    out: dict[str, float] = {}

    kf = KalmanFilter(dim_x=9, dim_z=problem.m)
    kf.F, kf.H, kf.Q, kf.R = lin.transition_matrix, lin.observation_matrix, lin.Q, lin.R

    def kf_step():
        kf.x, kf.P = x0.copy(), P.copy()
        kf.predict()
        kf.update(z)

    out["kf"] = best_time(kf_step, repeats, clock=clock)

    ekf = ExtendedKalmanFilter(dim_x=9, dim_z=problem.m)
    ekf.Q, ekf.R = problem.Q, problem.R

    def ekf_step():
        ekf.x, ekf.P = x0.copy(), P.copy()
        ekf.F = problem.F(ekf.x)
        ekf.x = problem.f(ekf.x)
        ekf.P = ekf.F @ ekf.P @ ekf.F.T + ekf.Q
        ekf.update(z, problem.H, problem.h)

    out["ekf"] = best_time(ekf_step, repeats, clock=clock)

    fx = lambda x, dt: problem.f(x)  # noqa: E731
    ukf = UnscentedKalmanFilter(
        9, problem.m, problem.dt, problem.h, fx, MerweScaledSigmaPoints(9, 1.0, 2.0, 0.0)
    )
    ukf.Q, ukf.R = problem.Q, problem.R

    def ukf_step():
        ukf.x, ukf.P = x0.copy(), P.copy()
        ukf.predict()
        ukf.update(z)

    out["ukf"] = best_time(ukf_step, repeats, clock=clock)

    ckf = CubatureKalmanFilter(9, problem.m, problem.dt, problem.h, fx)
    ckf.Q, ckf.R = problem.Q, problem.R

    def ckf_step():
        ckf.x, ckf.P = x0.copy(), P.copy()
        ckf.predict()
        ckf.update(z.reshape(-1, 1))

    out["ckf"] = best_time(ckf_step, repeats, clock=clock)
    return out


def _simdkalman_step(problem: RangeTracking, B: int, rng: np.random.Generator):
    """One simdkalman predict + update (with its log-likelihood) of B filters, or None."""
    try:
        from simdkalman import primitives
    except ImportError:  # not installed: the column shows "-"
        return None
    lin = problem.linear()
    _, m0, P0 = problem.initial_state(B, rng)
    z = lin.h(m0) + rng.standard_normal((B, problem.m))
    m, zz = m0[:, :, None], z[:, :, None]
    F, Q, H, R = lin.transition_matrix, lin.Q, lin.observation_matrix, lin.R

    def step():
        mp, Pp = primitives.predict(m, P0, F, Q)
        return primitives._update(mp, Pp, H, R, zz, log_likelihood=True)

    return step


def run(args: argparse.Namespace) -> int:
    problem = RangeTracking()
    rows, records = [], []
    malloc = args.malloc
    if malloc == "retain" and not retain_heap():
        print("--malloc retain: mallopt not available (not glibc); the allocator is left as it is")
        malloc = "default"
    with single_core():
        ref = {} if args.no_filterpy else _filterpy_times(problem, args.repeats, args.clock)
        for name in args.filters:
            for B in args.batch:
                simd_step = _simdkalman_step(problem, B, np.random.default_rng(B)) if name == "kf" else None
                simd = None
                if simd_step is not None:
                    simd = best_time(simd_step, args.repeats, clock=args.clock) / B * 1e6
                for path in args.path:
                    fn, points = _step_fn(name, problem, B, np.random.default_rng(B))
                    repeats = args.repeats if points * B < 5_000_000 else 1
                    with numpy_only(path == "numpy"):
                        us = best_time(fn, repeats, clock=args.clock) / B * 1e6
                    fp = ref.get(name)
                    ratio = fp * 1e6 / us if fp else math.nan
                    target = TARGETS_US.get(name) if B == 1024 else None
                    verdict = "" if target is None else ("met" if us <= target else "MISSED")
                    if target is not None and simd is not None:
                        verdict += ", faster than simdkalman" if us < simd else ", slower than simdkalman"
                    rows.append(
                        [
                            name,
                            path,
                            B,
                            f"{us:.2f}",
                            f"{simd:.2f}" if simd is not None else "-",
                            f"{fp * 1e6:.1f}" if fp else "-",
                            f"{ratio:.1f}x" if fp else "-",
                            f"<= {target} {verdict}" if target else "",
                        ]
                    )
                    records.append(
                        {
                            "filter": name,
                            "path": path,
                            "B": B,
                            "us_per_filter_step": us,
                            "simdkalman_us_per_filter_step": simd,
                            "filterpy_us_per_step": None if fp is None else fp * 1e6,
                            "speedup_vs_filterpy": None if fp is None else ratio,
                            "target_us": target,
                        }
                    )
                    print(f"  {name:6s} {path:8s} B={B:<5d} {us:9.2f} us/filter-step", flush=True)
    print()
    print(
        "Filter throughput (9 states, 4 range measurements, one core; filter-step = predict + update; "
        f"{args.clock} clock, malloc {malloc})"
    )
    print(
        format_table(
            [
                "filter",
                "filters path",
                "B",
                "us/filter-step",
                "simdkalman us/filter-step",
                "filterpy us/step",
                "speed-up vs filterpy",
                "target (B=1024)",
            ],
            rows,
        )
    )
    path = write_json(
        args.json,
        {"problem": "RangeTracking(n=9, m=4)", "clock": args.clock, "malloc": malloc, "results": records},
    )
    print(f"\nJSON written to {path}")
    return 0
