"""The files of ``navgym benchmark``: ``leaderboard.{md,json,csv}`` and ``manifest.json``.

* ``leaderboard.md``: the table (one row per id and policy), the across-ids table when an agent
  label covers several ids, the protocol in a few lines, the skipped references and the notes;
* ``leaderboard.json``: the rows, the across-ids rows, and per id its bar, seeds, references
  and every policy's per-episode RMSE, return and divergence flag (enough to recompute any
  paired comparison);
* ``leaderboard.csv``: the rows, flat;
* ``manifest.json``: the command, the seeds, the settings, the agents (folders, kinds, what their
  manifests record), the tuned files (SHA-256), the git commit and package versions, wall times.
"""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from agents.benchmark.protocol import Leaderboard
from agents.reporting import (
    environment_versions,
    git_commit,
    jsonable,
    markdown_table,
    replace_marked_block,
    write_csv,
)

__all__ = [
    "README_BEGIN",
    "README_END",
    "compact_markdown",
    "markdown",
    "write_leaderboard",
    "write_readme_block",
]

#: The markers of the leaderboard block of a README (``navgym benchmark --readme FILE``).
README_BEGIN, README_END = "<!-- leaderboard:begin -->", "<!-- leaderboard:end -->"
#: The roles a compact leaderboard keeps (the other tuned baselines and single seeds are left out).
COMPACT_ROLES = ("plain", "bar", "agent", "reference")

HEADER = (
    "id",
    "policy",
    "role",
    "RMSE [m]",
    "return",
    "ΔRMSE % vs bar [95 % CI]",
    "diverged",
    "across seeds: mean / IQM ΔRMSE % [95 % CI]",
)


def _f(x: Any, fmt: str) -> str:
    return "n/a" if x is None or not math.isfinite(float(x)) else format(float(x), fmt)


def _ci(v: Any, lo: Any, hi: Any) -> str:
    return f"{_f(v, '+.1f')} [{_f(lo, '+.1f')}, {_f(hi, '+.1f')}]"


def _seeds_cell(row: dict[str, Any]) -> str:
    a = row.get("across_seeds", {}).get("delta_pct")
    if not a:
        return ""
    return f"{_ci(a['mean'], a['mean_low'], a['mean_high'])} / {_ci(a['iqm'], a['iqm_low'], a['iqm_high'])}"


def _cells(row: dict[str, Any]) -> list[str]:
    name = f"**{row['policy']}**" if row["role"] == "bar" else row["policy"]
    delta = "bar" if row["role"] == "bar" else _ci(row["delta_pct"], row["delta_low"], row["delta_high"])
    return [
        f"`{row['id'].split('/')[-1]}`",
        name,
        row["role"],
        _f(row["rmse_m"], ".3f"),
        _f(row["return"], ".1f"),
        delta,
        f"{100 * row['diverged']:.1f} %",
        _seeds_cell(row),
    ]


def markdown(board: Leaderboard) -> str:
    """The leaderboard as markdown (module docstring)."""
    c = board.config
    lines = [
        "# navgym benchmark",
        "",
        f"{c['episodes']} held-out episodes per id (evaluation seeds "
        f"{c['seeds']['first']}-{c['seeds']['last']}, "
        "the same for every policy: paired); the bar of each id is its best tuned classical baseline "
        "(highest tuning score, chosen on tuning seeds before evaluation). ΔRMSE % = 100 mean(policy - bar) "
        f"/ mean(bar), with a paired percentile bootstrap {100 * c['level']:.0f} % CI over episodes "
        f"({c['n_boot']} resamples); below 0 is better than the bar. Across training seeds: the mean and the "
        f"IQM of the seeds' ΔRMSE %, stratified-bootstrap CIs ({c['seed_reps']} resamples; Agarwal et al. "
        "2021). References read truth and are never baselines.",
        "",
    ]
    if c["env_kwargs"]:
        lines += [f"**Non-standard env kwargs**: `{json.dumps(c['env_kwargs'])}`.", ""]
    seeds = any("across_seeds" in r for r in board.rows)  # the last column only with multi-seed agents
    cells = [_cells(r) if seeds else _cells(r)[:-1] for r in board.rows]
    lines.append(
        markdown_table(cells, HEADER if seeds else HEADER[:-1], align="lllrrrrl"[: len(HEADER) - (not seeds)])
    )
    if board.across_ids:
        lines += ["", "## Across ids (strata: the ids, runs: training seeds)", ""]
        lines.append(
            markdown_table(
                [
                    [
                        a["agent"],
                        ", ".join(f"`{i.split('/')[-1]}` ({a['runs'][i]})" for i in a["ids"]),
                        _ci(a["mean"], a["mean_low"], a["mean_high"]),
                        _ci(a["iqm"], a["iqm_low"], a["iqm_high"]),
                    ]
                    for a in board.across_ids
                ],
                ("agent", "ids (runs)", "mean ΔRMSE % [95 % CI]", "IQM ΔRMSE % [95 % CI]"),
            )
        )
    refs = [
        f"* `{i.split('/')[-1]}` {label}: {ref['source']}"
        + (f", table {tuple(ref['table'])}" if "table" in ref else "")
        for i, res in board.results.items()
        for label, ref in res.references.items()
    ]
    skipped = [
        f"* `{i.split('/')[-1]}` {label} skipped: {why}"
        for i, res in board.results.items()
        for label, why in res.skipped.items()
    ]
    if refs or skipped:
        lines += ["", "## References", "", *refs, *skipped]
    if board.notes:
        lines += ["", "## Notes", "", *[f"* {n}" for n in board.notes]]
    return "\n".join(lines) + "\n"


