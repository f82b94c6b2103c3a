"""``navgym recording check DIR`` (issue 38, item 6): the plugin's ``register`` and its report.

The entry point is declared in pyproject.toml by its owner; these tests call ``register`` on an
argparse parser directly, as ``navgym.cli`` does with every ``navgym.commands`` entry point.
"""

from __future__ import annotations

import argparse
import shutil

import pytest

from navgym.recordings import command
from navgym.recordings.loader import PACKAGED


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="navgym")
    command.register(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def test_check_prints_the_summary_of_the_packaged_walk(capsys):
    args = _parse(["recording", "check", str(PACKAGED)])
    assert args._run(args) == 0
    out = capsys.readouterr().out
    for row in (
        "recording walk_0827",
        "IMU            134.3 s, 20455 samples, 166.6 Hz",
        "IMU gaps       none",
        "GNSS           133.8 s, 536 epochs, 4 Hz, 0 missing",
        "Q1 fixed 65.1 %, Q2 float 34.9 %",
        "velocity       vn/ve/vu columns",
        "mount          residual 1.6 deg",
        "gyro vs GNSS   scale 0.8",
        "result         OK",
    ):
        assert row in out, (row, out)
    assert "np.float" not in out


def test_check_lists_the_problems_and_exits_1(tmp_path, capsys):
    d = tmp_path / "walk"
    shutil.copytree(PACKAGED, d)
    side = d / "recording.toml"
    side.chmod(0o644)
    side.write_text(side.read_text().replace('gyro_unit = "rad/s"', 'gyro_unit = "deg/s"'))
    args = _parse(["recording", "check", str(d)])
    assert args._run(args) == 1
    out = capsys.readouterr().out
    assert "result         1 problem(s):" in out and "gyro: the rates about the vertical are 0.01" in out


def test_check_of_a_missing_directory_is_a_user_error(tmp_path, capsys):
    with pytest.raises(ValueError, match=r"the recording directory does not exist"):
        command.check_directory(str(tmp_path / "nowhere"))
    assert command.main(["check", str(tmp_path / "nowhere")]) == 2
    assert "navgym recording: error: " in capsys.readouterr().err


def test_the_sub_command_is_required():
    with pytest.raises(SystemExit):
        _parse(["recording"])
