"""The start posture is checked against the cell when the cell changes and when planning
starts - "the start posture touches the wall" comes before a run, never during it - and the
robot can be moved out to a free posture on a path that touches nothing new."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.session import Session, SessionError
from assistant.session.events import Notice, SceneChanged
from assistant.transforms import make_T, pose_from_mm_deg

DOWN = [0, 0, 180]


@pytest.fixture
def session(tmp_path) -> Session:
    return Session.from_sample("thesis_rv2aj", tmp_path / "s", with_objects=False,
                               with_mission=False)


def forearm_point(s: Session) -> np.ndarray:
    """The middle of the RV-2AJ's forearm at its home posture, in the world."""
    frames = s.link_poses_world(s.current_joints())
    return 0.5 * (frames[3][:3, 3] + frames[4][:3, 3])


def test_a_wall_through_the_home_posture_is_said_when_placed_and_refuses_planning(session):
    s = session
    events = []
    s.bus.subscribe(events.append)
    s.next()
    s.add_primitive("box", (0.05, 0.05, 0.05), name="keep",
                    T_world_object=make_T(np.eye(3), [0.5, 0.5, 0.025]))
    assert s.start_posture_links() == ()
    s.add_primitive("box", (0.3, 0.02, 0.3), name="wall",
                    T_world_object=make_T(np.eye(3), forearm_point(s)))
    said = [e.message for e in events if isinstance(e, Notice) and "start posture" in e.message]
    assert len(said) == 1 and "touches wall" in said[0] and "free posture" in said[0]
    assert s.start_posture_links() and "wall" in s.start_posture_text()
    assert any(isinstance(e, SceneChanged) and e.what == "start" for e in events)
    s.next()  # place.objects
    s.goto("teach.locations")
    s.teach("P1", pose_from_mm_deg([80, -340, 200, *DOWN]))
    s.teach("P2", pose_from_mm_deg([80, 340, 200, *DOWN]))
    s.set_start("P1")
    s.set_goal("P2")
    s.goto("plan")
    with pytest.raises(SessionError, match="start posture touches something .*wall"):
        s.plan()
    # the way out: a path that leaves the wall and touches nothing new, then planning works
    s.move_to_free_posture()
    assert s.start_posture_links() == ()
    checker = s.known_checker()
    assert checker.is_valid(s.current_joints())
    s.plan()
    assert s.trajectory is not None


def test_undoing_the_wall_clears_the_red_start(session):
    s = session
    s.next()
    s.add_primitive("box", (0.3, 0.02, 0.3), name="wall",
                    T_world_object=make_T(np.eye(3), forearm_point(s)))
    assert s.start_posture_links()
    s.undo()
    assert s.start_posture_links() == ()
    with pytest.raises(SessionError, match="touches nothing"):
        s.move_to_free_posture()
