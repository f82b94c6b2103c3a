"""The benchmark commands run end to end on tiny sizes, print their tables and write JSON.

Smoke tests only: no timing is asserted (benchmarks are commands, not timed tests).
"""

import json

import pytest

from navgym.cli import main


@pytest.mark.parametrize(
    "argv, header",
    [
        ("sim --batch 2 --platforms vehicle robot --steps 2 --repeats 1".split(), "sim < filter"),
        ("particles --batch 2 --particles 16 --steps 1 --repeats 1".split(), "particle-steps/s"),
        (["filters", "--batch", "2", "--filters", "ekf", "--repeats", "1", "--no-filterpy"], "B=2"),
    ],
)
def test_bench_command_prints_a_table_and_writes_json(argv, header, tmp_path, capsys):
    out = tmp_path / "bench.json"
    assert main(["bench", *argv, "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert header in text and "|" in text
    data = json.loads(out.read_text())
    assert data
