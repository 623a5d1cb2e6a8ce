"""The source layout: the engine's layers, each importing only itself and the layers below
it; no import cycle at all in the engine or in geometry; geometry never imports the engine; at
most 13 entries at the engine's top level (its layers and three modules); no module over 500
lines unless its docstring says why.

Imports are read with :mod:`ast` (nothing is imported): module-level, function-level and
``if TYPE_CHECKING:`` imports all count (a type named in an annotation is a dependency too).
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


def _imported(tree: ast.Module, module: str, is_package: bool, modules: set[str]) -> set[str]:
    """Every name ``tree`` imports (anywhere, ``TYPE_CHECKING`` blocks included), relative
    imports resolved: ``import X.Y``
    gives ``X.Y``; ``from X import y`` gives ``X.y`` when that is a module, else ``X``."""
    names: set[str] = set()
    package = module if is_package else module.rpartition(".")[0]

    def visit(node: ast.AST) -> None:
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


LAYERS: tuple[tuple[str, ...], ...] = (
    ("handover.engine", "handover.engine.errors"),
    ("handover.engine.spec",),
    ("handover.engine.store",),
    ("handover.engine.assets",),
    ("handover.engine.load",),
    ("handover.engine.plan",),
    ("handover.engine.report",),
    ("handover.engine.planner",),
    ("handover.engine.tools",),
    ("handover.engine.cli", "handover.engine.service"),
)
"""The engine's layers, lowest first: a module may import its own layer and those below it.

0 the package, the errors and exit codes; 1 ``spec``: the KB's data model
and the rule kinds' fields; 2 ``store``: YAML with positions, validation, the KB store,
cultures, whole-file writes; 3 ``assets``: specs to geometry (meshes, grippers, robots), the
grasp database;
4 ``load``: ``load_kb`` and the checks across documents (a robot's URDF needs the assets);
5 ``plan``: one query, from its context to the chosen attempt; 6 ``report``: the result
record, the trace, the rerun recording; 7 ``planner``: the facade; 8 ``tools``: batch,
compare, KB tests; 9 the ``handover`` command and the plan service. ``handover.geometry`` lies
below them all and imports none of them."""

MAX_TOP_LEVEL = 12
"""Entries at the engine's top level (``__init__.py`` counted): the layers of LAYERS
(``service`` beside ``cli``), the errors and the package itself."""


def layer_of(module: str, layers: tuple[tuple[str, ...], ...] = LAYERS) -> int | None:
    """The index of the layer holding ``module`` (its longest matching prefix), None when no
    layer names it."""
    best, found = -1, None
    for index, prefixes in enumerate(layers):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, found = len(prefix), index
    return found


def layer_violations(graph: nx.DiGraph, prefix: str,
                     layers: tuple[tuple[str, ...], ...] = LAYERS) -> list[str]:
    """Imports among the modules under ``prefix`` that go to a higher layer, and modules
    that no layer names."""
    out = []
    for module in sorted(n for n in graph if n.startswith(prefix)):
        mine = layer_of(module, layers)
        if mine is None:
            out.append(f"{module} is in no layer (add it to LAYERS)")
            continue
        for target in sorted(graph.successors(module)):
            theirs = layer_of(target, layers)
            if target.startswith(prefix) and theirs is not None and theirs > mine:
                out.append(f"{module} (layer {mine}) imports {target} (layer {theirs})")
    return out


def test_engine_layers_import_only_downward() -> None:
    bad = layer_violations(import_graph(PACKAGES), "handover.engine")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("prefix", ["handover.engine", "handover.geometry"])
def test_no_import_cycle(prefix: str) -> None:
    cycles = import_cycles(import_graph(PACKAGES), prefix)
    assert not cycles, f"import cycles under {prefix}:\n" + "\n".join(
        " <-> ".join(c) for c in cycles
    )


def test_engine_top_level_is_small() -> None:
    top = sorted(p.name for p in (ROOT / "engine").iterdir()
                 if p.suffix == ".py" or (p / "__init__.py").exists())
    assert len(top) <= MAX_TOP_LEVEL, top


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


def test_cycle_found_through_function_and_type_checking_imports(tmp_path: Path) -> None:
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
    ]  # a <-> b through a function-level import
    assert graph.has_edge("handover.engine.d", "handover.engine.c")
    assert graph.has_edge("handover.engine.c", "handover.engine.a")  # under TYPE_CHECKING
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


def test_an_upward_import_is_a_layer_violation(tmp_path: Path) -> None:
    folder = _write(
        tmp_path / "eng",
        {
            "__init__.py": "",
            "spec/__init__.py": "",
            "spec/model.py": "from typing import TYPE_CHECKING\n"
            "if TYPE_CHECKING:\n    from handover.engine.plan.context import Ctx\n",
            "plan/__init__.py": "",
            "plan/context.py": "from handover.engine.spec.model import M\n",
            "stray.py": "",
        },
    )
    graph = import_graph({"handover.engine": folder})
    layers = (("handover.engine",), ("handover.engine.spec",), ("handover.engine.plan",))
    bad = layer_violations(graph, "handover.engine", layers)
    assert "handover.engine.spec.model (layer 1) imports handover.engine.plan.context (layer 2)" \
        in bad
    assert not any(b.startswith("handover.engine.plan.context ") for b in bad)
    # a module no layer names is reported, not let through (here stray.py is the package's)
    assert layer_of("handover.engine.stray", layers) == 0
    assert layer_violations(graph, "handover.engine", layers[1:])[0].endswith("in no layer "
                                                                              "(add it to LAYERS)")


def test_a_cycle_in_geometry_is_seen(tmp_path: Path) -> None:
    geo = _write(tmp_path / "geo", {"__init__.py": "", "a.py": "from .b import x\n",
                                    "b.py": "def f():\n    from . import a\n"})
    graph = import_graph({"handover.geometry": geo})
    assert import_cycles(graph, "handover.geometry") == [
        ["handover.geometry.a", "handover.geometry.b"]
    ]
