"""The session is composed, not mixed: no class in `assistant/session` is built from three or more
bases, the parts reach the core only through its public names, and every verb the session
hands over lands on a method its part has."""

from __future__ import annotations

import ast
from pathlib import Path

SESSION = Path(__file__).resolve().parents[1] / "assistant" / "session"


def _modules() -> list[tuple[Path, ast.Module]]:
    return [(p, ast.parse(p.read_text(encoding="utf-8"))) for p in sorted(SESSION.glob("*.py"))]


def test_no_class_in_the_session_package_has_three_or_more_bases():
    classes = [(p.name, node.name, len(node.bases)) for p, tree in _modules()
               for node in ast.walk(tree) if isinstance(node, ast.ClassDef)]
    assert len(classes) > 20  # the walk found the package's classes
    wide = [c for c in classes if c[2] >= 3]
    assert not wide, f"classes built from three or more bases: {wide}"


def test_the_parts_use_only_public_names_of_the_core_and_of_each_other():
    """`self._core.<name>` and `self._core.<part>.<name>` never name a private (`_x`)."""
    found: list[str] = []
    checked = 0
    for p, tree in _modules():
        outer = {id(n.value): n for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute)
                    and node.value.attr == "_core"):
                continue
            checked += 1
            names = [node.attr]
            if id(node) in outer:
                names.append(outer[id(node)].attr)
            if any(n.startswith("_") for n in names):
                found.append(f"{p.name}:{node.lineno} _core.{'.'.join(names)}")
    assert checked > 200  # the parts do reach the core this way
    assert not found, "a part reaches a private of the core or of another part:\n" + \
        "\n".join(found)


def test_every_hand_over_lands_on_its_parts_method():
    from assistant.session.handover import HandOver
    from assistant.session.session import Session

    s = Session()
    verbs = {name: v for name, v in vars(Session).items() if isinstance(v, HandOver)}
    assert len(verbs) > 80
    for name, verb in verbs.items():
        part = getattr(s, verb.part)
        assert callable(getattr(part, verb.name)), name
        assert getattr(s, name).__func__ is getattr(type(part), verb.name), name


def test_the_saved_document_beyond_cell_locations_and_mission_lives_in_its_parts():
    """The core keeps the cell, the locations and the mission; the rest of the document is
    kept by the part that owns it, and the core's name reads and writes that part's."""
    from assistant.session.handover import Forward
    from assistant.session.session import Session

    owners = {"link_settings": "setup", "hidden": "setup", "pointer_config": "teaching",
              "world_settings": "planning", "trajectory": "planning",
              "plan_report": "planning", "export_dialect": "exporter"}
    s = Session()
    for name, part in owners.items():
        assert name not in vars(s), f"{name} is kept on the core"
        assert name in vars(getattr(s, part)), f"{name} is not kept by {part}"
        assert getattr(s, name) is getattr(getattr(s, part), name)
        forward = next(vars(c)[name] for c in type(s).__mro__ if name in vars(c))
        assert isinstance(forward, Forward) and forward.part == part
    s.export_dialect = "krl"  # as loading a session writes it
    assert s.exporter.export_dialect == "krl"
