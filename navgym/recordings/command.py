"""``navgym recording check DIR``: read a recording, run its checks, print a summary.

A plugin of the ``navgym`` command line (:mod:`navgym.cli`): :func:`register` adds the
``recording`` command with its ``check`` sub-command. The summary (:func:`~navgym.recordings.
checks.format_report`) gives the duration, the IMU and GNSS rates, the IMU gaps, the solution's
quality shares, how the velocity was obtained, the mount's fitted residual (gravity while still
against the body's up axis) and the gyro against the GNSS heading rate (scale, lag,
correlation), then every problem (:mod:`navgym.recordings.checks`). Exit status 0: no problem;
1: problems listed; a file that cannot be read raises ``ValueError`` (``navgym`` prints it as
``navgym recording: error: ...`` with status 2). Also runs as ``python -m
navgym.recordings.command check DIR``.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, TextIO


def check_directory(directory: str, out: TextIO | None = None) -> int:
    """Print the check report of the recording in ``directory``; 0 if it has no problem, else 1.

    Raises:
        ValueError: the directory, its sidecar or a file cannot be read (the loader's message).
    """
    from navgym.recordings.checks import check_recording, format_report
    from navgym.recordings.loader import read_recording

    rec, sources = read_recording(directory)
    check = check_recording(rec, sources)
    print(format_report(check, rec.fix_q, rec.truth_q), file=out or sys.stdout)
    return 1 if check.problems else 0


def _run_check(args: argparse.Namespace) -> int:
    return check_directory(args.directory)


def register(subparsers: Any) -> None:
    """Add ``recording check DIR`` to the ``navgym`` sub-commands (``subparsers`` of argparse)."""
    parser = subparsers.add_parser(
        "recording", help="check a recording directory (IMU CSV + RTKLIB .pos + recording.toml)"
    )
    sub = parser.add_subparsers(dest="recording_command", required=True)
    check = sub.add_parser(
        "check",
        help="read the recording, run the plausibility checks and print a summary (exit 1 on problems)",
        description=__doc__.splitlines()[0],
    )
    check.add_argument("directory", help="the recording directory (imu.csv, gnss.pos, recording.toml)")
    check.set_defaults(_run=_run_check)


def main(argv: list[str] | None = None) -> int:
    """``recording check DIR`` without the ``navgym`` entry point (``python -m``)."""
    parser = argparse.ArgumentParser(prog="navgym")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["recording", *(sys.argv[1:] if argv is None else argv)])
    from navgym.cli_errors import report_errors

    return report_errors("navgym recording", args._run, args)


if __name__ == "__main__":
    sys.exit(main())
