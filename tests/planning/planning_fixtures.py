"""Shared builders for the planning tests: the sample cell on a coarse world (fast to build),
real FCL, the real roadmap and net with smaller budgets, and the simulated robot on a virtual
clock. Imported by the tests (not a conftest) so each test file says what it uses."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.links.simulated import SimulatedRobot
from assistant.links.timing import VirtualClock
from assistant.planning.config import MissionPlannerConfig
from assistant.planning.mission_planner import MissionPlanner
from assistant.roadmap.planner import RoadmapConfig, RoadmapPlanner
from assistant.robots.catalog import installed_robot_urdf
from assistant.robots.model import CollisionShape, Robot, ShapeKind, Tool
from assistant.robots.urdf_robot import URDFRobot
from assistant.trajectory.elastic_net import ElasticNetParams
from assistant.transforms import make_T
from assistant.world.model import WorldConfig, WorldModel
from assistant.world.reachability import ReachabilityConfig

#: 125 mm leaves and 62.5 mm joint steps: the world builds in about a second.
COARSE = WorldConfig(leaf=0.125, reach=ReachabilityConfig(d_step=0.0625), use_cache=False)

#: The real net with short stages (tests check behaviour, not the last millimetre).
FAST = MissionPlannerConfig(
    net_exploring=ElasticNetParams.exploring(stage1_iterations=40, stage2_iterations=20),
    net_final=ElasticNetParams.final(stage1_iterations=80, stage2_iterations=40))


def box(name: str, centre: Sequence[float], size: Sequence[float]) -> Obstacle:
    return Obstacle(name, make_T(p=np.asarray(centre, dtype=float)),
                    (CollisionShape(ShapeKind.BOX, tuple(float(v) for v in size)),))


UR5 = "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"


def ur5_with_tool() -> URDFRobot:
    """The UR5 of example-robot-data with a 100 mm straight tool, no visual meshes."""
    path, share = installed_robot_urdf(UR5)
    return URDFRobot.from_file(path, package_dirs=[share], tool_link="tool0",
                               load_visual=False).with_tool(Tool.straight(0.1))


def make_planner(robot: Robot, obstacles: Sequence, *, world: WorldConfig = COARSE,
                 roadmap: RoadmapConfig | None = None,
                 config: MissionPlannerConfig = FAST) -> MissionPlanner:
    obstacles = list(obstacles)
    checker = CollisionChecker(robot, obstacles)
    wm = WorldModel(robot, obstacles, world)
    rp = RoadmapPlanner(robot, checker, wm, roadmap)
    rp.build()
    return MissionPlanner(robot, obstacles, wm, rp, checker, config)


def sim_robot(robot: Robot, hidden: Sequence = (), start_q=None) -> SimulatedRobot:
    link = SimulatedRobot(robot, hidden_obstacles=list(hidden), clock=VirtualClock(),
                          start_q=start_q)
    link.connect()
    return link


def tcp_points(robot: Robot, Q) -> np.ndarray:
    return robot.batch_fk(np.asarray(Q, dtype=float)).positions
