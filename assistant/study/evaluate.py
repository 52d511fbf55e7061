"""The full evaluation of one candidate (seconds): the world model and roadmap for the cell as
seen from the candidate's base, then the mission planned and verified by `MissionPlanner`
exactly as the Session plans it.

What depends on the candidate is built here: the obstacles' leaves and the valid joint
positions per leaf (FCL on every link against the obstacles *relative to the base*), the
roads, the checker. What does not - the robot and its joint-position store (the thesis'
joint grid, or the sampled store of a 6/7-axis arm) with its inverse index - is `Shared`,
built once per process (by the parent before the local workers fork, once per Ray worker) and
only read here.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.mission.model import ResolvedMission
from assistant.progress import Progress
from assistant.robots.model import Robot
from assistant.study.scoring import Scoring

Array = np.ndarray


@dataclass
class Shared:
    """Read-only per-process data: the robot, the world config, the joint-position store."""

    robot: Robot
    world_config: Any
    store: Any

    @staticmethod
    def build(robot: Robot, world_config: Any = None, progress: Progress | None = None,
              ) -> Shared:
        from assistant.world.model import WorldConfig
        from assistant.world.reachability import load_or_build

        config = world_config or WorldConfig.for_robot(robot)
        store = load_or_build(robot, config.grid(), config.reach, progress,
                              cache=config.cache, use_cache=config.use_cache)
        store.index_of_ids(np.zeros(0, dtype=np.int64))  # the inverse map, built once here
        return Shared(robot, config, store)


@dataclass
class PlanOutcome:
    """What planning the mission at one candidate gave."""

    ok: bool
    reason: str
    tcp_length: float = 0.0
    joint_length: float = 0.0
    min_clearance: float | None = None
    cycle: float = 0.0
    build_seconds: float = 0.0
    plan_seconds: float = 0.0


def plan_candidate(shared: Shared, obstacles: list, mission: ResolvedMission, T_world_base: Array,
                   q_seed: Array, anchors: list[Array], planner_config: Any, scoring: Scoring,
                   progress: Progress | None = None) -> PlanOutcome:
    """World model + roadmap + mission plan at one candidate (obstacles in its base frame)."""
    from assistant.planning.mission_planner import MissionPlanner
    from assistant.roadmap.planner import RoadmapPlanner
    from assistant.world.model import WorldModel

    progress = progress or Progress("plan a candidate")
    robot = shared.robot
    t0 = time.perf_counter()
    world = WorldModel(robot, obstacles, shared.world_config, store=shared.store)
    world.anchors = np.array([np.asarray(q_seed, float)] + [np.asarray(q, float)
                                                              for q in anchors])
    checker = CollisionChecker(robot, obstacles)
    roadmap = RoadmapPlanner(robot, checker, world)
    roadmap.build(progress.sub(0.0, 0.6, "world model"))
    t1 = time.perf_counter()
    planner = MissionPlanner(robot, obstacles, world, roadmap, checker, planner_config)
    plan = planner.plan_mission(mission, T_world_base, q_seed, progress.sub(0.6, 1.0, "plan"))
    t2 = time.perf_counter()
    rep = plan.report
    if not plan.ok:
        where = rep.failed_piece or "mission"
        kind = next((p.kind for p in rep.pieces if p.label == where and not p.ok), "")
        what = f"transfer {where} not plannable" if kind == "transfer" else \
            f"{where} not plannable"
        return PlanOutcome(False, f"{what}: {rep.reason}", build_seconds=t1 - t0,
                           plan_seconds=t2 - t1)
    cycle = scoring.cycle(robot, plan.trajectory, rep.tcp_length)
    return PlanOutcome(True, "", float(rep.tcp_length), float(rep.joint_length),
                       None if rep.min_clearance is None else float(rep.min_clearance),
                       cycle, t1 - t0, t2 - t1)
