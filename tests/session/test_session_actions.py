"""The Session facade: guarded actions, rollback, undo/redo, autosave and reload."""

from __future__ import annotations

import json

import numpy as np
import pytest

from assistant.cell.cad import CadImportError
from assistant.robots.model import UnreachableError
from assistant.session import Session, SessionError
from assistant.session.events import ErrorRaised, Notice, SceneChanged, StateChanged
from assistant.session.store import SessionFileError
from assistant.transforms import pose_from_mm_deg
from workflow.machine import TransitionRefused

DOWN = [0, 0, 180]  # tool pointing down (A, B, C in degrees)


def to_place(s: Session, o1: bytes) -> None:
    s.next()
    s.import_cad(o1, "O1.dxf", name="O1", units="mm")
    s.next()


def test_actions_outside_their_step_are_refused_and_change_nothing(empty_session, o1_dxf):
    s = empty_session
    with pytest.raises(TransitionRefused, match="go to 'Import CAD' or 'Place models' first"):
        s.import_cad(o1_dxf, "O1.dxf")
    assert not s.cell.objects
    with pytest.raises(TransitionRefused, match="Import or place at least one object first"):
        s.goto("place.objects")
    assert s.machine.state == "setup"


def test_a_broken_cad_file_is_refused_with_a_hint_and_the_session_is_intact(empty_session,
                                                                            o1_dxf):
    s = empty_session
    events = []
    s.bus.subscribe(events.append)
    s.next()
    s.import_cad(o1_dxf, "O1.dxf", name="O1", units="mm")
    before = s.counters.operator_actions
    with pytest.raises(CadImportError):
        s.import_cad(b"solid broken\n facet normal 0 0", "broken.stl")
    assert list(s.cell.objects) == ["O1"]
    assert s.counters.operator_actions == before
    err = [e for e in events if isinstance(e, ErrorRaised)][-1]
    assert "broken.stl" in err.message and err.hint
    # The autosaved folder still loads with O1 in it.
    assert list(Session.load(s.folder).cell.objects) == ["O1"]


def test_undo_and_redo_of_placement_teaching_and_mission_edits(empty_session, o1_dxf):
    s = empty_session
    to_place(s, o1_dxf)
    s.place_object("O1", pose_from_mm_deg([220, -200, 0, 0, 0, 0]))
    s.goto("teach.locations")
    s.teach("P1", pose_from_mm_deg([80, -340, 200, *DOWN]))
    s.teach("P10", pose_from_mm_deg([80, 340, 200, *DOWN]))
    s.set_start("P1")
    s.set_goal("P10")
    s.add_path("SEAM", "line", ["P1", "P10"])
    assert s.undo() == "add the path SEAM" and not s.mission.paths
    assert s.undo() == "set the mission goal" and s.mission.goal is None
    assert s.redo() == "set the mission goal" and s.mission.goal == "P10"
    s.undo()
    s.undo()  # start
    s.undo()  # P10
    assert list(s.locations) == ["P1"]
    s.undo()  # P1
    s.undo()  # placement
    assert np.allclose(s.cell.objects["O1"].T_world_object, np.eye(4))
    s.redo()
    assert np.allclose(s.cell.objects["O1"].T_world_object[:3, 3], [0.22, -0.2, 0.0])
    # A new edit clears the redo stack.
    s.teach("P2", pose_from_mm_deg([250, 0, 200, *DOWN]))
    assert not s.history.can_redo


def test_autosave_after_every_action_and_reload_restores_everything(empty_session, o1_dxf):
    s = empty_session
    to_place(s, o1_dxf)
    s.place_object("O1", pose_from_mm_deg([220, -200, 0, 0, 0, 30]))
    s.goto("teach.locations")
    s.teach("P1", pose_from_mm_deg([80, -340, 200, *DOWN]))
    s.set_start("P1")
    doc = json.loads((s.folder / "session.json").read_text())
    assert doc["mission"]["start"] == "P1"  # by name
    back = Session.load(s.folder)
    assert back.machine.state == "teach.locations"
    assert np.allclose(back.cell.objects["O1"].T_world_object, s.cell.objects["O1"].T_world_object)
    assert np.allclose(back.locations["P1"].T_world_tool, s.locations["P1"].T_world_tool)
    assert back.mission.start == "P1"
    assert [h.name for h in back.hidden] == ["O3"]
    assert back.counters.operator_actions == s.counters.operator_actions


