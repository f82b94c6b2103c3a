"""What every study writes beside its plots and tables: a manifest of how it was made.

The git state, the package versions, the CSV writer and the markdown table are
:mod:`agents.reporting`'s, so studies and evaluations record the same provenance.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from agents.reporting import environment_versions, git_commit

__all__ = ["write_manifest"]


def write_manifest(out: Path, module: str, argv: list[str] | None, **fields: Any) -> Path:
    """``out/manifest.json``: the command that ran ``module``, ``fields``, git state, versions."""
    command = " ".join([f"python -m {module}", *(sys.argv[1:] if argv is None else argv)])
    manifest = {"command": command, **fields, "git": git_commit(), "versions": environment_versions()}
    path = Path(out) / "manifest.json"
    path.write_text(json.dumps(manifest, indent=1))
    return path
