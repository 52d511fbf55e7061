"""Imports run one way: a room of the code imports only rooms below it, so the data's path
(operator action -> session -> planning -> world/roadmap/trajectory -> collision -> robots)
reads top-down and no two rooms import each other. `workflow` and `vision` never import
viser or the assistant; `web` is the only importer of viser."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Rank of each room; a module may import rooms of a lower rank and its own room only.
#: Function-level imports count too (a cycle through a late import is still a cycle).
RANK = {
    "assistant.transforms": 0, "assistant.progress": 0, "assistant.kernels": 0,
    "assistant.file_guard": 0,  # reading files we did not write: every reader's rules
    "workflow": 0, "vision": 0,
    "cellteach_testing": 0.5,  # test and benchmark helpers over `vision`
    "assistant.robots": 1,
    "assistant.collision": 2,
    "assistant.cell": 3, "assistant.mission": 3, "assistant.world": 3,
    "assistant.roadmap": 4, "assistant.trajectory": 4,
    "assistant.export": 5, "assistant.links": 5,
    "assistant.emulators": 5.5,  # the controllers' emulators: peers of the links
    "assistant.planning": 6,
    "assistant.study": 6.5,  # placement studies: run the planner over candidate placements
    "assistant.session": 7,
    "web": 8,
    # the package itself: `assistant.Session`, looked up on first use (PEP 562)
    "assistant": 8.5,
    # the warm-up and the background compile drive the real API to compile every kernel
    "assistant.warmup": 9, "assistant.cli": 9, "assistant.__main__": 10,
}
PACKAGES = ("assistant", "web", "vision", "workflow", "cellteach_testing")


def room(module: str) -> str:
    """The room of a dotted module name: the longest RANK key it starts with."""
    best = ""
    for key in RANK:
        if (module == key or module.startswith(key + ".")) and len(key) > len(best):
            best = key
    return best


def _modules() -> list[tuple[str, Path]]:
    out = []
    for top in PACKAGES:
        for path in sorted((ROOT / top).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out.append((".".join(parts), path))
    return out


def _imports(path: Path) -> list[tuple[str, int]]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.module, node.lineno))
    return found


def test_every_module_has_a_room():
    assert [m for m, _ in _modules() if not room(m)] == []


@pytest.mark.parametrize("module,path", _modules(), ids=[m for m, _ in _modules()])
def test_imports_run_downwards(module, path):
    mine = room(module)
    wrong = []
    for name, line in _imports(path):
        top = name.split(".")[0]
        if top == "viser" and mine != "web":
            wrong.append(f"line {line}: viser (only web/ draws)")
        if top not in PACKAGES:
            continue
        theirs = room(name)
        if theirs != mine and RANK[theirs] >= RANK[mine]:
            wrong.append(f"line {line}: {name} ({theirs}, rank {RANK[theirs]} >= {RANK[mine]})")
    assert wrong == [], f"{module} ({mine}) imports upwards or sideways: {wrong}"


def test_the_rule_catches_an_upward_import(tmp_path):
    """The check itself: a collision module importing the planner is refused."""
    bad = tmp_path / "bad.py"
    bad.write_text("from assistant.planning.execution import Executor\n")
    (name, _), = _imports(bad)
    assert RANK[room(name)] > RANK[room("assistant.collision.checker")]


def test_the_product_never_imports_the_testing_helpers():
    """`cellteach_testing` is for the tests and benchmarks: no product module imports it."""
    wrong = [(module, line) for module, path in _modules()
             if room(module) != "cellteach_testing"
             for name, line in _imports(path) if name.split(".")[0] == "cellteach_testing"]
    assert wrong == []