def test_unreachable_targets_are_refused_and_orientations_projected_with_a_notice(
        empty_session, o1_dxf):
    s = empty_session
    to_place(s, o1_dxf)
    s.goto("teach.locations")
    with pytest.raises(UnreachableError, match="reach"):
        s.teach("FAR", pose_from_mm_deg([900, 0, 200, *DOWN]))
    assert "FAR" not in s.locations
    notes = []
    s.bus.subscribe(lambda e: notes.append(e) if isinstance(e, Notice) else None)
    loc = s.teach("TILT", pose_from_mm_deg([250, 150, 150, 0, 20, 180]))
    assert any("arm plane" in n.message for n in notes)
    # The stored pose is reachable by the 5-axis arm exactly.
    T_base = np.linalg.inv(s.T_world_base()) @ loc.T_world_tool
    assert s.robot.ik(T_base).ok


def test_bad_names_and_unknown_references_say_what_to_do(empty_session, o1_dxf):
    s = empty_session
    to_place(s, o1_dxf)
    s.goto("teach.locations")
    with pytest.raises(SessionError, match="use a letter"):
        s.teach("7up", pose_from_mm_deg([250, 0, 200, *DOWN]))
    with pytest.raises(SessionError, match="no location named 'P9'"):
        s.set_start("P9")


def test_events_announce_state_and_scene_changes(empty_session, o1_dxf):
    s = empty_session
    events = []
    s.bus.subscribe(events.append)
    s.next()
    s.import_cad(o1_dxf, "O1.dxf", name="O1", units="mm")
    kinds = [type(e) for e in events]
    assert StateChanged in kinds and SceneChanged in kinds
    # O1 lands at the world origin, on the robot: the start posture touches it ("start")
    assert [e.what for e in events if isinstance(e, SceneChanged)] == ["start", "objects"]
    assert any(isinstance(e, Notice) and "place O1 elsewhere" in e.message for e in events)


@pytest.mark.parametrize("damage,match", [
    (lambda d: d.update(schema_version=99), "schema version 99"),
    (lambda d: d["locations"].append({"name": "X", "T_world_tool": [[1, 2]]}), "finite 4x4"),
    (lambda d: d["machine"].update(state="nowhere"), "unknown workflow step"),
])
def test_malformed_session_files_fail_cleanly(empty_session, o1_dxf, damage, match):
    s = empty_session
    to_place(s, o1_dxf)
    path = s.folder / "session.json"
    doc = json.loads(path.read_text())
    damage(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(SessionFileError, match=match):
        Session.load(s.folder)


def test_a_session_file_that_is_not_json_fails_cleanly(tmp_path):
    (tmp_path / "session.json").write_text("{not json")
    with pytest.raises(SessionFileError, match="not valid JSON"):
        Session.load(tmp_path)
    with pytest.raises(SessionFileError, match="no session.json"):
        Session.load(tmp_path / "missing")


def test_occupied_cells_come_with_the_lattice_axes_of_the_octree(tmp_path):
    """The page draws the cells' outside faces along the octree's axes: the session says
    what they are (the robot base's), and every centre sits on that lattice."""
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    try:
        assert s.occupancy_cells() is None  # no world model yet
        s.goto("plan")
        s.build_world()
        cells = s.occupancy_cells(0.05)
        assert cells is not None and len(cells.centres) == len(cells.p) > 0
        T = s.T_world_base()
        assert np.array_equal(cells.R_world_grid, T[:3, :3])
        local = (cells.centres - T[:3, 3]) @ cells.R_world_grid / cells.leaf - 0.5
        assert np.allclose(local, np.rint(local), atol=1e-6)
        assert ((cells.p >= 0.05) & (cells.p <= 1.0)).all()
    finally:
        s.close()
