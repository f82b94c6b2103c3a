"""The docs site builds: ``mkdocs build --strict`` (mkdocs.yml, the hook docs/gen_site.py).

Strict mode fails on any warning, a relative link that leads nowhere included. The site has the
README as home, every page of ``docs/``, a page per env card (generated at the build, nothing
committed) listing every registered id, and the study READMEs.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import navgym  # noqa: F401
from navgym.envs.registration import ENVIRONMENTS

ROOT = Path(__file__).resolve().parents[1]

pytest.importorskip("material", reason="the docs extra: pip install -e '.[docs]' (make setup-test)")


def test_mkdocs_build_strict(tmp_path):
    site = tmp_path / "site"
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"), "-d", site],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "navgym" in (site / "index.html").read_text()  # the README
    for page in (ROOT / "docs").glob("*.md"):
        name = "" if page.stem == "README" else page.stem
        assert (site / "docs" / name / "index.html").is_file(), page
    for study in (ROOT / "experiments").glob("*/README.md"):
        assert (site / "experiments" / study.parent.name / "index.html").is_file(), study
    modules = {gym.spec(e.id).entry_point.partition(":")[0] for e in ENVIRONMENTS}
    assert {p.name for p in (site / "envs").iterdir() if p.is_dir()} == modules  # a page per card
    index = (site / "envs" / "index.html").read_text()
    assert all(e.id in index for e in ENVIRONMENTS)
    assert "## Observation Space" not in (site / "envs" / "navgym.robot2d.env_v2" / "index.html").read_text()
    assert not (ROOT / "docs" / "envs").exists()  # generated at the build, not committed
