"""The mkdocs hook of the docs site (``mkdocs.yml``, ``hooks:``): its pages, none of them committed.

The site mirrors the repository's layout, so that the relative links of the Markdown files work
as they do on a forge: the README is the home page (``README.md``), the files of ``docs/`` stay
under ``docs/``, the study READMEs under ``experiments/<study>/``, and ``CHANGELOG.md`` is a page.
Every env card (a platform's ``Env`` class docstring, filled from the code) becomes a page
``envs/<module>.md``, with ``envs/index.md`` listing every registered id; these pages are
generated in memory at each build. Any other file of the repository a page links to (a source
file, an image) is copied as it is, so the links stay valid; a folder linked becomes its
README (a package without one: its ``__init__.py``). Images of ``results/`` (written by a
study's run, not tracked) are named, not shown.

``mkdocs build --strict`` (``pip install -e '.[docs]'``) builds it; ``tests/test_docs_site.py``
runs that.
"""

from __future__ import annotations

import importlib
import re
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: Relative link targets of a Markdown page: ``[text](target)`` and ``![alt](target)``.
LINK = re.compile(r"\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
#: Sphinx roles of the cards (``:mod:`x```, ``:class:`~a.B```), shown as code in Markdown.
ROLE = re.compile(r":(?:mod|class|func|meth|data|attr|obj|exc):`~?([^`]+)`")
#: An image of an untracked run output (``results/...``), which the site cannot show.
RESULTS_IMAGE = re.compile(r"!\[([^\]]*)\]\(((?:\.\./)*results/[^)\s]+)\)")


def _pages() -> list[str]:
    """The repository's own pages (relative paths): README, docs/, the studies, the changelog."""
    docs = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))
    studies = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "experiments").glob("*/README.md"))
    return ["README.md", *docs, *studies, "CHANGELOG.md"]


def _docs_order() -> list[str]:
    """``docs/README.md``, then the pages in the order its list names them, then the others."""
    index = (ROOT / "docs" / "README.md").read_text()
    named = [f"docs/{t}" for t in LINK.findall(index) if (ROOT / "docs" / t).is_file()]
    rest = [p for p in _pages() if p.startswith("docs/") and p not in named and p != "docs/README.md"]
    return ["docs/README.md", *dict.fromkeys(named), *rest]


@dataclass
class Card:
    """One env card: the ``Env`` class of some registered ids (a platform's, of some versions)."""

    slug: str  #: the page, ``envs/<slug>.md``: the class's module (unique)
    title: str  #: the platform and its versions, e.g. ``GpsIns (v2)``
    cls: type
    entries: list[Any]


def cards() -> list[Card]:
    """The env cards of every registered navgym id, in registry order."""
    import gymnasium as gym

    import navgym  # noqa: F401  (registers the ids)
    from navgym.envs.registration import ENVIRONMENTS

    by_class: dict[str, list[Any]] = {}
    for e in ENVIRONMENTS:
        by_class.setdefault(str(gym.spec(e.id).entry_point), []).append(e)
    out = []
    for entry_point, entries in by_class.items():
        module, _, name = entry_point.partition(":")
        versions = ", ".join(dict.fromkeys(e.id.rpartition("-")[2] for e in entries))
        title = f"{entries[0].prefix} ({versions})"
        out.append(Card(module, title, getattr(importlib.import_module(module), name), entries))
    return out


def card_page(card: Card) -> str:
    """The Markdown page of one env card: its title, its class and ids, the card's sections."""
    doc = card.cls.__doc__ or ""
    first, _, rest = doc.partition("\n")
    body = ROLE.sub(r"`\1`", textwrap.dedent(rest)).strip()
    ids = ", ".join(f"`{e.id}`" for e in card.entries)
    where = f"`{card.cls.__module__}.{card.cls.__name__}`"
    return f"# {card.title}\n\n{first.strip()}\n\nClass {where}; ids {ids}.\n\n{body}\n"


def envs_index(all_cards: list[Card]) -> str:
    """``envs/index.md``: every registered id with its task, horizon and card."""
    rows = [
        f"| `{e.id}` | {e.task} | {e.steps} | [{c.title}]({c.slug}.md) |"
        for c in all_cards
        for e in c.entries
    ]
    return (
        "# Environments\n\nEvery registered id (`navgym list` prints the same registry), with the "
        "card of its platform.\n\n| id | task | steps | card |\n|---|---|---|---|\n" + "\n".join(rows) + "\n"
    )


def _folder_page(path: Path) -> Path:
    """A folder's page: its README, else (a package) its ``__init__.py``; a file is itself."""
    if not path.is_dir():
        return path
    readme = path / "README.md"
    return readme if readme.is_file() else path / "__init__.py"


def _linked_files(page: str, text: str) -> list[str]:
    """Repository files a page links to (a folder: its README), as paths relative to the root."""
    out = []
    for target in LINK.findall(text):
        if re.match(r"[a-z][a-z0-9+.-]*:", target) or target.startswith(("#", "/")):
            continue
        path = _folder_page((ROOT / page).parent / target.split("#")[0])
        try:
            rel = path.resolve().relative_to(ROOT)
        except ValueError:
            continue
        if path.is_file():
            out.append(str(rel))
    return out


def on_config(config: Any) -> Any:
    """The navigation: home, docs, environments, studies, changelog."""
    studies = [p for p in _pages() if p.startswith("experiments/")]
    config["nav"] = [
        {"Home": "README.md"},
        {"Documentation": _docs_order()},
        {"Environments": ["envs/index.md", *({c.title: f"envs/{c.slug}.md"} for c in cards())]},
        {"Studies": studies},
        {"Changelog": "CHANGELOG.md"},
    ]
    return config


def on_files(files: Any, config: Any) -> Any:
    """Replace the files of ``docs_dir`` by the site's: the pages, the cards, what they link to."""
    from mkdocs.structure.files import File, Files

    out = Files([])
    seen: set[str] = set()
    todo = list(_pages())
    while todo:
        rel = todo.pop(0)
        if rel in seen:
            continue
        seen.add(rel)
        out.append(File.generated(config, rel, abs_src_path=str(ROOT / rel)))
        if rel.endswith(".md"):
            todo += _linked_files(rel, (ROOT / rel).read_text(encoding="utf-8"))
    all_cards = cards()
    out.append(File.generated(config, "envs/index.md", content=envs_index(all_cards)))
    for card in all_cards:
        out.append(File.generated(config, f"envs/{card.slug}.md", content=card_page(card)))
    return out


def _folder_link(match: re.Match[str], page: str) -> str:
    target = match.group(1)
    if re.match(r"[a-z][a-z0-9+.-]*:", target) or not target.split("#")[0].endswith("/"):
        return match.group(0)
    folder = (ROOT / page).parent / target.split("#")[0]
    if not folder.is_dir():
        return match.group(0)
    return match.group(0).replace(target, target.split("#")[0] + _folder_page(folder).name, 1)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """The page's links to folders and to untracked run outputs, as the site can follow them.

    A folder linked: its page (README or ``__init__.py``); an image of ``results/...``: named
    as code, not shown.
    """
    markdown = LINK.sub(lambda m: _folder_link(m, page.file.src_uri), markdown)
    return RESULTS_IMAGE.sub(r"`\2` (\1; written by the run)", markdown)