def compact_markdown(board: Leaderboard, command: str) -> str:
    """A README's leaderboard, the command under it.

    Per id: the plain filter, the bar, each agent (a multi-seed one as its mean of seeds, with the
    across-seed CIs) and the references.
    """
    rows = [r for r in board.rows if r["role"] in COMPACT_ROLES or str(r["role"]).startswith("mean of")]
    seeds = any("across_seeds" in r for r in rows)
    header = ["id", "policy", "role", "RMSE m", "ΔRMSE % vs bar [95 % CI]"]
    cells = []
    for r in rows:
        full = _cells(r)
        row = [full[0], full[1], full[2], full[3], full[5]]
        if seeds:
            a = r.get("across_seeds", {}).get("delta_pct")
            row.append(_ci(a["iqm"], a["iqm_low"], a["iqm_high"]) if a else "")
        cells.append(row)
    table = markdown_table(cells, [*header, "seeds' IQM ΔRMSE % [95 % CI]"] if seeds else header)
    conf = board.config
    return (
        f"{table.rstrip()}\n\n`{command}`: {conf['episodes']} held-out episodes per id, paired "
        f"{100 * conf['level']:.0f} % "
        "bootstrap CIs against the bar (the best tuned classical baseline, fixed by its tuning score); "
        "every baseline's row and the seeds' rows: the command's `leaderboard.md`."
    )


def write_readme_block(path: str | Path, block: str) -> None:
    """Put ``block`` between :data:`README_BEGIN` and :data:`README_END` of ``path`` (both must be there)."""
    try:
        replace_marked_block(path, README_BEGIN, README_END, block)
    except ValueError as e:
        raise ValueError(f"--readme: {e}") from None


def _json(board: Leaderboard) -> dict[str, Any]:
    ids = {
        env_id: {
            "bar": res.bar,
            "bar_tuning_score": res.bar_score,
            "seeds": res.seeds,
            "roles": res.roles,
            "agents": res.agents,
            "references": res.references,
            "skipped_references": res.skipped,
            "wall_s": res.wall_s,
            "episodes": res.episodes,
        }
        for env_id, res in board.results.items()
    }
    return {
        "protocol": board.config,
        "rows": board.rows,
        "across_ids": board.across_ids,
        "ids": ids,
        "notes": board.notes,
    }


def _manifest(board: Leaderboard, command: list[str] | None) -> dict[str, Any]:
    from agents.baselines.registry import tuned_path
    from agents.training.agent_files import sha256_file

    tuned = {}
    for env_id in board.results:
        p = tuned_path(env_id)
        tuned[env_id] = {"path": str(p), "sha256": sha256_file(p) if p.is_file() else None}
    return {
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": command,
        "protocol": board.config,
        "ids": list(board.results),
        "seeds": {
            i: {"n": len(r.seeds), "first": r.seeds[0], "last": r.seeds[-1]} for i, r in board.results.items()
        },
        "bars": {i: {"name": r.bar, "tuning_score": r.bar_score} for i, r in board.results.items()},
        "tuned_files": tuned,
        "agents": [
            {
                "label": s.label,
                "path": str(s.path),
                "kind": s.kind,
                "env_id": s.env_id,
                "seeds": [{"name": n or None, "path": str(p)} for n, p in s.seeds],
                "record": s.record,
                "train_env_kwargs": s.train_env_kwargs,
            }
            for s in board.agents
        ],
        "wall_s": {i: r.wall_s for i, r in board.results.items()},
        "versions": environment_versions(),
        "git": git_commit(),
    }


def write_leaderboard(
    board: Leaderboard, out: str | Path, command: list[str] | None = None
) -> dict[str, Path]:
    """Write the files of the module docstring under ``out``; return their paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {k: out / f"leaderboard.{k}" for k in ("md", "json", "csv")}
    paths["manifest"] = out / "manifest.json"
    paths["md"].write_text(markdown(board))
    paths["json"].write_text(json.dumps(jsonable(_json(board)), indent=1) + "\n")
    write_csv(
        paths["csv"], [{k: v for k, v in r.items() if k != "across_seeds"} | _flat(r) for r in board.rows]
    )
    paths["manifest"].write_text(json.dumps(jsonable(_manifest(board, command)), indent=2) + "\n")
    return paths


def _flat(row: dict[str, Any]) -> dict[str, Any]:
    """The across-seed statistics of an aggregate row as flat columns (``seeds_delta_pct_iqm``, ...)."""
    out = {}
    for metric, stats in row.get("across_seeds", {}).items():
        for k, v in stats.items():
            out[f"seeds_{metric}_{k}"] = v
    if "seeds" in row:
        out["seeds"] = " ".join(row["seeds"])
    return out
