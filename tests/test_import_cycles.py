"""No two modules import each other, not even through others: the module import graph of
assistant/, web/, vision/ and workflow/ (module-level and function-level imports, as
`test_import_layers` reads them) has no strongly connected component of more than one
module. A cycle hidden in a late import is still a cycle: either module may be half
initialised when the other runs, and whoever reads one must read the other.

Names imported under `if TYPE_CHECKING:` only are left out: they are never executed, and a
part naming its owner's type (a panel its `App`) is a back-reference, not an import order."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

from tests.test_import_layers import _modules


def _type_only(tree: ast.AST) -> set[int]:
    """Ids of the nodes inside `if TYPE_CHECKING:` blocks."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for stmt in node.body:
                out.update(id(n) for n in ast.walk(stmt))
    return out


def imported_modules(path: Path, known: set[str]) -> set[str]:
    """The modules of ours a file imports when it runs: `from a.b import c` names module
    a.b.c where that is a module, else a.b."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = _type_only(tree)
    out: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in known
                     else node.module for a in node.names]
        else:
            continue
        out.update(n for n in names if n in known)
    return out


def import_graph() -> nx.DiGraph:
    modules = dict(_modules())
    known = set(modules)
    graph = nx.DiGraph()
    graph.add_nodes_from(known)
    for module, path in modules.items():
        graph.add_edges_from((module, t) for t in imported_modules(path, known)
                             if t != module)
    return graph


def test_no_import_cycles():
    cycles = sorted(sorted(c) for c in nx.strongly_connected_components(import_graph())
                    if len(c) > 1)
    assert cycles == []


def test_the_graph_sees_late_imports_and_not_type_names(tmp_path):
    """The check itself: a function-level `from a import b` of a submodule is an edge; a
    name imported for annotations only is not; two modules importing each other are one
    strongly connected component."""
    f = tmp_path / "m.py"
    f.write_text("from typing import TYPE_CHECKING\n"
                 "if TYPE_CHECKING:\n    from assistant.session.session import Session\n"
                 "def g():\n    from assistant.export import registry\n")
    known = {"assistant.export.registry", "assistant.export", "assistant.session.session"}
    assert imported_modules(f, known) == {"assistant.export.registry"}
    g = nx.DiGraph([("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")])
    assert [sorted(c) for c in nx.strongly_connected_components(g) if len(c) > 1] == [
        ["a", "b", "c"]]
