"""Teaching a location again under its name replaces it (and the mission's start follows);
undo brings the first back. Location equality compares its arrays element-wise."""

from __future__ import annotations

import numpy as np

from assistant.mission.model import Location
from assistant.session import Session
from assistant.transforms import pose_from_mm_deg


def test_a_location_taught_again_replaces_it_and_undo_restores_it(tmp_path):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                            with_mission=False)
    s.fire("next")
    s.add_primitive("box", (0.1, 0.1, 0.1))
    s.goto("teach.locations")
    s.teach("P1", pose_from_mm_deg([80, -340, 200, 0, 0, 180]))
    s.set_start("P1")
    s.teach("P1", pose_from_mm_deg([80, -330, 200, 0, 0, 180]))  # corrected
    np.testing.assert_allclose(s.teaching.resolved_mission().start.position, [0.08, -0.33, 0.2],
                               atol=1e-12)
    s.undo()
    np.testing.assert_allclose(s.locations["P1"].position, [0.08, -0.34, 0.2], atol=1e-12)
    np.testing.assert_allclose(s.teaching.resolved_mission().start.position, [0.08, -0.34, 0.2],
                               atol=1e-12)


def test_location_equality_is_by_value():
    T = np.eye(4)
    a = Location("P1", T.copy(), q_hint=np.zeros(5))
    assert a == Location("P1", T.copy(), q_hint=np.zeros(5))
    assert a != Location("P1", T.copy())
    moved = T.copy()
    moved[0, 3] = 1e-3
    assert a != Location("P1", moved, q_hint=np.zeros(5))
    assert a != Location("P2", T.copy(), q_hint=np.zeros(5))
