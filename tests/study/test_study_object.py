"""The same study for an object instead of the base: the pick-and-place fixture moved over
the table, the places taught on it moving with it (screen only: milliseconds a candidate)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from assistant.session import Session
from assistant.study import Region, StudySettings, run_study


@pytest.fixture(scope="module")
def pick_place():
    s = Session.from_sample("pick_and_place", None)
    yield s
    s.close()


def test_fixture_study_moves_the_places_with_it(pick_place):
    problem = pick_place.study_problem(object_name="fixture")
    fixture = pick_place.cell.get_object("fixture")
    x, y = fixture.T_world_object[0, 3], fixture.T_world_object[1, 3]
    # where it is, and 0.6 m further out along y: the places go with it, out of reach
    region = Region(x, y, x, y + 0.6, 0.6, 1)
    res = run_study(problem, region, StudySettings(plan_top=0, engine="inline"))
    here, far = sorted(res.candidates, key=lambda r: r.candidate.y)
    assert here.status == "screened", here.reason
    assert far.status == "failed"
    assert re.search(r"out of reach by \d+ mm", far.reason), far.reason
    assert "PICK" not in far.reason  # the picks stay on the conveyor, in reach
    cell, mission = problem.variant(far.candidate)
    moved = cell.get_object("fixture").T_world_object
    assert np.allclose(moved[:2, 3], [x, y + 0.6])
    # a path's place point moved with the fixture; its pick point did not
    pts = [p for seg in mission.paths[0].segments for p in seg.points]
    orig = [p for seg in pick_place.mission.paths[0].segments for p in seg.points]
    assert np.allclose(pts[0], orig[0])
    assert np.allclose(pts[-1], orig[-1] + [0.0, 0.6, 0.0])
    assert res.subject == "object fixture"


def test_unknown_object_is_refused(pick_place):
    from assistant.session.types import SessionError

    with pytest.raises(SessionError, match="no object named 'nope'"):
        pick_place.study_problem(object_name="nope")
