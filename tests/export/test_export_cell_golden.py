"""The UR5 and UR10 sample cells' programs in FANUC TP and Yaskawa INFORM, as `cellteach run`
wrote them (tests/export/make_cell_golden.py keeps them with the plan they came from), read
back against that plan:

* the independent grammar (tests/export/grammars) takes every file and gives each position's
  values as written; through the robot's kinematics - forward for joint values, inverse on
  the branch CONFIG or RCONF names for a Cartesian pose - every one lands within 0.01 mm of
  the planned TCP and on the planned joints (the issue's round trip: parse -> positions ->
  FK/IK);
* the dialect's own reader gives the program back, and driving it (`simulate`) arrives at
  every target in the planned posture.

Tolerances: the TCP within 0.01 mm (the issue's bound; the number formats leave at most
0.9 um of position rounding, and 0.0005 deg of W/P/R or 0.00005 deg of a joint or Rx..Rz at
a UR10's 1.3 m reach is under 12 um and 1.2 um); joints within 1e-3 rad (a branch or a turn
apart is over 0.1 rad).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from grammars import check_report
from scipy.spatial.transform import Rotation

from assistant.export import get_dialect
from assistant.export.dialect import ProgramFile
from assistant.export.fanuc import config_back
from assistant.export.simulate import simulate
from assistant.export.yaskawa import rconf_back
from assistant.robots.framed import controller_view

GOLDEN = Path(__file__).resolve().parent / "golden"
CASES = [(d, c) for d in ("fanuc", "yaskawa") for c in ("ur5_cell", "ur10_cell")]
POSITION = 1e-5  # m: the 0.01 mm
ANGLE = np.radians(0.01)
JOINTS = 1e-3  # rad


@pytest.fixture(scope="module")
def robots(tmp_path_factory):
    """cell -> its robot (tool included), as the sample cell sets it up, seen from its program
    frame (the UR controller's base: the programs count poses from there, `export_files`
    writes them so; plan.json keeps the model base)."""
    from assistant.session import Session

    made = {}

    def get(cell: str):
        if cell not in made:
            s = Session.from_sample(cell, tmp_path_factory.mktemp(cell))
            made[cell] = controller_view(s.robot)
            s.close()
        return made[cell]

    return get


def golden(dialect: str, cell: str) -> tuple[dict[str, str], dict]:
    folder = GOLDEN / dialect / cell
    files = {p.name: p.read_text(encoding="ascii") for p in sorted(folder.iterdir())
             if p.suffix != ".json"}
    return files, json.loads((folder / "plan.json").read_text(encoding="utf-8"))


def pose_of(values: list[float]) -> np.ndarray:
    """X, Y, Z (mm) and rotations about the fixed X, Y, Z axes (deg): FANUC's W, P, R and
    Yaskawa's Rx, Ry, Rz (scipy's extrinsic "xyz"), independent of the writers' code."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", values[3:6], degrees=True).as_matrix()
    T[:3, 3] = np.asarray(values[:3]) / 1000.0
    return T


def _off(Ta: np.ndarray, Tb: np.ndarray) -> tuple[float, float]:
    dp = float(np.linalg.norm(Ta[:3, 3] - Tb[:3, 3]))
    da = Rotation.from_matrix(Ta[:3, :3].T @ Tb[:3, :3]).magnitude()
    return dp, float(da)


def test_every_cell_program_is_kept_with_its_plan():
    for dialect, cell in CASES:
        files, plan = golden(dialect, cell)
        assert files and plan["cell"] == cell and plan["dialect"] == dialect
        names = {p["name"] for p in plan["positions"]}
        assert {"START", "SEAM_A", "GOAL"} <= names  # the operator's names, kept


@pytest.mark.parametrize("dialect, cell", CASES)
def test_the_grammar_reads_the_cell_program_back_onto_the_plan(robots, dialect, cell):
    files, plan = golden(dialect, cell)
    robot = robots(cell)
    rep = check_report(dialect, files)
    assert rep.problems == []
    planned = plan["positions"]
    assert rep.motions >= 4 and len(rep.targets) == len(planned)
    if dialect == "fanuc":  # FANUC names its positions: P[n:"NAME"]
        by_name = {p["name"]: p for p in planned}
        pairs = [(t, by_name[t["name"]]) for t in rep.targets]
    else:  # INFORM numbers them in the order of first use
        pairs = list(zip(rep.targets, planned, strict=True))
    T_frame = getattr(robot, "T_base_frame", np.eye(4))  # the program frame in the model base
    for t, p in pairs:
        q_plan = np.asarray(p["q"])
        T_plan = robot.fk(q_plan)  # in the program frame
        in_frame = np.linalg.inv(T_frame) @ np.asarray(p["T_base_tool"])
        assert _off(T_plan, in_frame)[0] < 1e-9  # the plan is consistent
        if t["kind"] == "joint":
            q = np.radians(t["values"])
            assert np.max(np.abs(q - q_plan)) < JOINTS
            dp, da = _off(robot.fk(q), T_plan)
            assert dp < POSITION and da < ANGLE, (p["name"], dp, da)
            continue
        assert t["kind"] == "cartesian"
        T = pose_of(t["values"])
        dp, da = _off(T, T_plan)
        assert dp < POSITION and da < ANGLE, (p["name"], dp, da)
        flags = (config_back(robot, t["config"], t["number"]) if dialect == "fanuc"
                 else rconf_back(robot, t["rconf"]))
        branch = [q for q in robot.ik(T, q_plan).solutions if flags.matches(robot, q, 1e-4)]
        assert branch, f"{p['name']}: no IK solution has the written flags"
        q = min(branch, key=lambda s: float(np.max(np.abs(s - q_plan))))
        assert np.max(np.abs(q - q_plan)) < JOINTS, (p["name"], q, q_plan)
        assert _off(robot.fk(q), T_plan)[0] < POSITION


@pytest.mark.parametrize("dialect, cell", CASES)
def test_the_cell_program_drives_through_the_planned_postures(robots, dialect, cell):
    files, plan = golden(dialect, cell)
    robot = robots(cell)
    back = get_dialect(dialect).read([ProgramFile(n, t) for n, t in files.items()], robot)
    planned = {p["name"]: np.asarray(p["q"]) for p in plan["positions"]}
    moves = back.moves()
    assert [m.target.name for m in moves][0] == "START"
    # the arm stands at the start posture; the path is compared every 50 mm (speed, not
    # accuracy: each target is reached exactly, by joints or by IK on the written branch)
    sim = simulate(back, robot, planned["START"], max_step=0.05)
    for m, sm in zip(moves, sim.moves, strict=True):
        assert np.max(np.abs(sm.q[-1] - planned[m.target.name])) < JOINTS, m.target.name
    assert not sim.config_mismatches
