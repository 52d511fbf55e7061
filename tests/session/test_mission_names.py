"""The mission names its start and goal; the session's `locations` is their one store.

A location taught again is planned where it is now (nothing keeps a copy in step), a location
the mission uses cannot be deleted, and a session saved while the mission held its start and
goal whole (the form before) still opens with them."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from assistant.mission.model import Location, Mission
from assistant.session import Session, SessionError
from assistant.session.store import SessionFileError
from assistant.transforms import make_T, pose_from_mm_deg

DOWN = [0, 0, 180]
P1 = [80, -340, 200, *DOWN]
P2 = [80, 340, 200, *DOWN]
P2_CORRECTED = [80, 330, 200, *DOWN]  # 10 mm nearer: taught again under its name


def taught(s: Session) -> Session:
    s.next()
    s.add_primitive("box", (0.05, 0.05, 0.05), name="keep",  # out of the way
                    T_world_object=make_T(np.eye(3), [0.5, 0.5, 0.025]))
    s.goto("teach.locations")
    s.teach("P1", pose_from_mm_deg(P1))
    s.teach("P2", pose_from_mm_deg(P2))
    s.set_start("P1")
    s.set_goal("P2")
    return s


def test_the_mission_holds_location_names_and_no_location(empty_session):
    s = taught(empty_session)
    assert (s.mission.start, s.mission.goal) == ("P1", "P2")
    held = [getattr(s.mission, f.name) for f in dataclasses.fields(s.mission)]
    assert not any(isinstance(v, Location) for v in held)
    assert {k: s.mission.to_json()[k] for k in ("start", "goal")} == {"start": "P1",
                                                                     "goal": "P2"}
    assert not hasattr(s.teaching, "relink_mission")  # nothing to keep in step
    # what planning gets is the one store's location itself
    resolved = s.teaching.resolved_mission()
    assert resolved.start is s.locations["P1"] and resolved.goal is s.locations["P2"]


def test_a_location_in_use_cannot_be_deleted_and_an_unknown_name_is_refused(empty_session):
    s = taught(empty_session)
    with pytest.raises(SessionError, match="P1 is used by the mission start"):
        s.remove_location("P1")
    with pytest.raises(SessionError, match="P2 is used by the mission goal"):
        s.remove_location("P2")
    with pytest.raises(SessionError, match="no location named 'P9'"):
        s.set_goal("P9")
    assert s.mission.goal == "P2" and set(s.locations) == {"P1", "P2"}
    with pytest.raises(ValueError, match="mission goal 'P9' is not a taught location"):
        Mission("P1", "P9").resolve(s.locations)


def test_a_location_taught_again_is_planned_where_it_is_now(empty_session):
    s = taught(empty_session)
    s.teach("P2", pose_from_mm_deg(P2_CORRECTED))
    s.goto("plan")
    s.plan()
    assert s.trajectory is not None
    end = s.trajectory.motions[-1].target
    assert end.name == "P2"
    # The RV-2AJ's closed-form IK gives back the taught position to ~1e-12 m (FK of its
    # solution, base at the world origin); 1e-6 m is far inside the 10 mm correction.
    np.testing.assert_allclose(end.position, s.locations["P2"].position, atol=1e-6)
    np.testing.assert_allclose(end.position, [0.08, 0.33, 0.2], atol=1e-6)


def test_a_session_saved_with_the_mission_holding_its_locations_whole_opens(empty_session):
    s = taught(empty_session)
    folder = s.folder
    old = json.loads((folder / "session.json").read_text())
    # The form before: the mission's start and goal written whole (the one writer of that
    # form, the samples' mission.json, is `ResolvedMission.to_json`), and P1 only there.
    old["mission"] = s.teaching.resolved_mission().to_json()
    assert old["mission"]["start"]["name"] == "P1"
    old["locations"] = [d for d in old["locations"] if d["name"] != "P1"]
    (folder / "session.json").write_text(json.dumps(old))
    back = Session.load(folder, autosave=False)
    assert (back.mission.start, back.mission.goal) == ("P1", "P2")
    assert back.locations["P1"] == s.locations["P1"]  # joined the locations from the mission
    assert back.locations["P2"] == s.locations["P2"]
    assert back.teaching.resolved_mission().start is back.locations["P1"]
    assert not back.load_notes
    # a mission copy that differs from the taught location: the location is kept, and said
    moved = s.locations["P2"].to_json()
    moved["T_world_tool"][1][3] = 0.3
    old["mission"]["goal"] = moved
    (folder / "session.json").write_text(json.dumps(old))
    back = Session.load(folder, autosave=False)
    assert back.locations["P2"] == s.locations["P2"]
    assert any("mission's copy of P2" in n for n in back.load_notes)


def test_a_saved_mission_naming_a_location_that_is_not_there_is_refused(empty_session):
    s = taught(empty_session)
    doc = json.loads((s.folder / "session.json").read_text())
    doc["locations"] = [d for d in doc["locations"] if d["name"] != "P2"]
    (s.folder / "session.json").write_text(json.dumps(doc))
    with pytest.raises(SessionFileError, match="mission goal.*'P2' is not a taught location"):
        Session.load(s.folder, autosave=False)
