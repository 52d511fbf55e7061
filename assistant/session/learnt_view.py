"""What the page draws of an obstacle learnt from collision indications.

The world model learns in octree leaves (62.5 mm on the thesis cell) and every leaf it marks
holds the arm's own hand at the indicated posture: drawn as whole leaves, the learnt solid
sits over the arm. What a contact implies is only the part of those leaves outside the arm:
each leaf is cut into sub-cells and the sub-cells the arm's links occupy in the posture it
stands in, or occupied at an indicated contact (it touched there, it did not go in), are left
out (real FCL, the arm's collision geometry against each sub-cell box). Only what is drawn
changes; the world model keeps its leaves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, Robot, ShapeKind
from assistant.session.types import OccupiedCells
from assistant.transforms import make_T

Array = np.ndarray

#: Sub-cells per leaf edge: 4 turns a 62.5 mm leaf into 15.6 mm cubes (64 a leaf).
SPLIT = 4


@dataclass(frozen=True)
class LearntView:
    """Cubes to draw (world frame), their edge, the lattice's axes in the world, and how many
    of the leaves' sub-cells were left out because the arm stands in them."""

    centres: Array
    edge: float
    R_world_grid: Array
    under_arm: int


def learnt_view(cells: OccupiedCells, robot: Robot, postures: Array, T_world_base: Array,
                split: int = SPLIT) -> LearntView:
    """The learnt leaves `cells` cut into `split`^3 sub-cells, without those the arm's links
    touch at any of the joint rows `postures` (K, dof) (the robot's base at
    `T_world_base`)."""
    R = np.asarray(cells.R_world_grid, dtype=float)
    edge = cells.leaf / split
    k = (np.arange(split) + 0.5) / split - 0.5  # sub-cell centres in leaf units
    offsets = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)
    centres = (np.asarray(cells.centres, dtype=float)[:, None, :]
               + (offsets * cells.leaf) @ R.T).reshape(-1, 3)
    if not len(centres):
        return LearntView(centres, edge, R, 0)
    T_base_world = np.linalg.inv(np.asarray(T_world_base, dtype=float))
    in_base = centres @ T_base_world[:3, :3].T + T_base_world[:3, 3]
    R_base_grid = T_base_world[:3, :3] @ R
    box = (CollisionShape(ShapeKind.BOX, (edge, edge, edge)),)
    subs = [Obstacle(f"sub{i}", make_T(R_base_grid, p), box) for i, p in enumerate(in_base)]
    checker = CollisionChecker(robot, subs)
    touched = {c.other for q in np.atleast_2d(np.asarray(postures, dtype=float))
               for c in checker.check(q).contacts if not c.self_collision}
    keep = np.array([f"sub{i}" not in touched for i in range(len(subs))])
    return LearntView(centres[keep], edge, R, int((~keep).sum()))
