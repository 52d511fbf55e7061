"""Loading is total: a session.json with any field out of range is refused with one sentence
naming it (exit code 2 from the CLI, no traceback), never half-loaded; a session saved while
the robot moved opens idle with a note; a plan that does not fit the robot is dropped."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from assistant.session import Session
from assistant.session.store import MAX_DEPTH, SessionFileError

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> Path:
    """The thesis sample (objects, locations P1-P10, the seam path) saved once."""
    folder = tmp_path_factory.mktemp("saved") / "s"
    Session.from_sample("thesis_rv2aj", folder).close()
    return folder


def _copy(saved: Path, tmp: Path, change: Callable[[dict], Any] | None = None,
          text: str | None = None) -> Path:
    folder = tmp / "copy"
    shutil.copytree(saved, folder)
    path = folder / "session.json"
    if text is not None:
        path.write_text(text)
    elif change is not None:
        doc = json.loads(path.read_text())
        change(doc)
        path.write_text(json.dumps(doc))
    return folder


def _loc(doc: dict, name: str = "P1") -> dict:
    return next(d for d in doc["locations"] if d["name"] == name)


def _set(d: dict, key: str, value: Any) -> None:
    d[key] = value


BAD: list[tuple[str, Callable[[dict], Any], str]] = [
    ("joints of 1e308", lambda d: _set(d, "robot_joints", [1e308] * 5),
     r"robot_joints: joint 1 at .* beyond the .* limits"),
    ("joints beyond a limit", lambda d: _set(d, "robot_joints", [0, 0, 0, 0, 4.0]),
     r"robot_joints: joint 5 at 229\.183 deg is beyond"),
    ("joints of another robot", lambda d: _set(d, "robot_joints", [0.0] * 6),
     r"expected 5 finite joint angles"),
    ("a location's joints", lambda d: _loc(d).__setitem__("q_hint", [0, -3.0, 0, 0, 0]),
     r"location P1 joints: joint 2"),
    ("a location far away", lambda d: _loc(d)["T_world_tool"][0].__setitem__(3, 1e6),
     r"location P1: 1e\+06 m from the origin"),
    ("a location's rotation", lambda d: _loc(d)["T_world_tool"][0].__setitem__(0, 2.0),
     r"location P1: not a rotation"),
    ("a location's name", lambda d: _loc(d).__setitem__("name", "P1\n; rm -rf"),
     r"must be 1-64 printable"),
    ("an uncertainty", lambda d: _loc(d).__setitem__("uncertainty_m", -1.0),
     r"P1 uncertainty \(m\): -1\.0 is out of range"),
    ("a path speed", lambda d: d["mission"]["paths"][0].__setitem__("speed", 0.0),
     r"speed \(m/s\): 0\.0 is out of range"),
    ("a path point", lambda d: d["mission"]["paths"][0]["segments"][0]["points"][0]
     .__setitem__(2, 500.0), r"segment 1 point 1: 500 m"),
    ("the mission order", lambda d: d["mission"].__setitem__("order", [0, 0]),
     r"mission order: \[0, 0\] is not an order"),
    ("a counter", lambda d: d["counters"].__setitem__("replans", -4),
     r"counters replans: -4 is out of range"),
    ("a collision", lambda d: _set(d, "recorded_collisions", [[0.0, 0.0]]),
     r"recorded collision 1: expected 5"),
    ("the simulation speed", lambda d: d["link"].__setitem__("time_scale", 1e9),
     r"link time_scale: 1000000000\.0 is out of range"),
    ("a dialect", lambda d: _set(d, "export_dialect", "cobol"),
     r"export_dialect: 'cobol' is not one of melfa"),
    ("a hidden obstacle", lambda d: d["hidden_obstacles"][0]["size"].__setitem__(0, 1e6),
     r"hidden obstacle O3 size \(m\): 1000000\.0 is out of range"),
    ("a camera", lambda d: _set(d, "pointer", {"cameras": [{"width": 640}]}),
     r"pointer: camera model is missing"),
    ("a seed", lambda d: _set(d, "pointer", {"seed": -1}), r"pointer seed: -1"),
]


@pytest.mark.parametrize("what,change,match", BAD, ids=[b[0] for b in BAD])
def test_every_field_is_range_checked(saved, tmp_path, what, change, match):
    folder = _copy(saved, tmp_path, change)
    with pytest.raises(SessionFileError, match=match) as exc:
        Session.load(folder)
    assert str(folder / "session.json") in str(exc.value)


@pytest.mark.parametrize("text,match", [
    ('{"schema_version": 1, "robot_joints": [1e999, 0, 0, 0, 0]}', "beyond floating-point"),
    ('{"schema_version": 1, "counters": {"replans": 1' + "0" * 40 + '}}', "more than 18"),
    ('{"schema_version": 1, "plan_report": ' + "[" * 100_000 + "]" * 100_000 + "}",
     f"nested deeper than {MAX_DEPTH} levels"),
    ('{"schema_version": 1, "plan_report": ' + "[" * 40 + "]" * 40 + "}",
     f"nested deeper than {MAX_DEPTH} levels"),
    ('{"schema_version": 1, "machine": {"state": "setup", "mode": "flying"}}', "'flying'"),
])
def test_the_json_itself_is_bounded(saved, tmp_path, text, match):
    folder = _copy(saved, tmp_path, text=text)
    with pytest.raises(SessionFileError, match=match):
        Session.load(folder)


def test_a_session_saved_moving_opens_idle_with_a_note(saved, tmp_path):
    folder = _copy(saved, tmp_path, lambda d: d["machine"].update(state="plan", mode="moving"))
    s = Session.load(folder)
    try:
        assert s.machine.mode.value == "idle"
        assert any("saved while the robot was moving; it opens idle" in n
                   for n in s.load_notes), s.load_notes
        s.stop()  # Stop, Cancel and Load work again (they did nothing while stuck)
        s.cancel()
        assert s.previous() and s.machine.state != "plan"
    finally:
        s.close()
    busy = _copy(saved, tmp_path / "b", lambda d: d["machine"].update(mode="busy"))
    s = Session.load(busy)
    assert s.machine.mode.value == "idle" and "a task was running" in " ".join(s.load_notes)
    s.close()


def test_a_plan_that_does_not_fit_the_robot_is_dropped_with_a_note(tmp_path):
    from assistant.mission.motion import Trajectory, Waypoint

    s = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    q = s.current_joints()
    q_bad = q.copy()
    q_bad[0] = 3.5  # beyond J1's +-150 deg
    start = Waypoint(s.robot.fk(q), q)
    s.trajectory = Trajectory(start, [])
    s.plan_report = {"description": "a plan"}
    s.save(s.folder)
    back = Session.load(s.folder)
    assert back.trajectory is not None  # a plan that fits loads as it was
    s.trajectory = Trajectory(Waypoint(s.robot.fk(q), q_bad), [])
    s.save(s.folder)
    s.close()
    back = Session.load(tmp_path / "s")
    assert back.trajectory is None and back.plan_report is None
    assert any("the plan was dropped - plan the mission again" in n for n in back.load_notes)
    assert np.allclose(back.current_joints(), q)
    back.close()


def test_bad_input_is_exit_code_2_with_one_line_and_no_traceback(saved, tmp_path):
    folder = _copy(saved, tmp_path, text='{"schema_version": 1, "mission": ' + "{\"a\": " *
                   50_000 + "1" + "}" * 50_000 + "}")
    proc = subprocess.run([sys.executable, "-m", "assistant", "serve", "--session",
                           str(folder), "--port", "0"], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "nested deeper than" in proc.stderr and "Traceback" not in proc.stderr
