"""MissionPlanner on the sample cell (coarse world, real FCL, real roadmap and net): one
verified trajectory with mission labels and gripper actions, and every failure with a reason
that names the piece."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from planning_fixtures import box, make_planner, tcp_points

from assistant.collision.checker import CollisionChecker
from assistant.mission.model import (
    ApplicationPath,
    Location,
    PathSegment,
    ResolvedMission,
    SegmentKind,
)
from assistant.mission.motion import MotionKind, ToolActionKind
from assistant.planning.locations import LocationError, LocationProblem, solve_location
from assistant.progress import Cancelled, Progress
from assistant.roadmap.astar import SearchBudget
from assistant.roadmap.planner import RoadmapConfig
from assistant.transforms import make_T, rot_x


@pytest.fixture(scope="module")
def planner(scenario, robot):
    return make_planner(robot, scenario.known_obstacles())


@pytest.fixture(scope="module")
def plan(planner, scenario):
    return planner.plan_mission(scenario.mission, scenario.cell.T_world_base, np.zeros(5))


def test_sample_mission_is_one_verified_trajectory(plan, planner, scenario, robot):
    assert plan.ok, plan.report.describe()
    traj = plan.trajectory
    dense = traj.dense_joint_path()
    # independent exact check against every known obstacle, and the limits
    known = CollisionChecker(robot, scenario.known_obstacles())
    assert known.check_path(list(dense)) is None
    assert robot.limits.contains_batch(dense).all()
    # it starts at P1, ends at P10, named for the program
    assert np.allclose(traj.start.q, plan.locations["P1"]) and traj.start.name == "P1"
    assert np.allclose(traj.motions[-1].target.q, plan.locations["P10"])
    assert traj.motions[-1].target.name == "P10"
    assert np.allclose(traj.start.position, scenario.mission.start.position, atol=1e-6)
    # labels name the mission steps, in order
    labels = [m.label for m in traj.motions]
    steps = list(dict.fromkeys(labels))
    assert steps == ["P1 -> SEAM", "SEAM", "SEAM -> P10"]
    # the application path is one straight MVS, tool down, from P7 to P8 (named so)
    app = [m for m in traj.motions if m.label == "SEAM"]
    assert len(app) == 1 and app[0].kind == MotionKind.LINEAR and app[0].target.name == "P8"
    line = scenario.mission.paths[0]
    P = tcp_points(robot, app[0].joint_path)
    d = np.linalg.norm(np.cross(P - line.start, line.end - line.start), axis=1) / np.linalg.norm(
        line.end - line.start)
    assert d.max() < 1e-4
    assert np.allclose(app[0].target.T_base_tool[:3, 2], [0, 0, -1], atol=1e-6)
    # gripper closes on arrival at P7 (before the line), opens after it
    k = labels.index("SEAM")
    before = traj.motions[k - 1]
    assert [a.kind for a in before.actions_after] == [ToolActionKind.GRIPPER_CLOSE]
    assert before.target.name == "P7"
    assert [a.kind for a in app[0].actions_after] == [ToolActionKind.GRIPPER_OPEN]
    # the report's figures are those of the trajectory
    rep = plan.report
    assert rep.ok and rep.failed_piece is None
    assert rep.primitives == len(traj.motions)
    assert rep.primitive_counts == traj.primitive_counts()
    tcp = tcp_points(robot, dense)
    assert rep.tcp_length == pytest.approx(np.linalg.norm(np.diff(tcp, axis=0), axis=1).sum())
    assert rep.min_clearance is not None and rep.min_clearance > 0
    assert [p.label for p in rep.pieces if p.kind == "transfer"] == ["P1 -> SEAM",
                                                                     "SEAM -> P10"]
    assert "mission plan ok" in rep.describe()


def test_exploring_plan_is_verified_too(planner, scenario, robot):
    plan = planner.plan_mission(scenario.mission, scenario.cell.T_world_base, np.zeros(5),
                                exploring=True)
    assert plan.ok and plan.report.exploring
    known = CollisionChecker(robot, scenario.known_obstacles())
    assert known.check_path(list(plan.trajectory.dense_joint_path())) is None


def _with_goal(mission: ResolvedMission, T_world_tool) -> ResolvedMission:
    return replace(mission, goal=Location("P10", T_world_tool))


def test_unreachable_goal_names_the_location(planner, scenario):
    T = scenario.mission.goal.T_world_tool.copy()
    T[:3, 3] = [0.9, 0.0, 0.2]
    plan = planner.plan_mission(_with_goal(scenario.mission, T), np.eye(4), np.zeros(5))
    assert not plan.ok and plan.trajectory is None
    assert plan.report.failed_piece == "goal P10"
    assert "P10" in plan.reason and "unreachable" in plan.reason


def test_goal_inside_an_obstacle_names_it(planner, scenario):
    T = scenario.mission.goal.T_world_tool.copy()
    T[:3, 3] = [0.22, -0.20, 0.12]  # inside O1
    plan = planner.plan_mission(_with_goal(scenario.mission, T), np.eye(4), np.zeros(5))
    assert not plan.ok and plan.report.failed_piece == "goal P10"
    assert "inside an obstacle" in plan.reason and "O1" in plan.reason


def test_five_axis_orientation_is_refused_with_the_projection_offered(planner, scenario,
                                                                     robot):
    T = scenario.mission.goal.T_world_tool @ make_T(rot_x(np.radians(30.0)))  # tilted sideways
    with pytest.raises(LocationError) as err:
        solve_location(robot, planner.checker, "P10", T, np.eye(4))
    assert err.value.problem == LocationProblem.ORIENTATION
    sugg = err.value.suggestion_T_world_tool
    assert sugg is not None and np.allclose(sugg[:3, 3], T[:3, 3])
    assert robot.ik(sugg).ok  # the offered pose is reachable
    plan = planner.plan_mission(_with_goal(scenario.mission, T), np.eye(4), np.zeros(5))
    assert not plan.ok and "orientation" in plan.reason and "projected" in plan.reason


def test_application_path_through_an_obstacle_names_the_path(planner, scenario):
    bad = ApplicationPath("cut", [PathSegment(SegmentKind.LINE, (np.array([0.22, -0.33, 0.10]),
                                                                 np.array([0.22, -0.07, 0.10])))])
    mission = replace(scenario.mission, paths=[bad])
    plan = planner.plan_mission(mission, np.eye(4), np.zeros(5))
    assert not plan.ok and plan.report.failed_piece == "cut"
    assert "O1" in plan.reason


def test_no_path_through_a_wall(scenario, robot):
    # a wall in the plane y = 0 (with a gap only around the turret): every posture with
    # J1 = 0 hits it, and J1 cannot go round the back (+-150 deg), so P1 and P10 are apart
    wall = [box("wall front", [0.55, 0.0, 0.45], [0.9, 0.02, 1.1]),
            box("wall back", [-0.55, 0.0, 0.45], [0.9, 0.02, 1.1]),
            box("wall top", [0.0, 0.0, 0.7], [0.2, 0.02, 0.6])]
    planner = make_planner(robot, scenario.known_obstacles() + wall)
    plan = planner.plan_mission(scenario.mission, np.eye(4), np.zeros(5))
    assert not plan.ok and plan.report.failed_piece == "SEAM"  # the line crosses the wall
    mission = replace(scenario.mission, paths=[])
    plan = planner.plan_mission(mission, np.eye(4), np.zeros(5))
    assert not plan.ok and plan.report.failed_piece == "P1 -> P10"
    assert plan.reason.startswith("no path")


def test_search_budget_ends_the_plan_with_a_reason(scenario, robot):
    # exploring: the transfer needs the roads (a final plan may need no search at all)
    tight = make_planner(robot, scenario.known_obstacles(),
                         roadmap=RoadmapConfig(budget=SearchBudget(max_expansions=2)))
    plan = tight.plan_mission(scenario.mission, np.eye(4), np.zeros(5), exploring=True)
    assert not plan.ok and plan.report.failed_piece == "P1 -> SEAM"
    assert "budget exhausted" in plan.reason


def test_cancelled_planning_raises_cancelled(planner, scenario):
    prog = Progress("plan")
    prog.cancel()
    with pytest.raises(Cancelled):
        planner.plan_mission(scenario.mission, np.eye(4), np.zeros(5), prog)


def test_paths_are_ordered_by_measured_transfers(planner, robot):
    # three short reversible lines given in a poor order; the planner orders and orients them
    down = np.diag([1.0, -1.0, -1.0])

    def line(name, a, b):
        return ApplicationPath(name, [PathSegment(SegmentKind.LINE, (np.array(a),
                                                                     np.array(b)))],
                               R_world_tool=down, reversible=True)

    paths = [line("far", [0.14, 0.30, 0.15], [0.08, 0.30, 0.15]),
             line("near", [0.08, -0.30, 0.15], [0.14, -0.30, 0.15]),
             line("mid", [0.34, -0.04, 0.12], [0.34, 0.04, 0.12])]
    start = Location("S", make_T(down, np.array([0.05, -0.30, 0.25])))
    goal = Location("G", make_T(down, np.array([0.05, 0.30, 0.25])))
    plan = planner.plan_mission(ResolvedMission(start, goal, paths), np.eye(4), np.zeros(5))
    assert plan.ok, plan.report.describe()
    assert [n.split(" ")[0] for n in plan.report.order] == ["near", "mid", "far"]
    assert plan.ordering is not None and plan.ordering.exact
    assert plan.ordering.rounds >= 1 and plan.ordering.measured >= 4
    labels = list(dict.fromkeys(m.label for m in plan.trajectory.motions))
    assert labels == ["S -> near", "near", "near -> mid", "mid", "mid -> far", "far",
                      "far -> G"]


def test_goal_equal_to_start_ends_in_the_start_posture_and_exports(planner, scenario, robot,
                                                                   monkeypatch):
    """A round trip back home: one location, one posture (the program names it once) - also
    with a numeric IK, whose answer depends a hair on its seed (emulated here)."""
    from assistant.export import get_dialect
    from assistant.export.program import program_from_trajectory

    exact_ik = type(robot).ik

    def seed_dependent_ik(self, T, seed=None, **kw):
        res = exact_ik(self, T, seed, **kw)
        wobble = 0.0 if seed is None else 1e-7 * float(np.sum(seed))
        return replace(res, solutions=[q + wobble for q in res.solutions])

    monkeypatch.setattr(type(robot), "ik", seed_dependent_ik)
    mission = replace(scenario.mission, goal=scenario.mission.start)
    plan = planner.plan_mission(mission, scenario.cell.T_world_base, np.zeros(5))
    assert plan.ok, plan.report.describe()
    traj = plan.trajectory
    assert traj.motions[-1].target.name == traj.start.name == "P1"
    assert np.allclose(traj.motions[-1].target.q, traj.start.q, rtol=0, atol=1e-12)
    prog = program_from_trajectory(traj, robot, name="HOME")
    files = get_dialect("melfa").write(prog, robot)
    assert sum(f.text.count("P1=(") for f in files) == 1


def test_when_no_smoothed_transfer_verifies_few_joint_moves_do(planner, plan, scenario, robot,
                                                               monkeypatch):
    """Every fitted trajectory refused (as when lines and arcs graze a part taught right next
    to the path): the final transfer falls back to straight joint moves along the roadmap
    path, shortcut wherever one move is valid - verified like everything else."""
    import assistant.planning.mission_planner as mp_mod
    from assistant.trajectory.assemble import AssemblyResult

    def refuse(robot_, fit, particles, verifier, params):
        return AssemblyResult(None, replace(mp_mod.verify(robot_, mp_mod._joint_moves(
            robot_, particles.joints[:2], "x", params), None).report, ok=False,
            reason="refused by the test"), None)

    monkeypatch.setattr(mp_mod, "assemble_trajectory", refuse)
    # and no joint moves along the searched path keep the clearance (the form tried first)
    monkeypatch.setattr(mp_mod, "moves_along", lambda *a, **k: (None, "refused by the test"))
    locs = plan.locations  # solved before the patch
    road = planner.roadmap.plan(locs["P1"], locs["P10"])
    assert road.ok and len(road.joint_path) > 4
    tr = planner.plan_transfer(locs["P1"], locs["P10"], label="fallback", roadmap_plan=road)
    assert tr.ok, tr.report.reason
    assert any("joint moves along the shortened roadmap path" in n for n in tr.report.notes)
    motions = tr.piece.trajectory.motions
    assert all(m.kind == MotionKind.JOINT for m in motions)
    assert len(motions) < len(road.joint_path) - 1  # fewer than the searched path's edges
    known = CollisionChecker(robot, scenario.known_obstacles())
    assert known.check_path(list(tr.piece.trajectory.dense_joint_path())) is None
    assert np.allclose(motions[-1].target.q, locs["P10"])
    # Exploring keeps to the roads (their clearance keeps it off what is not known yet).
    explo = planner.plan_transfer(locs["P1"], locs["P10"], label="fallback", exploring=True,
                                  roadmap_plan=road)
    assert explo.ok and any("joint moves along the roadmap path" in n
                            for n in explo.report.notes)
    assert len(explo.piece.trajectory.motions) == len(road.joint_path) - 1
