"""A goal the old rule made unreachable is named, not lost (issue 56), on a real UR5 with a
sampled world, real FCL and the simulated robot on a virtual clock.

A box hidden just before the goal on the transfer: the arm meets it close to the goal. The
old rule (the stopped posture's box of postures) then holds the goal posture too, and the
run ends "goal inside an obstacle" without a word of which indication. The new rule learns
only the swept region, never where the goal has the arm; met again at the same place the
region holds the goal's surroundings and the run names that indication in mm, which the
operator may forget - then the goal is free again."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from planning_fixtures import box as _box
from planning_fixtures import ur5_with_tool

from assistant.collision.checker import CollisionChecker
from assistant.links.simulated import SimulatedRobot
from assistant.links.timing import VirtualClock
from assistant.planning import MissionPlanner
from assistant.planning.config import ExecutionConfig
from assistant.planning.execution import EndReason, MissionExecutor, _Item, _Phase
from assistant.progress import Progress
from assistant.roadmap.planner import RoadmapPlanner
from assistant.world.model import WorldConfig, WorldModel
from assistant.world.reachability import ReachabilityConfig

Q_S = np.radians([-40.0, -100.0, 100.0, -90.0, -90.0, 0.0])
Q_G = np.radians([40.0, -100.0, 100.0, -90.0, -90.0, 0.0])



@pytest.fixture(scope="module")
def cell():
    ur5 = ur5_with_tool()
    obstacles = [_box("table", (0.2, 0.0, -0.011), (1.2, 1.2, 0.02))]
    cfg = WorldConfig.for_robot(ur5, reach=ReachabilityConfig(samples=1 << 15,
                                                              focus_samples=1 << 15),
                                use_cache=False)
    world = WorldModel(ur5, obstacles, cfg)
    world.anchors = np.array([Q_S, Q_G])
    checker = CollisionChecker(ur5, obstacles)
    roadmap = RoadmapPlanner(ur5, checker, world)
    roadmap.build()
    planner = MissionPlanner(ur5, obstacles, world, roadmap, checker)
    first = planner.plan_transfer(Q_S, Q_G, exploring=True, label="A -> B")
    assert first.ok and first.piece is not None
    D = first.piece.dense()
    hidden = _box("hidden", ur5.fk(D[int(0.95 * (len(D) - 1))])[:3, 3], (0.05,) * 3)
    return ur5, planner, first.piece, hidden


def drive(planner, robot, piece, hidden):
    """The transfer driven with re-planning (the executor's loop on this one piece)."""
    link = SimulatedRobot(robot, hidden_obstacles=[hidden], clock=VirtualClock(),
                          start_q=Q_S)
    link.connect()
    ex = MissionExecutor(planner, link, ExecutionConfig(plan_final=False))
    ex._queue, ex._index, ex._phase = [_Item(piece, True, ex._world_version())], 0, \
        _Phase.EXPLORE
    ex._progress = Progress("drive")

    def body():
        ex._drive_queue(final=False)
        ex.report.end, ex.report.reason = EndReason.COMPLETED, "goal reached"

    rep = ex._ended(body, "end")
    ex.detach()
    return rep, link


def test_a_goal_the_old_rule_lost_is_named_and_freed_by_forgetting(cell):
    robot, planner, piece, hidden = cell
    world = planner.world
    indication = world.config.indication
    # the old rule: the postures around the stop hold the goal; no indication is named
    world.config = replace(world.config, indication=replace(indication, learn_regions=False))
    try:
        rep, _ = drive(planner, robot, piece, hidden)
    finally:
        world.config = replace(world.config, indication=indication)
    assert rep.end == EndReason.NO_PATH, rep.describe()
    assert "goal inside an obstacle" in rep.reason and "forget" not in rep.reason
    assert world.near_recorded_collision(Q_G[None])[0]
    while world.collisions:  # forgotten: the postures and leaves are given back
        planner.roadmap.forget_collision(0)
    assert not world.near_recorded_collision(Q_G[None])[0]
    # the new rule: reached, or the run names the indication that holds the goal
    world.config = replace(world.config, indication=replace(indication, learn_regions=True))
    try:
        rep, link = drive(planner, robot, piece, hidden)
    finally:
        world.config = replace(world.config, indication=indication)
    learnt = [rc for rc in world.collisions if rc.region is not None]
    assert learnt and len(learnt) == len(world.collisions)
    if rep.end == EndReason.COMPLETED:
        assert np.allclose(link.current_joints(), Q_G, atol=1e-6)
        return
    assert rep.end == EndReason.NO_PATH, rep.describe()
    assert "indication 1 (a region of" in rep.reason and " mm from the arm there" in rep.reason
    assert "forget indication 1" in rep.reason
    assert world.near_recorded_collision(Q_G[None])[0]
    planner.roadmap.forget_collision(0)
    assert not world.collisions and not world.near_recorded_collision(Q_G[None])[0]


def test_stopped_again_where_nothing_could_be_learnt_ends_the_run_with_a_reason(cell):
    """The same stop twice, while what was learnt still lets the arm stand there (all of it
    withheld next to a protected posture), ends the run at once with a sentence naming
    what the operator can change - not 20 contacts at the same place until the budget."""
    from assistant.planning.execution import _End

    robot, planner, piece, _ = cell
    link = SimulatedRobot(robot, clock=VirtualClock(), start_q=Q_S)
    link.connect()
    ex = MissionExecutor(planner, link, ExecutionConfig(plan_final=False))
    try:
        q = piece.dense()[len(piece.dense()) // 2]
        assert not planner.world.near_recorded_collision(q[None])[0]
        ex._same_stop_again(q, piece)  # the first stop there: the run goes on
        ex._same_stop_again(q + 0.01, piece)  # elsewhere (0.01 rad): goes on
        with pytest.raises(_End) as end:
            ex._same_stop_again(q + 1e-4, piece)  # the same stop (a reading apart)
        assert end.value.reason == EndReason.NO_PATH
        assert "stopped again at the same posture" in end.value.message
        # where the record keeps the arm away, a stop there again is left to the re-plan
        world = planner.world
        world.indicate_collision(q)
        try:
            assert world.near_recorded_collision(q[None])[0]
            ex._same_stop_again(q, piece)
        finally:
            planner.roadmap.forget_collision(len(world.collisions) - 1)
    finally:
        ex.detach()


def test_positions_next_to_a_learnt_region_are_dead_before_the_search(cell):
    """After a region is learnt the search leaves out, before it starts, the positions
    next to it (`RoadmapPlanner._known_dead`): each one it marks is next to the record, and
    none is missed among those whose TCP leaf is near the region; the start and goal are
    never marked."""
    from types import SimpleNamespace

    from assistant.roadmap.edge_check import DEAD_REACH

    robot, planner, piece, hidden = cell
    world, roadmap = planner.world, planner.roadmap
    rep, _ = drive(planner, robot, piece, hidden)
    try:
        regions = [rc.region for rc in world.collisions if rc.region is not None
                   and len(rc.region.centres)]
        assert regions, rep.describe()
        base = roadmap._graph_base()
        n = int(base.cell_start[-1])
        graph = SimpleNamespace(node_q=base.node_q[:n + 2], n_nodes=n + 2)
        roadmap._edge.exempt = frozenset()
        dead = roadmap._known_dead(graph, base, (n, n + 1))
        assert dead is not None and not dead[n:].any()
        near = world.near_recorded_collision(base.node_q[:n])
        assert dead[:n].any() and not (dead[:n] & ~near).any()
        # the cut only leaves out positions whose TCP is far from every region
        C = np.concatenate([r.centres for r in regions])
        tcp = robot.batch_fk(base.node_q[:n][near & ~dead[:n]]).positions
        if len(tcp):  # a TCP leaf outside the box of centres +- (reach + half a diagonal)
            far = np.linalg.norm(tcp[:, None] - C[None], axis=2).min(axis=1)
            assert far.min() > DEAD_REACH - world.grid.leaf, far.min()
        memo = roadmap._dead  # the next query in the same world state poses nothing again
        again = roadmap._known_dead(graph, base, (n, n + 1))
        assert roadmap._dead is memo and np.array_equal(again, dead)
    finally:
        while world.collisions:
            roadmap.forget_collision(0)
