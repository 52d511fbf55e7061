"""What a collision indication teaches on a 6- or 7-axis arm: a small region where the contact is.

Why: the arm was free at the start of its last check step and touched something by its end,
so the contact lies in the space its links moved *into* during that step - the volume swept by
the leading surfaces of the links that moved, minus the space the arm itself filled at the
step's start. Learning that volume, and nothing else, keeps the evidence as small as it is:
not the whole hand's surroundings, not the coarse leaf the TCP was in, not a box of postures
(which on a 6- or 7-axis arm blocks other postures that reach the same place without touching
anything, and can make a goal unreachable). The re-plan keeps `clearance` from the region.

The region is a set of spheres (centres every `resolution` along the swept surfaces, radius
`resolution`), checked against the arm's capsules (`region_kernel`), the model it was learnt
with. Two rules keep it honest:

* It never holds the arm at the start of the last step (the arm was there, and the retreat
  goes back there), nor a protected posture - a goal, a taught location, a posture of a
  path the operator defined: those parts are cut out of the region, and the cut is reported
  (an inference never makes what the operator defined unreachable).
* Indicated again at the same place (a new region within `repeat_distance` of a learnt one),
  the learnt region grows: the union of both, each sphere `grow` larger per repeat - the
  obstacle is bigger than one step's sliver showed. Only at the `hold_after`-th indication
  there does it hold what it was cut for, and the run names it to be forgotten.

Used when `IndicationConfig.learn_regions` is on (the default).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from assistant.robots.model import Robot
from assistant.world.hand_cells import _shape_points
from assistant.world.region_kernel import CapsuleArm

Array = np.ndarray


@dataclass(frozen=True)
class RegionConfig:
    """Ours; lengths in metres."""

    #: The last check step: back from the stop along the executed path until some point of
    #: the arm moved this much (it must exceed the spheres' radius plus the clearance: what
    #: lies within those of the arm at the step's start is not new space).
    step: float = 0.04
    #: A point of the arm that moved less than this in the step did not move into new space.
    min_move: float = 0.004
    #: Spacing of the region's sphere centres, and their radius (covers the gaps between).
    resolution: float = 0.01
    #: What the re-plan keeps from the region (the spheres' collision margin).
    clearance: float = 0.005
    #: A new region whose centres come this close to a learnt one is the same place.
    repeat_distance: float = 0.03
    #: Growth of every sphere per repeat at the same place.
    grow: float = 0.015
    #: Postures sampled along the step (its start excluded).
    sweep_samples: int = 4
    #: The indication at the same place that lets the region hold what it was cut for (a
    #: goal, a taught location): the third. On the second the arm often met the obstacle
    #: from another side on the new way and the goal is still free (the UR5 and UR3 cells
    #: of `benchmarks/hidden_obstacles.py`); a third says the place is really blocked, and
    #: the run names the indication to forget instead of meeting it again and again.
    hold_after: int = 3
    #: At most this many vertices per mesh shape.
    mesh_points: int = 400


@dataclass
class ContactRegion:
    """Sphere centres (robot base frame, m) and one radius; `hits`: times indicated here."""

    centres: Array
    radius: float
    hits: int = 1
    #: Protected postures (their labels) whose arm the learnt spheres would have touched.
    cut_for: list[str] = field(default_factory=list)
    #: The spheres cut for them: not learnt, but remembered - indicated at the same place
    #: `RegionConfig.hold_after` times, the region holds them too and names what it then
    #: blocks (`grown` with `promote`).
    withheld: Array = field(default_factory=lambda: np.zeros((0, 3)))

    def everything(self) -> Array:
        """Learnt and withheld centres."""
        return np.concatenate([self.centres, self.withheld])

    def distance_to(self, other: ContactRegion) -> float:
        """Smallest distance between the two regions' sphere centres (withheld ones too)."""
        a, b = self.everything(), other.everything()
        d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
        return float(d.min()) if d.size else np.inf


def step_start(robot: Robot, approach: Array, local: Array, link: Array, step: float,
               weights: Array) -> int:
    """Index into `approach` (postures ending at the stop) of the last check step's start:
    the latest posture from which some point of the arm moved at least `step` to the stop
    (0 if none did). The arm travel (sum of arm radius x joint change) bounds every point's
    move, so only postures at least that far are posed."""
    Q = np.atleast_2d(np.asarray(approach, dtype=float))
    travel = np.abs(Q - Q[-1]) @ np.asarray(weights, dtype=float)
    cand = np.flatnonzero(travel >= step)[::-1]
    end = _posed(robot, Q[-1][None], local, link)[0]
    for k in range(0, len(cand), 16):
        rows = cand[k:k + 16]
        P = _posed(robot, Q[rows], local, link)
        moved = np.linalg.norm(P - end[None], axis=2).max(axis=1)
        far = np.flatnonzero(moved >= step)
        if len(far):
            return int(rows[far[0]])
    return 0


