"""Certification of a planned transfer by the exact check alone, and the repair when it refuses.

Why: on a mesh arm (URDF) the search, the joint-move scoring and even the verifier's own
checks ask the fast conservative model first (`collision.fast_checker`): what it calls free
is taken as free. Its tests prove it conservative on every shipped arm, but a transfer the
arm will drive must not rest on that proof alone. So the finished transfer's dense path is
checked once more on `CollisionChecker.exact_only` - the checker's broad phase and FCL on
the robot's own kinematics, never the fast model, by FCL distances pair by pair
(`collision.certify_path`: 2-10 ms a UR transfer) - and if that refuses, the transfer is
planned again with every check exact (`all_exact`), and that plan is certified in turn.

Only CAD is certified here: the recorded collision postures and hand leaves do not depend
on the fast model, and the verification of each form already checked them.

May import: collision, planning's own modules, roadmap.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

import numpy as np

from assistant.collision.certify_path import first_contact
from assistant.mission.motion import Trajectory
from assistant.planning.known_world import KnownVerifier

if TYPE_CHECKING:
    from assistant.planning.mission_planner import MissionPlanner

Array = np.ndarray


def needs_certificate(planner: MissionPlanner) -> bool:
    """Whether the planner's checks ask a fast model (mesh arms): otherwise its verification
    was exact already."""
    return planner.checker.exact_only() is not planner.checker


def certificate_refusal(planner: MissionPlanner, traj: Trajectory) -> str:
    """Why the exact check refuses the trajectory's dense path ("" if it passes)."""
    dense = np.asarray(traj.dense_joint_path(), dtype=float)
    if len(dense) < 2:
        return ""
    exact = planner.checker.exact_only()
    k = first_contact(exact, dense)
    if k is None:
        return ""
    S, F, _ = exact._path_samples(dense, None)
    q = dense[S[k]] + F[k] * (dense[min(S[k] + 1, len(dense) - 1)] - dense[S[k]])
    return (f"the exact check refuses the path at {k / max(1, len(S) - 1):.0%} of it: "
            f"{exact.check(q).describe()}")


@contextmanager
def all_exact(planner: MissionPlanner) -> Iterator[None]:
    """Every check of the planner and its roadmap on the exact view of its checker
    (`CollisionChecker.exact_only`) while the block runs: the repair of a refused
    certificate. Restored afterwards."""
    from assistant.roadmap.edge_check import EdgeCheck

    exact = planner.checker.exact_only()
    rm = planner.roadmap
    kept = (planner.checker, planner.verifier, planner.screen, planner.app_verifier,
            rm.checker, rm._edge, rm._exact_edge, rm._fast_edge)
    world = planner.world
    planner.checker = exact
    planner.verifier = planner.screen = KnownVerifier(exact, world)
    planner.app_verifier = KnownVerifier(exact, world, hand=False)
    rm.checker = exact
    rm._exact_edge = rm._edge = EdgeCheck(exact, world)
    rm._fast_edge = None
    try:
        yield
    finally:
        (planner.checker, planner.verifier, planner.screen, planner.app_verifier,
         rm.checker, rm._edge, rm._exact_edge, rm._fast_edge) = kept
