"""Per-episode plots of an evaluation, for a paper: distributions, paired differences, CDFs.

Every plot here takes one number per episode (the episode's horizontal RMSE), never the steps of
all episodes pooled, so that a long episode does not weigh more than a short one and the
intervals are over the unit that was sampled (the episode):

* ``rmse_box.png``: a violin (the distribution) with a box (quartiles, median) per policy;
* ``forest.png``: the paired difference of each policy's per-episode RMSE against the reference
  policy (the bar to beat), with its BCa bootstrap interval (``scipy.stats.bootstrap``,
  ``paired=True``: the episodes are resampled together); the numbers are in ``forest.csv``;
* ``error_cdf.png``: the empirical CDF of the per-episode RMSE of each policy;
* ``knob_trace.png`` (``trace`` episodes, ``navgym eval --trace N``): the knob each policy set
  over time (the mean of a vector knob's components) above its horizontal error, one column per
  episode, GNSS outages shaded.

The legends sit outside the axes. ``paired.csv`` (:mod:`agents.evaluation.bootstrap`) keeps its
own percentile intervals; the forest plot's BCa intervals are written beside it.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from agents.reporting import write_csv

__all__ = ["FOREST_METRIC", "episode_cdf", "forest_rows", "write_knob_trace", "write_paper_plots"]

#: The per-episode metric of these plots.
FOREST_METRIC = "rmse_m"


def episode_cdf(results: Any, metric: str = FOREST_METRIC) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{policy: (x, F)}``: the sorted per-episode values (finite ones) and their empirical CDF."""
    out = {}
    for name, m in results.episodes.items():
        x = np.sort(np.asarray(m[metric], dtype=np.float64))
        x = x[np.isfinite(x)]
        out[name] = (x, np.arange(1, x.size + 1) / max(x.size, 1))
    return out


def _bca(diff: np.ndarray, level: float, n_boot: int, seed: int) -> tuple[float, float]:
    """BCa interval of the mean of ``diff`` (the paired differences); the point for constant ones."""
    from scipy.stats import bootstrap

    if diff.size < 2 or np.ptp(diff) == 0.0:
        return float(diff.mean()), float(diff.mean())
    with warnings.catch_warnings():  # few episodes: BCa may warn of degenerate resamples
        warnings.simplefilter("ignore")
        res = bootstrap(
            (diff,),
            np.mean,
            confidence_level=level,
            n_resamples=n_boot,
            method="BCa",
            random_state=np.random.default_rng(seed),
        )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def forest_rows(results: Any, metric: str = FOREST_METRIC) -> list[dict[str, Any]]:
    """One row per policy but the reference: mean paired difference (policy - reference) and BCa CI.

    The bootstrap resamples episodes, each carrying both policies' values (``paired=True`` in
    ``scipy.stats.bootstrap`` terms: the statistic is the mean of the per-episode differences).
    Episodes where either value is not finite are left out (``n`` counts those kept).
    """
    ref = results.reference
    if ref is None or ref not in results.episodes:
        return []
    level = float(results.config.get("level", 0.95))
    n_boot = int(results.config.get("n_boot", 2000))
    seed = int(results.config.get("boot_seed", 0))
    base = np.asarray(results.episodes[ref][metric], dtype=np.float64)
    rows = []
    for name, m in results.episodes.items():
        if name == ref:
            continue
        x = np.asarray(m[metric], dtype=np.float64)
        ok = np.isfinite(x) & np.isfinite(base)
        d = x[ok] - base[ok]
        if d.size == 0:
            lo = hi = mean = math.nan
        else:
            mean = float(d.mean())
            lo, hi = _bca(d, level, n_boot, seed)
        rows.append(
            {
                "policy": name,
                "reference": ref,
                "metric": metric,
                "n": int(d.size),
                "mean_diff": mean,
                "low": lo,
                "high": hi,
                "level": level,
                "method": "BCa, paired",
            }
        )
    return rows


def _legend_outside(fig: Any, ax: Any) -> None:
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside right upper", fontsize=7, frameon=False)


