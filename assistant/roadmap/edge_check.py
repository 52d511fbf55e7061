"""The roadmap search's edge check and the positions it may leave out before it starts.

Why a module: both read the world's record of collision indications (posture boxes and
learnt regions, `WorldModel.near_recorded_collision`) on top of the checker's continuous
check; the planner (`roadmap.planner`) composes them. Imports the world and the graph only.
"""

from __future__ import annotations

import numpy as np

from assistant.collision.validity import ValidityChecker
from assistant.roadmap.edge_samples import edge_samples, first_invalid
from assistant.roadmap.graph import GraphBase
from assistant.world.model import WorldModel

Array = np.ndarray

#: How far (m) from a learnt region a position's TCP may be for `near_learnt` to ask about it.
DEAD_REACH = 0.3


class EdgeCheck:
    """The checker's continuous check plus "not near a recorded collision posture"."""

    def __init__(self, checker: ValidityChecker, world: WorldModel):
        self.checker = checker
        self.world = world
        #: Recorded collisions whose box holds the query's start: the robot stands there and
        #: must be allowed to move out.
        self.exempt: frozenset[int] = frozenset()

    def first_invalid_fraction(self, q0: Array, q1: Array) -> float | None:
        if self.world.collisions:
            table = self.world.table
            assert table is not None
            varying = table.counts > 1
            # half a grid step per sample: no posture box is jumped over
            steps = np.abs(q1 - q0)[varying] / (0.5 * table.step[varying])
            n = max(1, int(np.ceil(steps.max(initial=0.0))))
            f = np.arange(n + 1) / n
            near = self.world.near_recorded_collision(q0 + f[:, None] * (q1 - q0), self.exempt)
            if near.any():
                return float(f[int(np.argmax(near))])
        return self.checker.first_invalid_fraction(q0, q1)

    def first_invalid_fractions(self, Q0: Array, Q1: Array) -> list[float | None]:
        """Several edges in one batched validity call, sampled exactly as the checker's own
        motion check (`motion_samples_between`, certified by margins with `is_valid_samples` where
        the checker offers it); falls back to one call per edge otherwise."""
        samples = getattr(self.checker, "motion_samples_between", None)
        if samples is None:
            return [self.first_invalid_fraction(a, b) for a, b in zip(Q0, Q1, strict=True)]
        Q0 = np.ascontiguousarray(Q0, dtype=float)
        Q1 = np.ascontiguousarray(Q1, dtype=float)
        ns = np.ascontiguousarray(samples(Q0, Q1), dtype=np.int64)
        # every edge's samples a + (k / n) (b - a), k = 0..n, all at once (the same
        # operations on the same numbers as edge by edge)
        Q, edge, F = edge_samples(Q0, Q1, ns)
        near = (self.world.near_recorded_collision(Q, self.exempt)
                if self.world.collisions else None)
        along = getattr(self.checker, "is_valid_samples", None)
        if along is not None:  # only each edge's first invalid sample matters
            ok = along(Q, None if len(ns) == 1 else edge, first_only=True, known_invalid=near)
        else:
            ok = self.checker.is_valid_batch(Q)
            if near is not None:
                ok &= ~near
        first = first_invalid(np.ascontiguousarray(ok, dtype=bool), edge, F, len(ns))
        return [None if f != f else f for f in first.tolist()]  # NaN: no invalid sample


def near_learnt(w: WorldModel, base: GraphBase, n_base: int, exempt: frozenset[int]) -> Array:
    """Base positions worth asking `RoadmapPlanner._known_dead` about: with learnt regions
    only, those whose TCP leaf lies within `DEAD_REACH` of one (the arm touches a region with the
    links near its TCP; a position the cut leaves unmarked is still refused by the edge
    checks, only later). A UR10's first re-plan posed all 70 000 positions in 0.5 s; this
    cut, 0.04 s. Posture boxes: every position (their test needs no pose)."""
    if any(rc.region is None for i, rc in enumerate(w.collisions) if i not in exempt):
        return np.arange(n_base)
    centres = [rc.region.centres for i, rc in enumerate(w.collisions)
               if i not in exempt and rc.region is not None and len(rc.region.centres)]
    if not centres:
        return np.zeros(0, dtype=np.int64)
    C = np.concatenate(centres)
    pad = DEAD_REACH + w.grid.leaf * np.sqrt(3.0) / 2.0
    lo, hi = C.min(axis=0) - pad, C.max(axis=0) + pad
    P = w.grid.centres_of_ijk(w.grid.ijk_of_flat(base.node_cell[:n_base]))
    return np.flatnonzero(np.all((P >= lo) & (P <= hi), axis=1))
