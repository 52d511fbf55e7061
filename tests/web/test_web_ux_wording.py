"""The operator's words (no browser): progress without internal stage names, the planner's
report in mm / degrees / seconds, the move count from the report itself, typed angles shown
back as typed, and the end of a run said as the goal reached."""

from __future__ import annotations

import numpy as np

from web.panels.plan import report_markdown
from web.units import abc_shown, pose_from_fields
from web.wording import goal_reached, moves_words, progress_words

#: The shape of a real report (`Session.plan`, thesis cell), raw units.
REPORT = {"ok": True, "reason": "planned and verified", "min_clearance_m": 0.0116,
          "tcp_path_length_m": 1.1834, "joint_path_length_rad": 4.3266,
          "primitives": {"joint": 4, "linear": 1}, "planning_time_s": 1.094,
          "order": ["P7-P8"], "description": "mission plan ok in 1.09 s: ...",
          "clearance_required_mm": 10.0, "clearance_shortfalls": [], "retries_s": 0.25}


def test_progress_messages_are_in_the_operators_words():
    assert progress_words("elastic net stage 1, iteration 49") == "smoothing the path"
    assert progress_words("checking links up to joint 4 against CAD") == \
        "finding where the arm would touch the parts"
    assert progress_words("845120 joint positions in 6000 leaves") == "the robot's reach is mapped"
    assert progress_words("driving P1 -> P7-P8") == "the robot drives P1 -> P7-P8"
    assert progress_words("reading the file") == "reading the file"  # already plain: kept


def test_the_report_is_in_mm_degrees_and_seconds_with_readable_labels():
    md = report_markdown(REPORT)
    assert "| Closest to a known part | 11.6 mm (at least 10 mm asked) |" in md
    assert "| Tool path length | 1183 mm |" in md
    assert "| Joint travel (all axes) | 248° |" in md  # 4.3266 rad
    assert "| Planning time (this plan) | 1.1 s |" in md
    assert "| Moves | 5 (4 joint moves, 1 line) |" in md
    assert "| Retries | 0.2 s |" in md or "| Retries | 0.3 s |" in md  # unknown *_s: seconds
    for raw in ("ok", "True", "min clearance m", "_m", "rad", "description"):
        assert raw not in md, raw
    assert report_markdown(None) == "*Not planned yet.*"


def test_the_move_count_is_the_reports():
    n, words = moves_words(REPORT["primitives"])
    assert n == sum(REPORT["primitives"].values()) == 5
    assert words == "4 joint moves, 1 line"


def test_typed_angles_are_shown_as_typed_when_they_are_the_same_rotation():
    T = pose_from_fields((80, -340, 200), (0, 0, 180))
    assert abc_shown(T, (0.0, 0.0, 180.0)) == (0.0, 0.0, 180.0)
    # Without what was typed the pose reads back in the convention's own range; -0 is 0.
    a, b, c = abc_shown(T, None)
    assert np.allclose(pose_from_fields((0, 0, 0), (a, b, c))[:3, :3], T[:3, :3], atol=1e-6)
    assert "-0" not in f"{a:g} {b:g} {c:g}"
    # Typed angles that are NOT this rotation are not shown: the pose's own are.
    assert abc_shown(T, (0.0, 0.0, 90.0)) != (0.0, 0.0, 90.0)


def test_the_end_of_a_run_names_the_goal():
    assert goal_reached("P10", {"collision_indications": 3, "replans": 3}) == \
        "Goal reached: the robot is at P10. 3 collisions learnt, 3 re-plans; the final path " \
        "is planned round what was learnt."
    assert goal_reached("P10", {}) == "Goal reached: the robot is at P10."
