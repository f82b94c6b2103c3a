"""Files of an evaluation: CSV (per episode, summary, paired), markdown table, plots, manifest.

``write_outputs(results, out_dir)`` writes::

    episodes.csv   one row per (policy, episode): seed and every metric
    summary.csv    one row per policy: mean and bootstrap CI of every metric
    paired.csv     one row per (policy, metric): mean difference vs the reference and its CI
    report.md      the markdown table (and the definitions)
    error_time.png error over time of a few episodes (GNSS outages shaded), one line per policy,
                   the legend outside the axes
    error_cdf.png  CDF of the per-episode RMSE of each policy (one value per episode)
    rmse_box.png   per-episode RMSE per policy: violin and box
    forest.png     paired ΔRMSE of each policy vs the reference with BCa intervals (forest.csv)
    knob_trace.png with ``trace`` > 0: knob and error over time of that many episodes
    manifest.json  package versions, git commit, seeds, configuration, policies
"""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from agents.evaluation.metrics import METRICS, outage_runs
from agents.reporting import environment_versions, git_commit, jsonable, markdown_table, write_csv

__all__ = ["results_table", "write_outputs"]


def _fmt(x: float, digits: int = 1) -> str:
    if x is None or not math.isfinite(x):
        return "-"
    if abs(x) >= 1e4:
        return f"{x:.3g}"
    return f"{x:.{digits}f}"


def _ci(mean: float, lo: float, hi: float, digits: int = 1) -> str:
    if not math.isfinite(mean):
        return "-"
    return f"{_fmt(mean, digits)} [{_fmt(lo, digits)}, {_fmt(hi, digits)}]"


def results_table(results: Any) -> str:
    """The markdown table of an evaluation: one row per policy, paired differences against the reference.

    Ends with a newline (:func:`agents.reporting.markdown_table`).
    """
    ref = results.reference
    paired = {(p["policy"], p["metric"]): p for p in results.paired}
    show_res = any(math.isfinite(r["resamples"]) for r in results.summary)
    head = [
        "policy",
        "kind",
        "return [95% CI]",
        "RMSE m",
        "p95 m",
        "outage mean m",
        "outage end m",
        "NEES (median)",
        "diverged %",
    ]
    if show_res:
        head.append("resamples")
    head += ["Δreturn vs ref [95% CI]", "ΔRMSE m vs ref [95% CI]"]
    rows = []
    for r in results.summary:
        name = r["policy"] + (" (ref)" if r["policy"] == ref else "")
        cells = [
            name,
            r["kind"],
            _ci(r["return"], r["return_lo"], r["return_hi"]),
            _fmt(r["rmse_m"], 2),
            _fmt(r["p95_err_m"], 2),
            _fmt(r["outage_mean_err_m"], 2),
            _fmt(r["outage_end_err_m"], 2),
            _fmt(r["mean_nees_median"], 1),
            _fmt(100.0 * r["diverged"], 1),
        ]
        if show_res:
            cells.append(_fmt(r["resamples"], 1))
        for m, digits in (("return", 2), ("rmse_m", 2)):
            p = paired.get((r["policy"], m))
            cells.append(
                "-"
                if p is None
                else _ci(p["mean_diff"], p["low"], p["high"], digits) + ("*" if p["significant"] else "")
            )
        rows.append(cells)
    return markdown_table(rows, head)


def _report_md(results: Any, manifest: dict[str, Any]) -> str:
    s = results.seeds
    n = len(s)
    level = results.config.get("level", 0.95)
    return "\n".join(
        [
            f"# Evaluation: {results.env_id}",
            "",
            f"{n} held-out episodes (seeds {s[0]}..{s[-1]}), every policy on the same episodes; "
            f"env kwargs: `{json.dumps(results.env_kwargs)}`; commit `{manifest['git']['commit']}`.",
            f"Reference for the paired differences: **{results.reference}** (best baseline by mean "
            f"return unless set). Brackets: {int(100 * level)}% percentile bootstrap CI over episodes "
            f"({results.config.get('n_boot')} resamples); `*`: the CI of the difference excludes 0.",
            "",
            results_table(results),
            "Columns: mean over episodes of the per-episode return, horizontal RMSE, 95th-percentile error, "
            "mean error during GNSS outages and error at the end of each outage (episodes with outages "
            "only), median over episodes of the mean NEES, share of diverged (terminated) episodes"
            + (
                ", resamplings per episode"
                if any(math.isfinite(r["resamples"]) for r in results.summary)
                else ""
            )
            + ". Δ = policy − reference (higher return and lower errors are better). "
            "`oracle` rows read the truth: an optimistic reference, never a baseline.",
            "",
        ]
    )


