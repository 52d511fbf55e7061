"""Compile the numba kernels before their first use.

The kernels (`broad_phase`, `segment_box`, `dh`, `rv2aj_fk_batch`, `rv2aj_position_ik`,
`rv2aj_pose_batch`, `kernel_helpers`, `motion_rows`, `trajectory.fit_kernels`,
`trajectory.net_forces`, `trajectory.net_kernel`, `trajectory.joint_steps`,
`roadmap.brushfire`, `roadmap.voronoi_update`, `roadmap.graph_kernel`,
`roadmap.astar_kernel`, `roadmap.search_masks`, `world.leaf_lookup`, `shape_poses`,
`face_planes`, `chain_kernel`, `capsule_phase`, `hand_kernel`)
compile on their first call and cache the result on disk;
only the first run after an install pays, ~2 minutes of one core for all of them. The CLI
runs these steps in a background process (`lazy.start`, `compile`) while the kernels run
their fallbacks; the tests call `warm_up` before anything else, so no compile happens
inside a robot link's exchange, where seconds look like a lost link.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from assistant.collision.broad_phase import (
    _segment_segment_distance,
    certify_samples,
    margin_rows,
    prune_round_pairs,
    sphere_broad_phase,
)
from assistant.collision.capsule_phase import capsule_rows, capsule_samples
from assistant.collision.clearance_scan import pruned_clearance
from assistant.collision.face_planes import vertices_beyond
from assistant.collision.motion_rows import (
    motion_marks,
    path_samples,
    rows_before_first_bad,
    rows_inside,
    valid_before_first_bad,
)
from assistant.collision.segment_box import segment_box_distance_one
from assistant.collision.shape_poses import shape_poses
from assistant.roadmap.astar_kernel import search
from assistant.roadmap.brushfire import brushfire_region
from assistant.roadmap.graph_kernel import (
    base_nodes,
    expand,
    neighbour_cells,
    neighbour_cells_into,
    neighbour_nodes,
    predecessor_cells_into,
    select_nodes,
    successor_costs,
    successors_into,
    weighted_distances,
)
from assistant.roadmap.search_masks import search_masks
from assistant.roadmap.voronoi_update import terminal_round, update_rounds
from assistant.robots.chain_kernel import chain_link_frames
from assistant.robots.dh import _chain_frames_kernel
from assistant.robots.rv2aj_fk_batch import tcp_poses
from assistant.robots.rv2aj_pose_batch import _candidates
from assistant.robots.rv2aj_position_ik import planar_position_ik
from assistant.trajectory.fit_kernels import (
    arc_distances,
    circle_through_kernel,
    fit_arc,
    fit_line,
    line_distances,
)
from assistant.trajectory.joint_steps import joint_steps
from assistant.trajectory.net_forces import propose_moves
from assistant.trajectory.net_kernel import apply_moves, check_moves
from assistant.world.hand_kernel import hand_blocked
from assistant.world.leaf_lookup import leaf_flags, leaf_indices

#: Every compiled entry point (the test checks `warm_up` compiles each of them).
KERNELS = (sphere_broad_phase, prune_round_pairs, segment_box_distance_one,
           _segment_segment_distance, _chain_frames_kernel, tcp_poses, planar_position_ik,
           fit_line, fit_arc, line_distances, arc_distances, circle_through_kernel, propose_moves,
           brushfire_region, leaf_flags, pruned_clearance, neighbour_cells,
           neighbour_nodes, certify_samples, check_moves, apply_moves, _candidates,
           update_rounds, motion_marks, rows_inside, rows_before_first_bad,
           valid_before_first_bad, expand, weighted_distances, successor_costs,
           successors_into, neighbour_cells_into, predecessor_cells_into, search,
           select_nodes, shape_poses,
           terminal_round, base_nodes, path_samples, joint_steps, margin_rows,
           search_masks, leaf_indices, vertices_beyond, chain_link_frames, capsule_rows,
           capsule_samples, hand_blocked)


def warm_up(*, reverse: bool = False) -> float:
    """Compile (or load from the cache) every kernel in this process, as plain njit: call each
    through the real API with the argument types it gets in use; returns the seconds it took.
    The tests call it; the CLI compiles in the background instead (`lazy.start`).

    `reverse` runs the steps last to first: a second process warming up at the same time
    (the tests' second worker) then compiles the other end of the list, and each loads
    from the shared cache what the other has saved - a cold cache costs about half."""
    from assistant.kernels.lazy import REGISTRY, set_pending, write_marker

    set_pending(False)
    t0 = time.perf_counter()
    for _ in warm_steps(reverse=reverse):
        pass
    with contextlib.suppress(OSError):  # an unwritable cache: the next run compiles again
        write_marker(sum(1 for d in REGISTRY.values() if d.overloads))
    return time.perf_counter() - t0


def warm_steps(*, reverse: bool = False) -> Iterator[None]:
    """`warm_up` in steps, in the order a first run needs them (the collision checker and the
    world's kernels, the roadmap's, then the trajectory's; `reverse`: last first); yields
    after each, when the kernels it compiled are in the cache (`compile` reports them)."""
    ctx = _Context.make()
    steps = (_world_checks, _motion_checks, _roads, _search, _moves, _net, _fit)
    for step in reversed(steps) if reverse else steps:
        step(ctx)
        yield


@dataclass
class _Context:
    """What the steps share: the RV-2AJ, a checker with a box at its elbow, a few points."""

    robot: Any
    checker: Any
    q: np.ndarray
    bent: np.ndarray
    arc: np.ndarray

    @staticmethod
    def make() -> _Context:
        from assistant.collision.checker import CollisionChecker
        from assistant.collision.reports import Obstacle
        from assistant.robots.model import CollisionShape, ShapeKind, Tool
        from assistant.robots.rv2aj import RV2AJ, RV2AJConfig
        from assistant.transforms import make_T

        robot = RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))
        q = np.zeros((1, robot.dof))
        elbow = robot.link_poses(q[0])[3][:3, 3]
        # a box at the elbow: the broad phase passes pairs on to the pruning and FCL
        block = Obstacle("warm-up", make_T(p=elbow),
                         (CollisionShape(ShapeKind.BOX, (0.1,) * 3),))
        # a quarter circle then a straight run: lines, arcs (free and tangent), their ends
        a = np.linspace(0.0, np.pi / 2, 12)
        arc = np.stack([0.1 * np.cos(a), 0.1 * np.sin(a), np.zeros_like(a)], axis=1)
        return _Context(robot, CollisionChecker(robot, [block]), q,
                        np.array([0.3, 0.2, 0.5, 0.3, 0.1]), arc)


def _roads_source() -> np.ndarray:
    source = np.zeros((4, 4, 4), dtype=np.int32)
    source[0, 0, 0], source[3, 3, 3] = 1, 2
    return source


def _world_checks(c: _Context) -> None:
    q, checker = c.q, c.checker
    checker.is_valid_batch(np.vstack([q, q + 0.3]))  # the plain batch (and its pruning)
    checker.min_clearance_along([q[0], q[0] + 0.3])
    tcp = c.robot.batch_fk(q).positions
    # a URDF arm's link frames (`chain_kernel`), with the types `BatchChain` passes
    chain_link_frames(np.zeros((1, 1)), np.eye(4)[None], np.eye(3)[2:], np.zeros(1, dtype=bool),
                      np.empty((1, 2, 4, 4)))
    leaf_flags(np.ascontiguousarray(tcp, dtype=float), np.full(3, -1.0), 0.0625, 32,
               np.ones(32 ** 3, dtype=bool))
    leaf_indices(np.ascontiguousarray(tcp, dtype=float), np.full(3, -1.0), 0.0625, 32)
    # a 6/7-axis arm's hand against the recorded leaves (`hand_kernel`), as `HandCells` calls it
    hand_blocked(np.tile(np.eye(4), (1, 2, 1, 1)), np.zeros(1, dtype=np.int64), np.zeros((1, 3)),
                 np.zeros((1, 3)), 0.0625, np.full(3, -1.0), 0.0625, 32,
                 np.zeros(32 ** 3, dtype=bool), np.zeros(1, dtype=bool))


def _motion_checks(c: _Context) -> None:
    q, checker = c.q, c.checker
    checker.is_valid_batch_margin(np.vstack([q, q + 0.3]))  # the net's starting margins
    checker.check_motion(q[0], q[0] + 0.3)
    checker.check_path([q[0], q[0] + 0.3], trusted=np.zeros(1, dtype=bool))
    checker.check_path([q[0], q[0] + 0.3])
    # the fast model's capsule pass (`capsule_phase`), through the fast checker's own calls
    fast = checker.fast
    two = np.vstack([q, q + 0.3])
    fast.is_valid_samples(two, np.zeros(2, dtype=np.int64), first_only=True)
    fast.is_valid_batch_margin(two)
    fast.min_clearance_along([q[0], q[0] + 0.3])
    fast.keeps_clearance([q[0], q[0] + 0.3], 0.01)
    # called per table node from Python (`pair_tables`), not only inside other kernels
    _segment_segment_distance(np.zeros(3), np.ones(3), np.zeros(3), np.ones(3))
    # the certificate's face-plane test (`certify_path`), with the types it is called with
    vertices_beyond(np.eye(4)[None], np.eye(3)[None], np.zeros((1, 3)), np.ones(3),
                    np.zeros((1, 3)), 1e-6, np.zeros(1, dtype=bool))


def _roads(c: _Context) -> None:
    from assistant.roadmap.voronoi import build_voronoi, terminal_labels, update_voronoi

    source = _roads_source()
    vmap = build_voronoi(source)
    source[0, 3, 0] = 3  # a query's terminal: the incremental update
    update_voronoi(vmap, source)
    terminal_labels(vmap, np.array([21, 42]), np.array([4, 5]))  # a query's start and goal


def _search(c: _Context) -> None:
    from assistant.roadmap.astar import lazy_astar
    from assistant.roadmap.graph import GraphBase, JointGraph
    from assistant.roadmap.path_first import lazy_path_search

    q, checker = c.q, c.checker
    cells = np.arange(8, dtype=np.int64)
    graph, _ = JointGraph.build((2, 2, 2), cells, np.arange(9), np.zeros((8, 5)),
                                np.ones(8, bool), np.zeros(8, bool), np.zeros(8), np.ones(5))
    graph.successors(0)
    GraphBase.of((2, 2, 2), cells, np.arange(9), np.zeros((8, 5)))  # the planner's graphs
    graph.distance(graph.node_q[0], graph.node_q)  # the A*'s repair of a rejected edge
    lazy_astar(graph, 0, 7, _AllFree())  # its expansion kernel
    lazy_path_search(graph, 0, 7, _AllFree())  # the compiled search
    # the roadmap's batched edge check (`edge_check.EdgeCheck`): its samples' validity
    checker.is_valid_samples(np.vstack([q, q + 0.3]), first_only=True)
    # a query's searchable cells (`planner`): labels, free / offering / CAD leaves
    source = _roads_source()
    source[0, 3, 0] = 3
    flags, cad = np.ones(4 ** 3, dtype=bool), np.ones(4 ** 3, dtype=bool)
    cad.setflags(write=False)  # as `WorldModel.cad_leaves` hands it out
    search_masks(source.reshape(-1), -1, 4, 5, flags, flags, cad, 4, 0, 63, 2)


def _moves(c: _Context) -> None:
    from assistant.trajectory.assemble import joint_interpolation
    from assistant.trajectory.cartesian_follow import follow_poses, slerp_rotations

    robot, q, bent = c.robot, c.q, c.bent
    tcp = robot.batch_fk(q).positions
    joint_interpolation(robot, q[0], q[0] + 0.3, 0.01)  # the assembly's joint moves
    robot.batch_position_ik(tcp + 0.001, q, q)
    # `bent` is off the J1 axis: the batch answers
    follow_poses(robot, np.stack([robot.fk(bent), robot.fk(bent + 0.01)]), bent)
    slerp_rotations(robot.fk(bent)[:3, :3], robot.fk(bent + 0.01)[:3, :3], np.linspace(0, 1, 3))


def _net(c: _Context) -> None:
    from assistant.trajectory.elastic_net import ElasticNetParams, run_elastic_net

    # a short net on the RV-2AJ: its compiled move test (`net_kernel`), and the kernel that
    # applies the moves FCL clears, called from Python with no rows
    short = ElasticNetParams.final(stage1_iterations=2, stage2_iterations=1)
    res = run_elastic_net(c.robot, np.stack([c.bent, c.bent + 0.05]), validity=c.checker,
                          params=short)
    P, Q = res.particles.points.copy(), res.particles.joints.copy()
    none = np.zeros(0, dtype=np.int64)
    apply_moves(P, Q, none, np.zeros(0, dtype=bool), Q[:0], P[:0], np.zeros(0), np.zeros(0),
                Q.copy(), np.zeros(len(Q)), np.zeros(len(Q)))
    net = ElasticNetParams.final()
    for stage in (1, 2):
        propose_moves(c.arc, stage, 0.5, net.c_equidistance, net.c_rotation, net.c_shrink,
                      net.c_line_shrink, net.stage1_shrink, net.r_max, net.r_min, net.max_move)


def _fit(c: _Context) -> None:
    from assistant.trajectory.fit_growth import fit_primitives
    from assistant.trajectory.primitives import (
        ArcPrimitive,
        FitParams,
        primitive_poses,
    )

    arc = c.arc
    run = arc[-1] + np.outer(np.linspace(0.02, 0.2, 10), [-1.0, 0.0, 0.0])
    fit = fit_primitives(np.vstack([arc, run]), FitParams(tolerance=0.001))
    for prim in fit.primitives:
        prim.distance(arc)
        primitive_poses(prim, 0.01, np.eye(3), c.robot.fk(c.bent)[:3, :3])  # a move's poses
    ArcPrimitive.through(arc[0], arc[5], arc[-1])


class _AllFree:
    """An edge checker that finds every edge free (the warm-up's search)."""

    def first_invalid_fraction(self, q0: np.ndarray, q1: np.ndarray) -> float | None:
        return None
