"""agents.reporting: the README block writer shared by the studies and navgym benchmark."""

from pathlib import Path

import pytest

from agents.reporting import replace_marked_block


def test_the_block_between_the_markers_is_replaced_and_the_rest_kept(tmp_path: Path):
    p = tmp_path / "README.md"
    p.write_text("# t\n<!-- a -->\nold\nlines\n<!-- b -->\ntail <!-- a --> again\n")
    replace_marked_block(p, "<!-- a -->", "<!-- b -->", "new")
    assert p.read_text() == "# t\n<!-- a -->\nnew\n<!-- b -->\ntail <!-- a --> again\n"


def test_a_missing_marker_is_named(tmp_path: Path):
    p = tmp_path / "README.md"
    p.write_text("<!-- a -->\n")
    with pytest.raises(ValueError, match="README.md has no <!-- a --> ... <!-- b --> block"):
        replace_marked_block(p, "<!-- a -->", "<!-- b -->", "new")
    assert p.read_text() == "<!-- a -->\n"
