"""Timing of the batched GNSS simulator step (a measurement helper, not a test).

``python -m navgym.gnss.bench [B ...]`` prints a table; :func:`measure_step_cost` returns the
numbers (used by the project's benchmark commands).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from navgym.geo.frames import geodetic_to_ecef
from navgym.gnss.almanac import load_default_almanac
from navgym.gnss.clock import clock_init, clock_step
from navgym.gnss.noise import make_regime
from navgym.gnss.simulate import (
    NORMALS_PER_ROW,
    UNIFORMS_PER_ROW,
    constellation,
    simulate_gnss_step,
)
from navgym.gnss.streams import EpisodeStreams, episode_generators

__all__ = ["measure_step_cost"]


def _best_ms(fn, steps: int, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        for k in range(steps):
            fn(k)
        best = min(best, (time.perf_counter() - t) / steps * 1e3)
    return float(best)


def measure_step_cost(
    batch: int, steps: int = 100, repeats: int = 5, m_max: int = 12, seed: int = 0
) -> dict[str, float]:
    """Best-of-``repeats`` wall time per step [ms] of the parts of a GNSS simulator step.

    Receivers at random places, shared GPS time, 1 s steps, mixture noise (eps = 0.1,
    variance ratio 100) so that every branch runs.

    Returns:
        ``{"batch", "constellation_ms", "measurements_ms", "clock_ms", "random_ms",
        "total_ms"}``: ``measurements_ms`` is :func:`simulate_gnss_step` given the
        constellation and the random draws (selection, pseudo- and delta-ranges,
        troposphere, noise shaping); ``random_ms`` the amortised per-episode draws
        (:class:`EpisodeStreams`, refills included).
    """
    rng = np.random.default_rng(seed)
    rx = geodetic_to_ecef(rng.uniform(-1.2, 1.2, batch), rng.uniform(-3.1, 3.1, batch), 100.0)
    vel = rng.normal(0.0, 10.0, (batch, 3))
    alm = load_default_almanac()
    n_z = NORMALS_PER_ROW * m_max
    streams = EpisodeStreams(episode_generators(seed, batch), n_z + 2, UNIFORMS_PER_ROW * m_max)
    z, u = streams.step()
    clock = clock_init(z[:, n_z:])
    regime = make_regime(batch, eps=0.1, var_ratio=100.0)
    t0 = float(alm.t_ref[0])
    orbit = constellation(alm, t0)
    out = {"batch": float(batch)}
    out["constellation_ms"] = _best_ms(lambda k: constellation(alm, t0 + k), steps, repeats)
    out["measurements_ms"] = _best_ms(
        lambda k: simulate_gnss_step(
            alm, t0, rx, vel, clock, regime, z[:, :n_z], u, m_max=m_max, orbit=orbit
        ),
        steps,
        repeats,
    )
    out["clock_ms"] = _best_ms(lambda k: clock_step(clock, 1.0, z[:, n_z:]), steps, repeats)
    out["random_ms"] = _best_ms(lambda k: streams.step(), streams.block, repeats)
    out["total_ms"] = sum(v for k, v in out.items() if k.endswith("_ms"))
    return out


def main(argv: list[str] | None = None) -> None:
    """Print the step cost for the batch sizes given on the command line (default 1, 1024)."""
    sizes = [int(a) for a in (argv if argv is not None else sys.argv[1:])] or [1, 1024]
    print(
        f"{'B':>6} {'constellation':>14} {'measurements':>13} {'clock':>8} {'random':>8} "
        f"{'total':>8}  [ms/step]"
    )
    for b in sizes:
        r = measure_step_cost(b)
        print(
            f"{b:>6d} {r['constellation_ms']:>14.3f} {r['measurements_ms']:>13.3f} "
            f"{r['clock_ms']:>8.3f} {r['random_ms']:>8.3f} {r['total_ms']:>8.3f}"
        )


if __name__ == "__main__":
    main()
