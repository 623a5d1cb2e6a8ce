"""The source layout: no import cycle among the engine's modules, geometry never imports the
engine, and no module over 500 lines unless its docstring says why.

Imports are read with :mod:`ast` (nothing is imported): module-level and function-level
imports both count; imports under ``if TYPE_CHECKING:`` do not (they never run).
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
# import package -> source folder (pyproject's package-dir)
PACKAGES = {"handover.engine": ROOT / "engine", "handover.geometry": ROOT / "geometry"}
MAX_LINES = 500
REASON = "Longer than"


def _modules(package: str, folder: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file below ``folder``."""
    out = {}
    for path in sorted(folder.rglob("*.py")):
        parts = path.relative_to(folder).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join((package, *parts))] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imported(tree: ast.Module, module: str, is_package: bool, modules: set[str]) -> set[str]:
    """Every name ``tree`` imports at run time, relative imports resolved: ``import X.Y``
    gives ``X.Y``; ``from X import y`` gives ``X.y`` when that is a module, else ``X``."""
    names: set[str] = set()
    package = module if is_package else module.rpartition(".")[0]

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                names.add(sub if sub in modules else base)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return names


def import_graph(packages: dict[str, Path]) -> nx.DiGraph:
    """Module -> module edges among the modules of ``packages`` (dotted import name ->
    folder). Importing ``a.b.c`` runs ``a.b.c`` and also the packages ``a.b`` and ``a`` on
    the way: an edge goes to each of those too, except to the importer's own packages
    (already running when it runs) unless it names one of them itself."""
    modules: dict[str, Path] = {}
    for package, folder in packages.items():
        modules.update(_modules(package, folder))
    graph = nx.DiGraph()
    graph.add_nodes_from(modules)
    for module, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        own = {".".join(module.split(".")[:i]) for i in range(1, module.count(".") + 1)}
        for name in _imported(tree, module, path.name == "__init__.py", set(modules)):
            parts = name.split(".")
            for i in range(len(parts), 0, -1):
                target = ".".join(parts[:i])
                if target in modules and (target == name or target not in own):
                    graph.add_edge(module, target)
    graph.remove_edges_from([(m, m) for m in modules])
    return graph


def import_cycles(graph: nx.DiGraph, prefix: str) -> list[list[str]]:
    """Cycles among the modules whose name starts with ``prefix``, shortest first."""
    sub = graph.subgraph(n for n in graph if n.startswith(prefix))
    cycles = [sorted(c) for c in nx.strongly_connected_components(sub) if len(c) > 1]
    return sorted(cycles, key=len)


def too_long(packages: dict[str, Path]) -> list[str]:
    """Modules over ``MAX_LINES`` lines whose docstring's first paragraph does not say why
    (a sentence starting "Longer than", e.g. "Longer than 500 lines: one parser, ...")."""
    out = []
    for package, folder in packages.items():
        for module, path in _modules(package, folder).items():
            text = path.read_text(encoding="utf-8")
            n = text.count("\n") + (not text.endswith("\n"))
            if n <= MAX_LINES:
                continue
            doc = ast.get_docstring(ast.parse(text)) or ""
            first = doc.split("\n\n", 1)[0]
            if REASON not in first:
                out.append(f"{module}: {n} lines, and its docstring says not why ({REASON} ...)")
    return out


def test_no_import_cycle_in_engine() -> None:
    cycles = import_cycles(import_graph(PACKAGES), "handover.engine")
    assert not cycles, "import cycles among engine modules:\n" + "\n".join(
        " <-> ".join(c) for c in cycles
    )


def test_geometry_never_imports_engine() -> None:
    graph = import_graph(PACKAGES)
    bad = [
        f"{a} imports {b}"
        for a, b in graph.edges
        if a.startswith("handover.geometry") and b.startswith("handover.engine")
    ]
    assert not bad, "\n".join(bad)


def test_modules_short_or_say_why() -> None:
    assert not too_long(PACKAGES), "\n".join(too_long(PACKAGES))


# ---------------------------------------------------------------- the checks can fail


def _write(folder: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text, encoding="utf-8")
    return folder


def test_cycle_found_through_function_import_not_type_checking(tmp_path: Path) -> None:
    folder = _write(
        tmp_path / "eng",
        {
            "__init__.py": "",
            "a.py": "from handover.engine.b import x\n",
            "b.py": "def f():\n    from handover.engine import a\n",
            "c.py": "from typing import TYPE_CHECKING\n"
            "if TYPE_CHECKING:\n    from handover.engine.a import x\n",
            "d.py": "from .c import y\n",
            "sub/__init__.py": "from ..d import z\n",
            "sub/e.py": "from handover.engine.sub import w\n",
            "sub/f.py": "from handover.engine.sub.e import v\nfrom . import e\n",
        },
    )
    graph = import_graph({"handover.engine": folder})
    assert import_cycles(graph, "handover.engine") == [
        ["handover.engine.a", "handover.engine.b"]
    ]
    assert graph.has_edge("handover.engine.d", "handover.engine.c")
    assert not graph.has_edge("handover.engine.c", "handover.engine.a")
    assert graph.has_edge("handover.engine.sub", "handover.engine.d")
    assert graph.has_edge("handover.engine.sub.e", "handover.engine.sub")  # named itself
    assert set(graph.successors("handover.engine.sub.f")) == {"handover.engine.sub.e"}


def test_geometry_importing_engine_is_seen(tmp_path: Path) -> None:
    eng = _write(tmp_path / "eng", {"__init__.py": "", "kb.py": ""})
    geo = _write(tmp_path / "geo", {"__init__.py": "", "m.py": "import handover.engine.kb\n"})
    graph = import_graph({"handover.engine": eng, "handover.geometry": geo})
    assert graph.has_edge("handover.geometry.m", "handover.engine.kb")


@pytest.mark.parametrize(
    ("doc", "flagged"),
    [
        ('"""A module.\n\nLonger than 500 lines: below, not first."""\n', True),
        ('"""A module.\n\nLonger than 500 lines: one table."""\n'.replace("\n\n", " "), False),
        ("", True),
    ],
)
def test_long_module_needs_a_reason(tmp_path: Path, doc: str, flagged: bool) -> None:
    folder = _write(tmp_path / "eng", {"__init__.py": "", "big.py": doc + "x = 1\n" * 600})
    found = too_long({"handover.engine": folder})
    assert bool(found) is flagged, found
