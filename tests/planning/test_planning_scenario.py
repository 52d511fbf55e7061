"""The thesis sample cell: what it holds, that its generator reproduces it, that every taught
location is reachable and free, and that the hidden O3 touches none of them."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from assistant.collision.checker import CollisionChecker
from assistant.mission.model import SegmentKind
from assistant.mission.motion import ToolActionKind
from assistant.planning.locations import solve_location
from assistant.planning.scenario import DEFAULT_SAMPLE, load_hidden


def test_sample_cell_holds_the_thesis_experiment(scenario):
    cell, mission = scenario.cell, scenario.mission
    assert np.allclose(cell.T_world_base, np.eye(4))
    robot = cell.robot()
    assert robot.name == "Mitsubishi RV-2AJ" and np.isclose(robot.T_flange_tool[2, 3], 0.1)
    objs = cell.objects
    assert set(objs) == {"table", "O1", "O2"}
    for name in ("O1", "O2"):  # known from DXF drawings, like the thesis
        assert objs[name].source is not None and objs[name].source.format == "dxf"
        assert objs[name].role.value == "obstacle"
    assert objs["table"].role.value == "fixture"
    top = objs["table"].T_world_object[2, 3] + objs["table"].primitive.size[2] / 2
    assert top == pytest.approx(0.0)
    assert [o.name for o in scenario.hidden] == ["O3"]
    assert mission.start.name == "P1" and mission.goal.name == "P10"
    (path,) = mission.paths
    assert path.name == "SEAM" and path.segments[0].kind == SegmentKind.LINE
    assert [a.kind for a in path.actions_before] == [ToolActionKind.GRIPPER_CLOSE]
    assert [a.kind for a in path.actions_after] == [ToolActionKind.GRIPPER_OPEN]
    # thesis layout: P1 on one side, P10 on the other, the line in front
    assert mission.start.position[1] < 0 < mission.goal.position[1]
    assert path.start[0] > 0.25 and path.end[0] > 0.25


def test_locations_are_reachable_and_free_and_o3_is_clear_of_them(scenario):
    cell, mission = scenario.cell, scenario.mission
    robot = cell.robot()
    known = CollisionChecker(robot, cell.collision_objects_in_base())
    hidden = CollisionChecker(robot, scenario.hidden, self_collision=False)
    T_line = np.eye(4)
    T_line[:3, :3] = mission.paths[0].R_world_tool
    seed = np.zeros(robot.dof)
    for name, T in [("P1", mission.start.T_world_tool), ("P10", mission.goal.T_world_tool)] + [
            (f"line {u}", _at(T_line, mission.paths[0].start * (1 - u)
                              + mission.paths[0].end * u)) for u in np.linspace(0, 1, 8)]:
        sol = solve_location(robot, known, name, T, cell.T_world_base, seed=seed)
        assert known.is_valid(sol.q), name
        assert hidden.is_valid(sol.q), f"O3 touches {name}"
        # within reach: flange reach 0.41 m + tool, with margin
        assert np.linalg.norm(sol.T_base_tool[:3, 3] - [0, 0, 0.3]) < 0.5


def test_generator_reproduces_the_committed_files(tmp_path):
    script = DEFAULT_SAMPLE / "make_cell.py"
    subprocess.run([sys.executable, str(script), str(tmp_path)], check=True,
                   capture_output=True)
    for rel in ("cell/cell.json", "mission.json", "hidden.json", "dxf/O1.dxf", "dxf/O2.dxf"):
        assert (tmp_path / rel).read_bytes() == (DEFAULT_SAMPLE / rel).read_bytes(), rel
    assert sorted(p.name for p in (tmp_path / "cell" / "cad").iterdir()) == sorted(
        p.name for p in (DEFAULT_SAMPLE / "cell" / "cad").iterdir())


def test_hidden_file_errors_name_the_file(tmp_path):
    bad = tmp_path / "hidden.json"
    bad.write_text('{"obstacles": [{"name": "X", "kind": "box", "size": [0.1, -1, 0.1]}]}')
    with pytest.raises(ValueError, match="hidden.json"):
        load_hidden(bad, np.eye(4))
    bad.write_text("[]")
    with pytest.raises(ValueError, match="list 'obstacles'"):
        load_hidden(bad, np.eye(4))


def _at(T, p):
    T = T.copy()
    T[:3, 3] = p
    return T