def _plots(results: Any, out: Path, n_episodes: int = 3, trace: int = 0) -> list[Path]:
    """``error_time.png`` (a few episodes) and the per-episode plots (:mod:`.paper_plots`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.evaluation.paper_plots import write_paper_plots

    paths = []
    names = list(results.rollouts)
    first = results.rollouts[names[0]]
    gnss = first.steps.get("gnss_available")
    B = first.alive.shape[0]
    with_outage = [i for i in range(B) if gnss is not None and (~gnss[i, : first.length[i]]).any()]
    chosen = (with_outage + [i for i in range(B) if i not in with_outage])[: min(n_episodes, B)]
    fig, axes = plt.subplots(
        len(chosen), 1, figsize=(10, 2.8 * len(chosen)), squeeze=False, sharex=False, layout="constrained"
    )
    for ax, i in zip(axes[:, 0], chosen, strict=True):
        for name in names:
            r = results.rollouts[name]
            n = int(r.length[i])
            ax.plot(np.arange(1, n + 1) * r.dt, r.steps["pos_err_m"][i, :n], lw=1.0, label=name)
        if gnss is not None:
            for a, b in outage_runs(~gnss[i, : first.length[i]]):
                ax.axvspan(a * first.dt, b * first.dt, color="0.85", zorder=0)
        ax.set_yscale("log")
        ax.set_ylabel("horizontal error [m]")
        ax.set_title(f"episode seed {results.seeds[i]} (grey: GNSS outage)", fontsize=9)
    axes[-1, 0].set_xlabel("time [s]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize=7, frameon=False)  # off the data
    p = out / "error_time.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)
    paper = write_paper_plots(results, out, trace=trace)
    paths.append(paper["error_cdf"])
    paths += [paper[k] for k in ("rmse_box", "forest", "knob_trace") if k in paper]
    return paths


def write_outputs(
    results: Any,
    out_dir: str | Path,
    plots: bool = True,
    extra_manifest: dict[str, Any] | None = None,
    trace: int = 0,
) -> dict[str, Path]:
    """Write the files listed in the module docstring under ``out_dir``; return their paths.

    ``trace`` > 0 adds ``knob_trace.png`` of that many episodes (with ``plots``).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name, m in results.episodes.items():
        for i, s in enumerate(results.seeds):
            rows.append({"policy": name, "seed": s, **{k: m[k][i] for k in METRICS}})
    paths = {"episodes": out / "episodes.csv", "summary": out / "summary.csv", "paired": out / "paired.csv"}
    write_csv(paths["episodes"], rows)
    write_csv(paths["summary"], results.summary)
    write_csv(paths["paired"], results.paired)
    manifest = {
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "env_id": results.env_id,
        "env_kwargs": results.env_kwargs,
        "seeds": {
            "n": len(results.seeds),
            "first": results.seeds[0],
            "last": results.seeds[-1],
            "all": results.seeds,
        },
        "reference": results.reference,
        "policies": results.policies,
        "config": results.config,
        "versions": environment_versions(),
        "git": git_commit(),
        **(extra_manifest or {}),
    }
    paths["manifest"] = out / "manifest.json"
    paths["manifest"].write_text(json.dumps(jsonable(manifest), indent=2) + "\n")
    paths["report"] = out / "report.md"
    paths["report"].write_text(_report_md(results, manifest))
    if plots:
        for p in _plots(results, out, trace=trace):
            paths[p.stem] = p
    return paths
