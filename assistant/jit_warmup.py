"""Compile the numba kernels before their first use.

The kernels (`broad_phase`, `segment_box`, `dh`, `rv2aj_fk_batch`, `rv2aj_position_ik`)
compile on their first call and cache the result on disk; only the first run after an
install pays, ~10 s for all of them on this 2-core machine. `cellteach serve` runs
`warm_up` in a background thread at start, so that first run does not stall the operator's
first world build or plan (a compile reports no progress); `cellteach run` and the tests
call it before anything else, so no compile happens inside a robot link's exchange, where
seconds look like a lost link.
"""

from __future__ import annotations

import time

import numpy as np

from assistant.broad_phase import (
    _segment_segment_distance,
    prune_round_pairs,
    sphere_broad_phase,
)
from assistant.dh import _chain_frames_kernel
from assistant.rv2aj_fk_batch import tcp_poses
from assistant.rv2aj_position_ik import planar_position_ik
from assistant.segment_box import _segment_box_distances, segment_box_distance_one

#: Every compiled entry point (the test checks `warm_up` compiles each of them).
KERNELS = (sphere_broad_phase, prune_round_pairs, segment_box_distance_one,
           _segment_box_distances, _segment_segment_distance, _chain_frames_kernel, tcp_poses,
           planar_position_ik)


def warm_up() -> float:
    """Call each kernel through the real API, with the argument types it gets in use;
    returns the seconds it took (compiling or loading the cache)."""
    from assistant.collision import CollisionChecker, Obstacle
    from assistant.robot_model import CollisionShape, ShapeKind, Tool
    from assistant.rv2aj import RV2AJ, RV2AJConfig
    from assistant.transforms import make_T

    t0 = time.perf_counter()
    robot = RV2AJ(RV2AJConfig(tool=Tool.straight(0.1)))
    q = np.zeros((1, robot.dof))
    elbow = robot.link_poses(q[0])[3][:3, 3]
    # a box at the elbow: the broad phase passes pairs on to the pruning and FCL
    block = Obstacle("warm-up", make_T(p=elbow), (CollisionShape(ShapeKind.BOX, (0.1,) * 3),))
    checker = CollisionChecker(robot, [block])
    checker.is_valid_batch_margin(np.vstack([q, q + 0.3]))
    checker.min_clearance_along([q[0], q[0] + 0.3])
    tcp = robot.batch_fk(q).positions
    robot.batch_position_ik(tcp + 0.001, q, q)
    return time.perf_counter() - t0
