"""The switch of filters.core.compiled: numpy_only() nests and NAVGYM_NUMPY_ONLY forces NumPy."""

import os
import subprocess
import sys

from filters.core.compiled import ENV_VAR, compiled_enabled, numpy_only


def test_numpy_only_nests_and_restores():
    assert compiled_enabled()
    with numpy_only():
        assert not compiled_enabled()
        with numpy_only(False):
            assert compiled_enabled()
        assert not compiled_enabled()
    assert compiled_enabled()


def test_environment_variable_forces_numpy_in_a_fresh_process():
    code = "from filters.core.compiled import compiled_enabled, numpy_only\n" + (
        "a = compiled_enabled()\nwith numpy_only(False):\n    b = compiled_enabled()\nprint(a, b)"
    )
    for value, expected in (("1", "False False"), ("0", "True True"), ("", "True True")):
        env = {**os.environ, ENV_VAR: value}
        out = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
        assert out.stdout.strip() == expected, value
