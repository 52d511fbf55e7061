"""The simulated robot runs at the program's pace (issue 49): the time law of the predicted
cycle time, applied to the path the executor drives, so a run lasts what the program will and
the seam runs at its programmed 50 mm/s (not at the joints' limits)."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.export import predict_cycle_time, program_from_trajectory
from assistant.export.pace import program_pace
from assistant.links.link import LinkEventKind
from assistant.planning import EndReason, ExecutionConfig, MissionExecutor
from assistant.planning.pieces import PieceKind
from tests.planning.planning_fixtures import make_planner, sim_robot, tcp_points

#: The thesis seam's programmed speed (sample_cells/thesis_rv2aj: 50 mm/s).
SEAM_SPEED = 0.05


@pytest.fixture(scope="module")
def plan(scenario, robot):
    p = make_planner(robot, scenario.known_obstacles())
    out = p.plan_mission(scenario.mission, np.eye(4), np.zeros(robot.dof), exploring=False)
    assert out.ok
    return out


def test_the_pieces_paces_add_up_to_the_predicted_cycle_time(robot, plan):
    paces = [program_pace(p.trajectory, robot, p.dense()) for p in plan.pieces]
    assert all(pc is not None for pc in paces)
    for pc, piece in zip(paces, plan.pieces, strict=True):
        assert len(pc.t) == len(piece.dense()) and pc.t[0] == 0.0
        assert np.all(np.diff(pc.t) >= 0.0) and np.all(pc.hold >= 0.0)
    predicted = predict_cycle_time(program_from_trajectory(plan.trajectory, robot, name="T"),
                                   robot).total_s
    # One time law on the same moves; the whole program's Cartesian caps are measured on its
    # own simulated path, the same TCP path as the planned one to IK tolerance: 0.1 %.
    assert sum(pc.seconds for pc in paces) == pytest.approx(predicted, rel=1e-3)
    # the gripper closes and opens on the seam piece: two holds of the program's 0.3 s
    seam = plan.pieces[[p.kind for p in plan.pieces].index(PieceKind.APPLICATION)]
    holds = program_pace(seam.trajectory, robot, seam.dense()).hold
    assert sorted(holds[holds > 0]) == pytest.approx([0.3, 0.3])


def test_the_seam_runs_at_its_programmed_speed(robot, plan):
    seam = next(p for p in plan.pieces if p.kind == PieceKind.APPLICATION)
    D = seam.dense()
    pc = program_pace(seam.trajectory, robot, D)
    P = tcp_points(robot, D)
    # the arm's TCP speed between samples while it moves (holds left out)
    dt = np.diff(pc.t) - pc.hold[:-1]
    ds = np.linalg.norm(np.diff(P, axis=0), axis=1)
    moving = dt > 1e-9
    v = ds[moving] / dt[moving]
    # cruise: the line's middle runs at the programmed speed (the profile is flat there;
    # 2 % covers the sampling of the TCP arc length)
    assert np.median(v) == pytest.approx(SEAM_SPEED, rel=0.02)
    assert float(np.max(v)) <= SEAM_SPEED * 1.02


def test_a_run_on_the_simulated_robot_lasts_the_predicted_cycle_time(scenario, robot, plan):
    planner = make_planner(robot, scenario.known_obstacles())
    link = sim_robot(robot, (), plan.locations["P1"])
    seen = []
    link.subscribe(lambda ev: seen.append(ev))
    t0 = link.clock.now()
    rep = MissionExecutor(planner, link, ExecutionConfig(plan_final=False)).run(
        scenario.mission, np.eye(4), plan=plan)
    assert rep.end == EndReason.COMPLETED, rep.describe()
    ran = link.clock.now() - t0
    predicted = predict_cycle_time(program_from_trajectory(plan.trajectory, robot, name="T"),
                                   robot).total_s
    # the motion loop ends a move on its last step (<= one 20 ms event period a piece late)
    assert ran == pytest.approx(predicted, abs=0.02 * len(plan.pieces) + 1e-3 * predicted)
    # the arm stood still at the gripper actions: two events 0.3 s apart at one posture
    moved = [e for e in seen if e.kind == LinkEventKind.MOVED]
    still = [b.time_s - a.time_s for a, b in zip(moved, moved[1:], strict=False)
             if np.allclose(a.q, b.q, atol=1e-12)]
    assert sum(still) >= 0.5


def test_a_pace_that_runs_backwards_is_refused_before_the_arm_moves(robot, plan):
    from assistant.links.link import LinkError

    D = plan.pieces[0].dense()
    link = sim_robot(robot, (), D[0])
    t = np.linspace(0.0, 1.0, len(D))
    t[len(D) // 2] = -1.0
    with pytest.raises(LinkError, match="backwards"):
        link.move_paced(D, t, np.zeros(len(D)))
    with pytest.raises(LinkError, match="a finite time and hold per path point"):
        link.move_paced(D, t[:-1], np.zeros(len(D)))
    assert np.array_equal(link.current_joints(), D[0])  # nothing moved: the same array
