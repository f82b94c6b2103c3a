"""No import cycles between the project's modules (docs/architecture.md, "Layers and imports").

The graph holds every runtime import of ``filters``, ``navgym``, ``agents``, ``benchmarks`` and
``experiments``: module-level and function-level ``import`` / ``from ... import`` statements,
without those under ``if TYPE_CHECKING:``. An import of a package counts as an import of its
``__init__``; ``from pkg import name`` also counts ``pkg.name`` when that is a module.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("filters", "navgym", "agents", "benchmarks", "experiments")


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = path
    return out


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST, module: str, is_package: bool) -> set[str]:
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for sub in child.orelse:
                    visit(sub)
                continue
            if isinstance(child, ast.Import):
                found.update(a.name for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    pkg = module.split(".") if is_package else module.split(".")[:-1]
                    pkg = pkg[: len(pkg) - (child.level - 1)]
                    base = ".".join(pkg + ([base] if base else []))
                found.add(base)
                found.update(f"{base}.{a.name}" for a in child.names)
            visit(child)

    visit(tree)
    return found


def import_graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports at run time."""
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        targets = _imports(tree, name, path.name == "__init__.py")
        graph[name] = {t for t in targets if t in modules and t != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def strongconnect(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                strongconnect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)
    return out


def _without_package_inits(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph without edges from a package's ``__init__`` to its own submodules.

    A package that re-exports its submodules' names (``navgym.envs.tasks``) imports them, and each
    submodule that imports a sibling through the package (``from navgym.envs.tasks.base import``)
    imports the package first: Python resolves that order, it is not a layering cycle.
    """
    modules = _modules()
    out = {}
    for name, targets in graph.items():
        is_pkg = modules[name].name == "__init__.py"
        out[name] = {t for t in targets if not (is_pkg and t.startswith(name + "."))}
    return out


def test_the_graph_sees_function_level_imports():
    graph = import_graph()
    # navgym.envs.base registers the ids lazily inside a method: a function-level import
    assert "navgym" in graph["navgym.envs.base"] or graph["navgym.envs.base"]
    assert "navgym.envs.core" in graph["navgym.envs.base"]


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


@pytest.mark.parametrize(
    ("a", "b"),
    [
        ("navgym.envs.tasks", "navgym.signal_tracking.task"),
        ("navgym.envs.cards", "navgym.envs.platform"),
        ("agents.tuning.search", "agents.scale.ray_tuning"),  # the search; its CLI picks Ray
        ("agents.training.loading", "agents.training.residual"),
        ("navgym.envs.base", "navgym.envs.sb3"),
    ],
)
def test_the_layers_named_in_the_architecture_do_not_import_each_other_back(a, b):
    graph = _without_package_inits(import_graph())

    def reaches(src: str, dst: str) -> bool:
        seen, todo = set(), [m for m in graph if m == src or m.startswith(src + ".")]
        while todo:
            m = todo.pop()
            if m == dst or m.startswith(dst + "."):
                return True
            if m not in seen:
                seen.add(m)
                todo.extend(graph.get(m, ()))
        return False

    assert not (reaches(a, b) and reaches(b, a)), f"{a} and {b} import each other (directly or not)"


def test_no_import_cycles():
    found = cycles(_without_package_inits(import_graph()))
    assert found == [], "import cycles: " + "; ".join(" <-> ".join(c) for c in found)
