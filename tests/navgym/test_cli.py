"""The ``navgym`` command: ``list`` is its own, the other sub-commands come from entry points."""

from __future__ import annotations

import subprocess
import sys
from importlib.metadata import EntryPoint

import pytest

from navgym import cli


def test_the_library_imports_no_layer_above_it():
    code = (
        "import sys, navgym, navgym.cli, navgym.envs.listing; "
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'agents', 'benchmarks', 'experiments'}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_installed_package_registers_every_command():
    eps = {ep.name: ep for ep in cli.command_entry_points()}
    assert set(eps) == {
        "bench",
        "dataset",
        "soak",
        "recording",
        "render",
        "train",
        "tune",
        "eval",
        "benchmark",
        "export",
        "import",
        "demo",
        "sweep",
    }
    assert eps["bench"].extras == [] and eps["train"].extras == ["agents"]
    assert eps["sweep"].extras == ["scale"] and eps["recording"].extras == []
    actions = cli._build_parser([])._subparsers._group_actions[0].choices
    assert set(actions) == {"list", *eps}


def _commands_loaded(argv: list[str]) -> list[str]:
    code = (
        "import sys\n"
        "from navgym.cli import _build_parser\n"
        f"parser = _build_parser({argv!r})\n"
        "print(sorted(parser._subparsers._group_actions[0].choices))\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'agents', 'benchmarks'}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return out.splitlines()


def test_a_command_loads_only_its_own_entry_point():
    assert _commands_loaded(["list"]) == ["['list']", "[]"]
    assert _commands_loaded(["bench", "filters", "-h"]) == ["['bench', 'list']", "['benchmarks']"]
    assert _commands_loaded(["eval", "--env", "x"]) == ["['eval', 'list']", "['agents']"]
    every = str(
        sorted(
            {
                "bench",
                "benchmark",
                "dataset",
                "demo",
                "eval",
                "export",
                "import",
                "list",
                "recording",
                "render",
                "soak",
                "sweep",
                "train",
                "tune",
            }
        )
    )
    assert _commands_loaded([])[0] == every and _commands_loaded(["-h"])[0] == every
    assert _commands_loaded(["nosuchcommand"])[0] == every


def test_list_prints_the_registry(capsys):
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("| id ") and "navgym/GpsInsFading-v0" in out


def test_a_command_whose_module_is_missing_says_what_to_install(monkeypatch, capsys):
    eps = [
        EntryPoint("needy", "no_such_module_for_navgym:register [extra1]", cli.COMMAND_GROUP),
        EntryPoint("plain", "no_such_module_for_navgym.sub:register", cli.COMMAND_GROUP),
    ]
    monkeypatch.setattr(cli, "command_entry_points", lambda: eps)
    assert cli.main(["needy"]) == 2
    assert capsys.readouterr().out.strip() == (
        "navgym needy: needs the 'extra1' extra (missing module 'no_such_module_for_navgym'); "
        "pip install -e '.[extra1]'"
    )
    assert cli.main(["plain"]) == 2
    out = capsys.readouterr().out
    assert "needs an optional dependency (missing module 'no_such_module_for_navgym')" in out
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "needy (needs the 'extra1' extra: no_such_module_for_navgym missing)" in help_text


def test_version_is_the_installed_distributions_and_loads_no_command():
    from importlib.metadata import version

    import navgym

    assert navgym.__version__ == version("navgym")
    code = (
        "import sys\n"
        "from navgym.cli import main\n"
        "try:\n"
        "    main(['--version'])\n"
        "except SystemExit as exc:\n"
        "    print('exit', exc.code)\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'agents', 'benchmarks'}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.splitlines() == [f"navgym {navgym.__version__}", "exit 0", "[]"]
