"""The study through the Session: in the background with progress events, its result kept
for the page, and "Move the robot here" as an undoable edit that moves the base (the
taught locations stay where they are in the world)."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.session import Session
from assistant.session.events import ProgressChanged, SceneChanged
from assistant.session.types import SessionError
from assistant.study import Region, StudySettings


@pytest.fixture
def session():
    s = Session.from_sample("thesis_rv2aj", None)
    s.goto("teach.locations")
    yield s
    s.close()


def test_study_then_apply_and_undo(session):
    events = []
    session.bus.subscribe(events.append)
    region = Region(0.1, 0.0, 0.1, 0.3, 0.3, 1)  # (100, 0) reaches all; (100, 300) does not
    res = session.study_placement(region, StudySettings(plan_top=1, engine="inline",
                                                        include_current=False))
    assert session.placement_study is res
    assert any(isinstance(e, ProgressChanged) and e.task == "placement study" for e in events)
    assert any(isinstance(e, SceneChanged) and e.what == "study" for e in events)
    best = res.best()
    assert best is not None and abs(best.candidate.x - 0.1) < 1e-9
    T_before = session.T_world_base().copy()
    P1 = session.locations[session.mission.start].T_world_tool.copy()
    T = session.apply_placement(best.candidate.index)
    assert np.allclose(session.T_world_base()[:3, 3], [0.1, 0.0, T_before[2, 3]])
    assert np.allclose(T, session.T_world_base())
    # the world stays put
    assert np.allclose(session.locations[session.mission.start].T_world_tool, P1)
    assert session.undo().startswith("move the robot base")
    assert np.allclose(session.T_world_base(), T_before)
    with pytest.raises(SessionError, match="no candidate #99"):
        session.apply_placement(99)


def test_apply_before_any_study_is_refused(session):
    with pytest.raises(SessionError, match="no placement study yet"):
        session.apply_placement(0)
