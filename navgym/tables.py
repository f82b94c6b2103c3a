"""Plain-text tables for the command lines (``navgym list``, the benchmark commands)."""

from __future__ import annotations


def format_table(headers: list[str], rows: list[list[object]]) -> str:
    """A GitHub-flavoured markdown table (readable in a terminal too); numbers right-aligned."""
    cells = [[str(c) for c in r] for r in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h) for i, h in enumerate(headers)]
    line = "| " + " | ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)) + " |"
    sep = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    body = ["| " + " | ".join(_align(c, w) for c, w in zip(r, widths, strict=True)) + " |" for r in cells]
    return "\n".join([line, sep, *body])


def _align(cell: str, width: int) -> str:
    """Numbers right-aligned, text left-aligned."""
    try:
        float(cell.rstrip("x%").replace(",", ""))
    except ValueError:
        return cell.ljust(width)
    return cell.rjust(width)
