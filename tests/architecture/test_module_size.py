"""Small modules with one concept each: no module of ``navgym`` over 700 lines (docs/architecture.md)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAX_LINES = 700


def test_no_navgym_module_over_the_limit():
    sizes = {
        str(p.relative_to(ROOT)): len(p.read_text(encoding="utf-8").splitlines())
        for p in (ROOT / "navgym").rglob("*.py")
    }
    assert sizes, "no navgym modules found"
    over = {name: n for name, n in sizes.items() if n > MAX_LINES}
    assert over == {}, f"modules over {MAX_LINES} lines: {over}"
