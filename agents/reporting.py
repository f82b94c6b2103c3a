"""What every run records beside its numbers: git state, package versions, CSV and markdown tables.

The one home of these helpers for ``agents/`` (evaluation, training, tuning, sweeps) and the
studies (:mod:`experiments.outputs`), so that every file they write records its provenance the
same way:

* :func:`git_commit` — ``{"commit", "dirty"}`` of the repository holding the code;
* :func:`environment_versions` — Python, the platform and the packages that matter;
* :func:`write_csv` — rows (dicts) as CSV, values made plain (:func:`jsonable`);
* :func:`markdown_table` — rows as a markdown table.

Nothing here imports navgym or the learning libraries.
"""

from __future__ import annotations

import csv
import math
import platform
import subprocess
import sys
from collections.abc import Mapping, Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "PACKAGES",
    "REPO_ROOT",
    "environment_versions",
    "git_commit",
    "jsonable",
    "markdown_table",
    "write_csv",
]

#: The repository holding this code (its git state is what :func:`git_commit` reads).
REPO_ROOT = Path(__file__).resolve().parents[1]
#: Packages whose versions :func:`environment_versions` records.
PACKAGES = ("numpy", "scipy", "gymnasium", "stable-baselines3", "torch", "matplotlib", "tqdm", "navgym")


def git_commit(root: Path = REPO_ROOT) -> dict[str, Any]:
    """``{"commit": sha or None, "dirty": bool or None}`` of the repository at ``root``.

    ``dirty``: tracked files differ from the commit (untracked files do not count); both
    ``None`` when git is not available or ``root`` is not a checkout.
    """
    try:
        sha = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
        status = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout
        return {"commit": sha, "dirty": bool(status.strip())}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}


def environment_versions(packages: Sequence[str] = PACKAGES) -> dict[str, str | None]:
    """Versions of Python, the platform and ``packages`` (``None`` where not installed)."""
    out: dict[str, str | None] = {"python": sys.version.split()[0], "platform": platform.platform()}
    for p in packages:
        try:
            out[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            out[p] = None
    return out


def jsonable(x: Any) -> Any:
    """``x`` with NumPy values as Python ones, tuples as lists and non-finite floats as ``None``."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    return x


def replace_marked_block(path: str | Path, begin: str, end: str, block: str) -> None:
    """Put ``block`` between the markers ``begin`` and ``end`` of the file ``path``.

    The studies and ``navgym benchmark --readme`` write their README tables this way; the text
    outside the markers is kept as it is.

    Raises:
        ValueError: ``path`` lacks one of the markers (the path and the markers named).
    """
    p = Path(path)
    body = p.read_text()
    if begin not in body or end not in body:
        raise ValueError(f"{p} has no {begin} ... {end} block")
    head, _, rest = body.partition(begin)
    p.write_text(f"{head}{begin}\n{block}\n{end}{rest.partition(end)[2]}")


def write_csv(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """Write ``rows`` (one dict per row) to ``path`` as CSV.

    The columns are the rows' keys in first-seen order; a row without a column leaves its cell
    empty, and so does a non-finite number (values pass through :func:`jsonable`). No rows:
    an empty file.
    """
    path = Path(path)
    if not rows:
        path.write_text("")
        return
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: jsonable(r[k]) if k in r else "" for k in cols})


def markdown_table(
    rows: Sequence[Mapping[str, Any]] | Sequence[Sequence[Any]],
    header: Sequence[str] | None = None,
    *,
    align: str | None = None,
) -> str:
    """A markdown table: a header line, the separator, one line per row; ends with a newline.

    Args:
        rows: one dict per row (its values, in order, are the cells) or one sequence of cells.
        header: the column titles; default the first row's keys.
        align: one character per column, ``l`` (``---``, the default) or ``r`` (``---:``).

    Cells are ``str(value)``: format numbers before. No columns (no rows and no header): ``""``.
    """
    if header is None:
        first = rows[0] if rows else {}
        if not isinstance(first, Mapping):
            raise ValueError("markdown_table needs a header for rows that are not dicts")
        header = list(first)
    cols = list(header)
    if not cols:
        return ""
    marks = align or "l" * len(cols)
    if len(marks) != len(cols) or set(marks) - {"l", "r"}:
        raise ValueError(f"align must be one of 'l' / 'r' per column ({len(cols)}); got {align!r}")
    lines = ["| " + " | ".join(cols) + " |", "|" + "".join("---:|" if m == "r" else "---|" for m in marks)]
    for r in rows:
        cells = r.values() if isinstance(r, Mapping) else r
        lines.append("| " + " | ".join(str(v) for v in cells) + " |")
    return "\n".join(lines) + "\n"
