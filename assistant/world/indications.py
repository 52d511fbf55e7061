"""Operator collision indications: a posture where the arm touched something becomes evidence.

The operator is the collision sensor (SPEC §1). Where the contact was is unknown - somewhere on
the arm at posture q - so an indication gives two kinds of evidence:

* Cells: the leaves the arm's moving links occupy at q (points sampled along each collision
  shape's axis, at most half a leaf apart, plus the TCP) receive an occupancy observation
  from the "button" source. The thesis stored the posture only in the TCP cell; marking the
  arm's cells as well keeps the TCP roads out of the region where the arm was stopped.
  Links before `first_link` (base, turret) are skipped: they never move into anything.
* Postures: table joint positions within `joint_steps` grid steps of q in every joint (the
  grid cell around the stopped posture, widened; fixed table joints such as J6 are ignored)
  become invalid, and the planner rejects edges that pass through that box.

On 6- and 7-axis arms, when the executor knows how the arm came to the stop, an indication
teaches the swept region of the last check step instead (`contact_region`): no leaves, no box.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from assistant.robots.model import Robot, ShapeKind
from assistant.world.contact_region import RegionConfig
from assistant.world.leaf_store import JointStore
from assistant.world.octree import OctreeGrid

Array = np.ndarray


@dataclass(frozen=True)
class IndicationConfig:
    """Defaults are ours (the thesis gives no figures)."""

    #: First link index whose cells are marked (0 base, 1 turret, 2 upper arm, ...).
    first_link: int = 2
    #: Observation value of the marked cells.
    value: float = 1.0
    #: Half-width, in table grid steps per joint, of the box of postures around the stopped
    #: one that become invalid (1 = the grid cell around q; 1.5 also takes the next ring
    #: where it is close).
    joint_steps: float = 1.5
    #: 6- and 7-axis arms with the approach known: the region learnt instead of the box.
    #: The box blocks other postures that reach the same place without touching anything
    #: and, near a goal, the goal itself: on the hidden-obstacle benchmark's UR3 cells 1
    #: of 5 reached the goal with the box, 5 of 5 with the region (docs/benchmarks.md).
    learn_regions: bool = True
    region: RegionConfig = field(default_factory=RegionConfig)


def arm_points(robot: Robot, q: Array, first_link: int, spacing: float) -> Array:
    """Points (base frame) on the links' collision shapes at q: along capsule/cylinder axes
    every <= `spacing`, sphere/box/mesh centres and box corners, plus the TCP."""
    frames = robot.link_poses(np.asarray(q, dtype=float))
    pts = [robot.fk(q)[:3, 3][None]]
    for k in range(first_link, len(robot.links)):
        F = frames[k]
        for s in robot.links[k].collision:
            T = F @ s.T_link_shape
            if s.kind in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
                h = s.size[1] / 2.0
                n = max(2, int(np.ceil(2 * h / spacing)) + 1)
                local = np.zeros((n, 3))
                local[:, 2] = np.linspace(-h, h, n)
            elif s.kind == ShapeKind.BOX:
                e = np.asarray(s.size) / 2.0
                local = np.array([[0.0, 0.0, 0.0]] + [[x, y, z] for x in (-e[0], e[0])
                                                      for y in (-e[1], e[1])
                                                      for z in (-e[2], e[2])])
            elif s.kind == ShapeKind.MESH and s.mesh is not None:
                local = np.asarray(s.mesh.vertices, dtype=float)
            else:
                local = np.zeros((1, 3))
            pts.append(local @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(pts)


def indicated_cells(robot: Robot, grid: OctreeGrid, q: Array,
                    config: IndicationConfig) -> Array:
    """Flat ids (unique) of the leaves the arm occupies at q, inside the octree."""
    flat = grid.flat_of_points(arm_points(robot, q, config.first_link, grid.leaf / 2.0))
    return np.unique(flat[flat >= 0])


def posture_box_half(table: JointStore, joint_steps: float) -> Array:
    """Half-widths (dof,) of a recorded collision's posture box: `joint_steps` grid steps in
    every varying table joint, inf in the joints the table does not vary."""
    varying = table.counts > 1
    half = np.full(len(varying), np.inf)
    half[varying] = joint_steps * table.step[varying] + 1e-12
    return half


def near_posture(table: JointStore, Q: Array, q: Array, joint_steps: float) -> Array:
    """Bool per row of Q: within `joint_steps` grid steps of q in every varying table joint."""
    d = np.abs(np.atleast_2d(np.asarray(Q)) - np.asarray(q))
    return np.all(d <= posture_box_half(table, joint_steps), axis=1)


def nearby_positions(table: JointStore, q: Array, joint_steps: float) -> Array:
    """Indices into `table.positions` of the positions near q (`near_posture`): the grid
    points in the box around q, looked up directly (no leaf scan)."""
    idx = table.index_of_ids(table.ids_in_box(np.asarray(q, dtype=float), joint_steps))
    return np.unique(idx[idx >= 0])
