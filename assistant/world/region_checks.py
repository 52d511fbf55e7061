"""Checks of arm postures and motions against the regions learnt from indications.

Why a module: every planner asks the world "is this posture near a recorded collision?"
(`WorldModel.near_recorded_collision`); for an indication that taught a region
(`contact_region`) the answer is whether the arm comes within the clearance of that
region's spheres - the arm as the capsules that contain its links (`region_kernel`), the
same model the region was learnt with.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from assistant.robots.model import Robot
from assistant.world.contact_region import ContactRegion
from assistant.world.region_kernel import CapsuleArm, rows_near

Array = np.ndarray


def indication_name(i: int) -> str:
    """The operator's name of recorded collision i (0-based): numbered from 1."""
    return f"indication {i + 1}"


class RegionChecks:
    """Postures vs learnt regions (`ContactRegion`), for one robot and clearance."""

    def __init__(self, robot: Robot, clearance: float):
        self.robot = robot
        self.clearance = float(clearance)
        self.weights = np.asarray(robot.arm_radii(), dtype=float)
        self._arm: CapsuleArm | None = None

    @property
    def arm(self) -> CapsuleArm:
        if self._arm is None:
            self._arm = CapsuleArm(self.robot)
        return self._arm

    def blocked(self, Q: Array, regions: Sequence[tuple[int, ContactRegion]]) -> Array:
        """Bool per row of Q: the arm comes within the clearance of one of the regions."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        out = np.zeros(len(Q), dtype=bool)
        if not regions or not len(Q):
            return out
        A, B = self.arm.segments(Q)
        for _, r in regions:
            todo = ~out
            if not todo.any():
                break
            out[todo] = rows_near(np.ascontiguousarray(A[todo]), np.ascontiguousarray(B[todo]),
                                  self.arm.radii, np.ascontiguousarray(r.centres),
                                  r.radius + self.clearance)
        return out

    def meeting(self, q: Array, regions: Sequence[tuple[int, ContactRegion]]) -> set[int]:
        """Indices of the regions the arm at q comes within the clearance of."""
        q = np.asarray(q, dtype=float)[None]
        return {i for i, r in regions
                if self.arm.near_rows(q, r.centres, r.radius + self.clearance)[0]}

    def motion_meets(self, a: Array, b: Array,
                     regions: Sequence[tuple[int, ContactRegion]]) -> bool:
        """Whether the straight joint move a -> b meets a region: its postures are checked
        at most the clearance of arm travel apart (`weights`: the arm's radii), so between
        two of them no point of the arm moves farther than the regions' margin - a posture
        between that touches a region has a checked one within the margin of it."""
        if not regions:
            return False
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        n = max(1, int(np.ceil(float(np.abs(b - a) @ self.weights) / self.clearance)))
        f = np.arange(n + 1) / n
        return bool(self.blocked(a + f[:, None] * (b - a), regions).any())

    def distance(self, q: Array, region: ContactRegion) -> float:
        """Distance (m) from the arm's capsules at q to the region's spheres (0: touching)."""
        A, B = self.arm.segments(np.asarray(q, dtype=float)[None])
        A, B = A[0][:, None, :], B[0][:, None, :]  # (C, 1, 3)
        P = region.centres[None, :, :]  # (1, M, 3)
        u = B - A
        uu = np.maximum((u * u).sum(axis=2), 1e-18)
        t = np.clip(((P - A) * u).sum(axis=2) / uu, 0.0, 1.0)
        d = np.linalg.norm(P - (A + t[..., None] * u), axis=2)
        gap = d - self.arm.radii[:, None] - region.radius
        return float(max(0.0, gap.min()))
