"""Exploration modes on the simulated robot with a hidden obstacle: evidence reaches the world
model, budgets end the run, paths are replayed past a blocked stretch."""

from __future__ import annotations

import numpy as np
import pytest
from planning_fixtures import box, make_planner, sim_robot, tcp_points

from assistant.planning.execution import EndReason
from assistant.planning.exploration import ExplorationConfig, Explorer
from assistant.progress import Progress
from assistant.trajectory.assemble import joint_interpolation

Q_A = np.radians([-50.0, 40.0, 60.0, 20.0, 0.0])
Q_B = np.radians([50.0, 40.0, 60.0, 20.0, 0.0])


@pytest.fixture
def planner(scenario):
    return make_planner(scenario.cell.robot(), scenario.known_obstacles())


def sweep(robot):
    return joint_interpolation(robot, Q_A, Q_B, 0.005)


def hidden_mid(robot):
    P = sweep(robot)
    return box("hidden", tcp_points(robot, P[len(P) // 2][None])[0] + [0, 0, 0.05],
               [0.06, 0.06, 0.06])


def test_replay_records_the_hidden_obstacle_and_rejoins_the_path(planner):
    robot = planner.robot
    assert planner.checker.check_path(list(sweep(robot))) is None  # fine in the known cell
    link = sim_robot(robot, [hidden_mid(robot)], Q_A)
    rep = Explorer(planner, link).replay(sweep(robot))
    assert rep.end == EndReason.COMPLETED, rep.describe()
    assert rep.collision_indications >= 1
    assert len(planner.world.collisions) == rep.collision_indications
    assert "skipping" in " ".join(rep.log)
    assert np.allclose(link.current_joints(), Q_B, atol=1e-6)  # it got to the end


def test_random_moves_are_deterministic_and_end_within_budget(scenario):
    robot = scenario.cell.robot()
    ends = []
    for _ in range(2):
        planner = make_planner(robot, scenario.known_obstacles())
        link = sim_robot(robot, [hidden_mid(robot)], Q_A)
        rep = Explorer(planner, link).random_moves(2, seed=7)
        assert rep.end == EndReason.COMPLETED, rep.describe()
        assert rep.targets == 2 and rep.reached + rep.unplannable <= 2
        assert rep.executed_tcp_length > 0
        ends.append(link.current_joints())
    assert np.allclose(ends[0], ends[1])


def test_indication_budget_ends_exploration(planner):
    robot = planner.robot
    link = sim_robot(robot, [hidden_mid(robot)], Q_A)
    rep = Explorer(planner, link, ExplorationConfig(max_indications=0)).replay(sweep(robot))
    assert rep.end == EndReason.INDICATION_BUDGET and "more than 0" in rep.reason


def test_following_the_roads_visits_road_cells(planner):
    robot = planner.robot
    link = sim_robot(robot, (), Q_A)
    rep = Explorer(planner, link).follow_roads(max_targets=3)
    assert rep.end == EndReason.COMPLETED, rep.describe()
    assert rep.targets == 3 and rep.reached >= 1
    # it ended in a road cell
    w = planner.world
    lab = planner.roadmap.voronoi.label.reshape(-1)
    assert rep.reached == 0 or lab[w.tcp_cell(link.current_joints())] == -1


def test_cancelled_exploration_stops(planner):
    robot = planner.robot
    link = sim_robot(robot, (), Q_A)
    prog = Progress("explore")
    prog.cancel()
    rep = Explorer(planner, link).replay(sweep(robot), progress=prog)
    assert rep.end == EndReason.CANCELLED
