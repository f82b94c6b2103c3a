"""glibc allocator tuning is opt-in: ``import navgym`` changes no process setting by itself."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import pytest

import navgym

CODE = "import navgym, navgym._malloc as m; print(m._done)"


def _done_after_import(**env: str) -> str:
    base = {k: v for k, v in os.environ.items() if k not in ("NAVGYM_MALLOPT", "NAVGYM_NO_MALLOPT")}
    proc = subprocess.run(
        [sys.executable, "-c", CODE], capture_output=True, text=True, check=True, env={**base, **env}
    )
    return proc.stdout.strip()


def test_import_navgym_does_not_call_mallopt():
    assert _done_after_import() == "False"
    assert _done_after_import(NAVGYM_MALLOPT="0") == "False"


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt is glibc's")
def test_navgym_mallopt_1_tunes_at_import():
    assert _done_after_import(NAVGYM_MALLOPT="1") == "True"
    assert _done_after_import(NAVGYM_MALLOPT="1", NAVGYM_NO_MALLOPT="1") == "False"


def test_tune_malloc_is_public():
    from navgym._malloc import tune_malloc

    assert navgym.tune_malloc is tune_malloc
