"""What every study writes beside its plots: its table as CSV and markdown, and a manifest.

The CSV writer, the git state and the package versions are the evaluation's
(:mod:`agents.evaluation.report`), so studies and evaluations record the same provenance.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from agents.evaluation.report import environment_versions, git_commit, write_csv

__all__ = ["markdown_table", "write_csv", "write_manifest"]


def markdown_table(rows: list[dict[str, Any]], header: list[str] | None = None) -> str:
    """A markdown table of ``rows`` (one dict per row); the header is the first row's keys or ``header``."""
    cols = list(rows[0]) if header is None else header
    head = "| " + " | ".join(cols) + " |\n|" + "---|" * len(cols) + "\n"
    return head + "".join("| " + " | ".join(str(v) for v in r.values()) + " |\n" for r in rows)


def write_manifest(out: Path, module: str, argv: list[str] | None, **fields: Any) -> Path:
    """``out/manifest.json``: the command that ran ``module``, ``fields``, git state, versions."""
    command = " ".join([f"python -m {module}", *(sys.argv[1:] if argv is None else argv)])
    manifest = {"command": command, **fields, "git": git_commit(), "versions": environment_versions()}
    path = Path(out) / "manifest.json"
    path.write_text(json.dumps(manifest, indent=1))
    return path