def _local_points(robot: Robot, first_link: int, spacing: float, mesh_points: int,
                  ) -> tuple[Array, Array]:
    pts, link = [], []
    for k in range(first_link, len(robot.links)):
        for s in robot.links[k].collision:
            P = _shape_points(s, spacing, mesh_points)
            pts.append(P)
            link.append(np.full(len(P), k))
    if not pts:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    return np.concatenate(pts), np.concatenate(link)


def _posed(robot: Robot, Q: Array, local: Array, link: Array) -> Array:
    """Points (N, M, 3) of the arm at each row of Q."""
    poses = robot.batch_link_poses(np.atleast_2d(Q))[:, link]
    return np.einsum("nmij,mj->nmi", poses[:, :, :3, :3], local) + poses[:, :, :3, 3]


def _thin(P: Array, resolution: float) -> Array:
    """One point per cube of edge `resolution` (the first of each)."""
    if not len(P):
        return P
    keys = np.floor(P / resolution).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return P[np.sort(first)]


def touching(arm: CapsuleArm, centres: Array, radius: float, clearance: float, Q: Array,
             ) -> Array:
    """Bool per sphere: within `clearance` of the arm (its capsules) at some row of Q."""
    return arm.near_centres(np.atleast_2d(np.asarray(Q, dtype=float)), centres,
                            radius + clearance)


def learn_region(robot: Robot, arm: CapsuleArm, approach: Array, weights: Array,
                 first_link: int, config: RegionConfig,
                 protected: Sequence[tuple[str, Array]] = (),
                 ) -> tuple[ContactRegion | None, Array]:
    """The region an indication at `approach[-1]` teaches (module docstring), and the
    posture the last step started from. A step that swept too little to hold the arm at the
    stop is taken twice as long (up to three times); None when nothing moved into new
    space; no spheres left when all of them touch protected postures (`cut_for` says
    which)."""
    Q = np.atleast_2d(np.asarray(approach, dtype=float))
    local, link = _local_points(robot, first_link, config.resolution / 2.0,
                                config.mesh_points)
    q1 = Q[-1]
    step = config.step
    region, q0 = None, Q[0]
    for _ in range(3):
        q0 = Q[step_start(robot, Q, local, link, step, weights)]
        region = _swept(robot, arm, q0, q1, local, link, config)
        if region is not None and touching(arm, region.centres, region.radius,
                                           config.clearance, q1[None]).any():
            break
        step *= 2.0
    if region is None:
        return None, q0
    return carve(arm, region, config, protected), q0


def _swept(robot: Robot, arm: CapsuleArm, q0: Array, q1: Array, local: Array, link: Array,
           config: RegionConfig) -> ContactRegion | None:
    """Spheres along the surfaces the moving links swept from q0 to q1, outside the arm
    (and its clearance) at q0; None if there are none."""
    t = np.arange(1, config.sweep_samples + 1) / config.sweep_samples
    S = q0 + t[:, None] * (q1 - q0)
    P0 = _posed(robot, q0[None], local, link)[0]
    P = _posed(robot, S, local, link)  # (T, M, 3)
    moving = np.linalg.norm(P[-1] - P0, axis=1) >= config.min_move
    cand = _thin(P[:, moving].reshape(-1, 3), config.resolution)
    if not len(cand):
        return None
    # new space only: not where the arm was at the step's start (the checker's own rule)
    keep = ~touching(arm, cand, config.resolution, config.clearance, q0[None])
    return ContactRegion(cand[keep], config.resolution) if keep.any() else None


def carve(arm: CapsuleArm, region: ContactRegion, config: RegionConfig,
          protected: Sequence[tuple[str, Array]], *, withhold: bool = True,
          ) -> ContactRegion:
    """The region without the spheres that touch the arm at a protected posture (label,
    one posture or several): with `withhold` they are kept aside (`withheld`) and the
    labels noted in `cut_for`; else dropped (where the arm itself was)."""
    keep = np.ones(len(region.centres), dtype=bool)
    cut = list(region.cut_for)
    for label, q in protected:
        if not keep.any():
            break
        hit = touching(arm, region.centres[keep], region.radius, config.clearance,
                       np.atleast_2d(np.asarray(q, dtype=float)))
        if hit.any():
            keep[np.flatnonzero(keep)[hit]] = False
            if withhold and label not in cut:
                cut.append(label)
    aside = region.withheld
    if withhold:
        aside = np.concatenate([aside, region.centres[~keep]])
    return ContactRegion(region.centres[keep], region.radius, region.hits, cut, aside)


def grown(old: ContactRegion, new: ContactRegion, config: RegionConfig, *,
          promote: bool = False) -> ContactRegion:
    """The same place indicated again: the union, each sphere `grow` larger. With
    `promote` the withheld spheres are learnt too (the evidence is no longer one
    inference: the arm was stopped there twice)."""
    hits = old.hits + 1
    parts = [old.everything(), new.everything()] if promote else [old.centres, new.centres]
    centres = _thin(np.concatenate(parts), config.resolution)
    aside = np.zeros((0, 3)) if promote else np.concatenate([old.withheld, new.withheld])
    return ContactRegion(centres, config.resolution + config.grow * (hits - 1), hits,
                         list(dict.fromkeys(old.cut_for + new.cut_for)), aside)
