"""``navgym list``'s status column: superseded ids and the v3 ids worth training on (gate G1)."""

from __future__ import annotations

import pytest

from navgym.envs import ids
from navgym.envs.ids import status

IDS = ["navgym/AFading-v0", "navgym/AFading-v1", "navgym/AFading-v2", "navgym/ARowScale-v3"]


def test_an_id_with_a_later_version_is_superseded_by_the_latest():
    assert status("navgym/AFading-v0", IDS) == "superseded by -v2"
    assert status("navgym/AFading-v1", IDS) == "superseded by -v2"
    assert status("navgym/AFading-v2", IDS) == ""


@pytest.mark.parametrize(
    ("reach", "expected"),
    [
        (None, "G1 not measured"),
        ((30.6, 25.2, 36.5), "train: G1 +31 %"),
        ((20.0, 10.0, 30.0), "G1 failed (+20 %)"),
        ((26.0, -1.0, 50.0), "G1 failed (+26 %)"),  # the margin without a CI above 0 fails
    ],
)
def test_a_v3_id_is_marked_by_its_g1_figure(monkeypatch, reach, expected):
    monkeypatch.setattr(ids, "G1_REACH", {} if reach is None else {"navgym/ARowScale-v3": reach})
    assert status("navgym/ARowScale-v3", IDS) == expected


def test_the_real_data_v3_id_is_marked_for_evaluation():
    assert status("navgym/ReplayRowScale-v3", ["navgym/ReplayRowScale-v3"]) == "evaluation: real data"


def test_the_list_shows_the_status_column(capsys):
    from navgym.cli import main

    assert main(["list", "--json", "Robot2dFading"]) == 0
    import json

    rows = {r["id"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["navgym/Robot2dFading-v0"]["status"] == "superseded by -v2"
    assert rows["navgym/Robot2dFading-v2"]["status"] == ""
