"""``python -m experiments.knob_reach.bounds RESULTS_DIR [--widen 100] [--episodes 256]``: does a range bind?

A knob whose best setting sits at the end of its range may be held back by the range. This
probe takes a NoiseScale study of ``experiments.knob_reach`` (its ``results.json``: the env id,
its ``env_kwargs`` and the regime table found) and, on the same **tuning** episodes the table was
searched on, plays the regime oracle twice on an env whose ranges are ``--widen`` times wider at
both ends: with the table as found, and with every scale that sat at an end of the original
range pushed ``--widen`` times further out. If the second is not better, the range did not bind
(the knob had saturated: a process noise already far above the fixes' noise follows the fixes
whatever its size). The table's entries are scales ``10 ** (lo + (a + 1) / 2 (hi - lo))`` of the
original range.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from agents.seeds import seeds as seed_range
from experiments.knob_reach.__main__ import REGIMES, RegimeOracle, Scorer


def scales_of(table: dict[str, list[float]], lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``(regimes, 2)`` scales of a table of actions over log10 ranges ``lo``, ``hi``."""
    a = np.array([table[r] for r in REGIMES], dtype=np.float64)
    return 10.0 ** (lo + (a + 1.0) / 2.0 * (hi - lo))


def actions_of(scales: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The actions of ``scales`` over log10 ranges ``lo``, ``hi``."""
    return -1.0 + 2.0 * (np.log10(scales) - lo) / (hi - lo)


def probe(result: dict[str, Any], widen: float, episodes: int) -> dict[str, Any]:
    """The tuning-episode RMSE of the table as found and pushed out, on the widened ranges."""
    kw = dict(result.get("env_kwargs") or {})
    q, r = kw.get("q_scale_range", (0.1, 100.0)), kw.get("r_scale_range", (0.1, 100.0))
    lo, hi = np.log10([q[0], r[0]]), np.log10([q[1], r[1]])
    scales = scales_of(result["table"], lo, hi)
    at_low, at_high = np.isclose(np.log10(scales), lo), np.isclose(np.log10(scales), hi)
    pushed = np.where(at_low, scales / widen, np.where(at_high, scales * widen, scales))
    wide = {
        **kw,
        "q_scale_range": (q[0] / widen, q[1] * widen),
        "r_scale_range": (r[0] / widen, r[1] * widen),
    }
    wlo, whi = lo - np.log10(widen), hi + np.log10(widen)
    score = Scorer(result["env_id"], seed_range("tune", episodes), wide)
    as_found = score(RegimeOracle(score.codes, actions_of(scales, wlo, whi)))
    further = score(RegimeOracle(score.codes, actions_of(pushed, wlo, whi)))
    score.env.close()
    return {
        "env_id": result["env_id"],
        "entries_at_an_end": int(at_low.sum() + at_high.sum()),
        "table_rmse_m": as_found,
        "pushed_rmse_m": further,
        "change_pct": 100.0 * (further - as_found) / as_found,
        "widen": widen,
        "episodes": episodes,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m experiments.knob_reach.bounds", description=__doc__.split("\n\n")[1]
    )
    p.add_argument(
        "results", type=Path, nargs="+", help="folders of knob_reach NoiseScale studies (results.json)"
    )
    p.add_argument("--widen", type=float, default=100.0, help="how much further out the ends go")
    p.add_argument("--episodes", type=int, default=256, help="tuning episodes (those of the search)")
    a = p.parse_args(argv)
    for folder in a.results:
        for result in json.loads((folder / "results.json").read_text()):
            r = probe(result, a.widen, a.episodes)
            print(
                f"{r['env_id']}: {r['entries_at_an_end']} table entries at a range end; tuning RMSE "
                f"{r['table_rmse_m']:.3f} m as found, {r['pushed_rmse_m']:.3f} m pushed x{a.widen:g} "
                f"({r['change_pct']:+.2f} %)",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