def _box(results: Any, out: Path, plt: Any) -> Path:
    names = list(results.episodes)
    data = [np.asarray(results.episodes[n][FOREST_METRIC], dtype=np.float64) for n in names]
    data = [d[np.isfinite(d)] for d in data]
    fig, ax = plt.subplots(figsize=(max(5.0, 0.8 * len(names) + 2.0), 4.2), layout="constrained")
    pos = np.arange(1, len(names) + 1)
    keep = [i for i, d in enumerate(data) if d.size]
    if keep:
        if all(data[i].size > 1 for i in keep):
            ax.violinplot([data[i] for i in keep], positions=pos[keep], showextrema=False)
        ax.boxplot([data[i] for i in keep], positions=pos[keep], widths=0.25, showfliers=True)
    ax.set_xticks(pos, names, rotation=30, ha="right", fontsize=8)
    positive = [d[d > 0] for d in data if d.size]
    if positive and all(p.size for p in positive):
        lo, hi = min(p.min() for p in positive), max(p.max() for p in positive)
        if hi / lo > 30:
            ax.set_yscale("log")
    ax.set_ylabel("per-episode horizontal RMSE [m]")
    ax.set_title(f"{results.env_id}: {len(results.seeds)} episodes per policy", fontsize=9)
    ax.grid(alpha=0.3, axis="y")
    p = out / "rmse_box.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def _forest(results: Any, rows: list[dict[str, Any]], out: Path, plt: Any) -> Path:
    fig, ax = plt.subplots(figsize=(6.5, 0.45 * max(len(rows), 1) + 1.6), layout="constrained")
    y = np.arange(len(rows))[::-1]
    for yi, r in zip(y, rows, strict=True):
        if math.isfinite(r["mean_diff"]):
            ax.plot([r["low"], r["high"]], [yi, yi], color="0.3", lw=1.5)
            ax.plot(r["mean_diff"], yi, "o", color="C0" if r["high"] < 0 else "C3" if r["low"] > 0 else "0.3")
    ax.axvline(0.0, color="k", lw=0.8, ls="--")
    ax.set_yticks(y, [r["policy"] for r in rows], fontsize=8)
    level = int(round(100 * float(results.config.get("level", 0.95))))
    ax.set_xlabel(f"ΔRMSE vs {results.reference} [m] (mean of paired differences, {level}% BCa CI)")
    ax.set_title(f"{results.env_id}: left of 0 is better than the reference", fontsize=9)
    ax.grid(alpha=0.3, axis="x")
    p = out / "forest.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def _cdf(results: Any, out: Path, plt: Any) -> Path:
    fig, ax = plt.subplots(figsize=(7.5, 4.2), layout="constrained")
    for name, (x, f) in episode_cdf(results).items():
        if x.size:
            ax.step(x, f, where="post", lw=1.2, label=name)
    if any(x.size and x.min() > 0 for x, _ in episode_cdf(results).values()):
        ax.set_xscale("log")
    ax.set_xlabel("per-episode horizontal RMSE [m] (one value per episode)")
    ax.set_ylabel("share of episodes")
    ax.grid(alpha=0.3)
    ax.set_title(results.env_id, fontsize=9)
    _legend_outside(fig, ax)
    p = out / "error_cdf.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def write_knob_trace(results: Any, out: str | Path, n_episodes: int, plt: Any = None) -> Path:
    """``knob_trace.png``: knob and error over time of each policy on the first ``n_episodes``."""
    from agents.evaluation.metrics import outage_runs

    if plt is None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    names = list(results.rollouts)
    first = results.rollouts[names[0]]
    chosen = list(range(min(int(n_episodes), first.alive.shape[0])))
    fig, axes = plt.subplots(
        2, len(chosen), figsize=(4.2 * len(chosen) + 1.8, 5.2), squeeze=False, layout="constrained"
    )
    gnss = first.steps.get("gnss_available")
    for col, i in enumerate(chosen):
        top, bottom = axes[0, col], axes[1, col]
        for name in names:
            r = results.rollouts[name]
            n = int(r.length[i])
            t = np.arange(1, n + 1) * r.dt
            if "knob" in r.steps:
                top.plot(t, r.steps["knob"][i, :n], lw=1.0, label=name)
            bottom.plot(t, r.steps["pos_err_m"][i, :n], lw=1.0)
        if gnss is not None:
            for a, b in outage_runs(~gnss[i, : first.length[i]]):
                for ax in (top, bottom):
                    ax.axvspan(a * first.dt, b * first.dt, color="0.85", zorder=0)
        top.set_title(f"episode seed {results.seeds[i]}", fontsize=9)
        bottom.set_yscale("log")
        bottom.set_xlabel("time [s]")
    axes[0, 0].set_ylabel("knob (mean of its components)")
    axes[1, 0].set_ylabel("horizontal error [m]")
    _legend_outside(fig, axes[0, 0])
    p = Path(out) / "knob_trace.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def write_paper_plots(results: Any, out: str | Path, trace: int = 0) -> dict[str, Path]:
    """Write the per-episode plots (module docstring) under ``out``; return their paths.

    ``rmse_box.png``, ``forest.png`` (with ``forest.csv``), ``error_cdf.png`` and, with ``trace``
    > 0, ``knob_trace.png`` of that many episodes.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    rows = forest_rows(results)
    paths = {"rmse_box": _box(results, out, plt), "error_cdf": _cdf(results, out, plt)}
    if rows:
        paths["forest_csv"] = out / "forest.csv"
        write_csv(paths["forest_csv"], rows)
        paths["forest"] = _forest(results, rows, out, plt)
    if trace > 0:
        paths["knob_trace"] = write_knob_trace(results, out, trace, plt)
    return paths
