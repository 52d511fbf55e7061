"""What the planners may rely on: CAD checked exactly plus the operator's recorded collisions.

The roadmap already refuses edges through a recorded collision's posture box; the elastic
net and the final verification must do the same, or a smoothed path would slide back into a
posture the operator just flagged. Three small adapters give the trajectory package that view
through its own interfaces:

* `WorldAllowed` - TCP points -> bool: inside a free leaf of the world model (the net's
  `allowed`); the dense grid is read once per plan, not once per net iteration.
* `KnownValidity` - the `ValidityChecker` for the net's particles: FCL against CAD and joint
  limits, and not inside a recorded posture box.
* `KnownVerifier` - the `PathVerifier` for finished trajectories: the exact continuous FCL
  check, then the recorded posture boxes along every segment.

Boxes that hold the path's first posture are exempt (the robot stands there after an
indication and must be allowed to leave), as in the roadmap's own edge check.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import CollisionReport, Contact, MotionCheck
from assistant.world.indications import posture_box_half
from assistant.world.leaf_lookup import leaf_flags
from assistant.world.model import WorldModel

Array = np.ndarray
#: Arm travel (m, `WorldModel.weights`) between the postures whose hand leaves are tested:
#: a quarter of a 62.5 mm leaf.
HAND_STEP = 0.015


class WorldAllowed:
    """`allowed(points)` for the elastic net: TCP points in free, reachable leaves."""

    def __init__(self, world: WorldModel):
        self.world = world
        self._free = world.free().reshape(-1)

    def refresh(self) -> None:
        """Re-read the grid after the world changed (an indication, an observation)."""
        self._free = self.world.free().reshape(-1)

    def grid_flags(self) -> tuple[Array, float, int, Array]:
        """(origin, leaf, n, flat free flags): what `__call__` reads, for compiled callers."""
        g = self.world.grid
        return g.origin, float(g.leaf), int(g.n), self._free

    def __call__(self, points: Array) -> Array:
        g = self.world.grid
        P = np.ascontiguousarray(np.atleast_2d(np.asarray(points, dtype=float)))
        return leaf_flags(P, g.origin, g.leaf, g.n, self._free)


class KnownValidity:
    """FCL + joint limits + recorded collision postures, for single configurations."""

    def __init__(self, checker: CollisionChecker, world: WorldModel,
                 exempt: frozenset[int] = frozenset()):
        self.checker = checker
        self.world = world
        self.exempt = exempt

    def is_valid(self, q: Array) -> bool:
        return bool(self.is_valid_batch(np.asarray(q, dtype=float)[None])[0])

    def is_valid_batch(self, Q: Array) -> Array:
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        ok = self.checker.is_valid_batch(Q)
        if self.world.collisions and ok.any():
            ok[ok] &= ~self.world.near_recorded_collision(Q[ok], self.exempt)
        return ok

    def is_valid_batch_margin(self, Q: Array, certified: Array | None = None,
                              ) -> tuple[Array, Array]:
        """`CollisionChecker.is_valid_batch_margin` for CAD; the recorded postures are
        tested on every row (a margin certifies clearance from CAD only)."""
        ok, margin = self.checker.is_valid_batch_margin(Q, certified)
        if self.world.collisions and ok.any():
            ok[ok] &= ~self.world.near_recorded_collision(np.atleast_2d(Q)[ok], self.exempt)
        return ok, margin

    def travel(self, Q0: Array, Q1: Array) -> Array:
        return self.checker.travel(Q0, Q1)

    def net_kernel_validity(self) -> tuple[tuple, Array, Array, object] | None:
        """`CollisionChecker.net_kernel_validity` with the recorded collision postures
        (but the exempt ones) and their boxes (`indications.near_posture`)."""
        base = self.checker.net_kernel_validity()
        if base is None:
            return None
        model, _, _, exact = base
        table = self.world.table
        if any(rc.region is not None for i, rc in enumerate(self.world.collisions)
               if i not in self.exempt):
            return None  # a learnt region has no compiled form: `is_valid_batch` asks it
        kept = [rc.q for i, rc in enumerate(self.world.collisions) if i not in self.exempt]
        if table is None or not kept:
            return base
        half = posture_box_half(table, self.world.config.indication.joint_steps)
        return model, np.array(kept, dtype=float), half, exact

    def first_invalid_fraction(self, q0: Array, q1: Array) -> float | None:
        mc = KnownVerifier(self.checker, self.world).check_motion(q0, q1, self.exempt)
        return mc.first_invalid_fraction


class KnownVerifier:
    """Exact continuous check of joint paths against CAD, limits and recorded postures."""

    def __init__(self, checker: CollisionChecker, world: WorldModel, *, hand: bool = True):
        self.checker = checker
        self.world = world
        #: Whether the recorded hand leaves count (transfers). Not for application paths:
        #: the operator taught them; what they meet, the run itself shows.
        self.hand = hand

    def _box_samples(self, q0: Array, q1: Array) -> Array:
        """Fractions along q0 -> q1 at most half a table grid step apart (no box skipped)."""
        table = self.world.table
        if table is None:
            return np.array([0.0, 1.0])
        varying = table.counts > 1
        steps = np.abs(np.asarray(q1) - q0)[varying] / (0.5 * table.step[varying])
        n = max(1, int(np.ceil(steps.max(initial=0.0))))
        return np.arange(n + 1) / n

    def check_motion(self, q0: Array, q1: Array, exempt: frozenset[int] = frozenset(),
                     hand_exempt: Array | None = None) -> MotionCheck:
        """FCL's continuous check, then the recorded posture boxes (`exempt`: not these),
        then on sampled stores the recorded hand leaves (`WorldModel.hand_blocked`;
        `hand_exempt`: leaves not counted, by default those q0's and q1's hand fills)."""
        q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
        mc = self.checker.check_motion(q0, q1)
        if not mc.valid or not self.world.collisions:
            return mc
        f = self._box_samples(q0, q1)
        near = self.world.near_recorded_collision(q0 + f[:, None] * (q1 - q0), exempt)
        if near.any():
            k = int(np.argmax(near))
            hit = sorted(self.world.recorded_collisions_at(q0 + f[k] * (q1 - q0)) - exempt)
            what = ", ".join(f"recorded collision {i + 1}" for i in hit) or \
                "a recorded collision"
            report = CollisionReport(True, (Contact("arm posture", what),))
            return MotionCheck(float(f[k]), len(f) - 1, report)
        return self._hand_check(q0, q1, mc, hand_exempt)

    def _hand_check(self, q0: Array, q1: Array, mc: MotionCheck,
                    hand_exempt: Array | None) -> MotionCheck:
        w = self.world
        if not w.sampled or not self.hand or not w.collisions:
            return mc
        if hand_exempt is None:
            hand_exempt = w.hand_cells_at(np.stack([q0, q1]))
        travel = float(np.abs(q1 - q0) @ w.weights)
        n = max(1, int(np.ceil(travel / HAND_STEP)))
        f = np.arange(n + 1) / n
        blocked = w.hand_blocked(q0 + f[:, None] * (q1 - q0), hand_exempt)
        if not blocked.any():
            return mc
        k = int(np.argmax(blocked))
        report = CollisionReport(True, (Contact("arm's hand",
                                                "where a recorded collision stopped it"),))
        return MotionCheck(float(f[k]), n, report)

    def check_path(self, path: Sequence[Array], max_step: float | None = None,
                   trusted: Array | None = None) -> tuple[int, MotionCheck] | None:
        """First invalid segment (index, check) or None; exempts the boxes at path[0].

        `trusted` segments skip the checker (`CollisionChecker.check_path`), never the
        recorded collisions: those depend on where the path starts."""
        if len(path) == 0:
            return None
        hit = self.checker.check_path(path, max_step, trusted)
        if not self.world.collisions:
            return hit
        exempt = self.world.recorded_collisions_at(np.asarray(path[0], dtype=float))
        last = hit[0] if hit is not None else len(path) - 1
        P = np.asarray(path, dtype=float)
        segs, parts = [], []
        for i in range(min(last + 1, len(P) - 1)):  # all samples at once, one box query
            f = self._box_samples(P[i], P[i + 1])
            parts.append(P[i] + f[:, None] * (P[i + 1] - P[i]))
            segs.append(np.full(len(f), i))
        if not parts:
            return hit
        near = self.world.near_recorded_collision(np.concatenate(parts), exempt)
        if near.any():
            i = int(np.concatenate(segs)[int(np.argmax(near))])
            if hit is None or i < hit[0] or (i == hit[0]):
                mc = self.check_motion(P[i], P[i + 1], exempt, hand_exempt=None)
                if not mc.valid:
                    return i, mc
        return self._hand_hit(P, last, hit)

    def _hand_hit(self, P: Array, last: int, hit: tuple[int, MotionCheck] | None,
                  ) -> tuple[int, MotionCheck] | None:
        """The first segment (up to `last`) whose postures put the hand into recorded hand
        leaves (sampled stores; those the path's first or last posture's hand fills are
        exempt), if before `hit`."""
        w = self.world
        if not w.sampled or not self.hand or len(P) < 2:
            return hit
        hand_exempt = w.hand_cells_at(np.stack([P[0], P[-1]]))
        parts, segs, fracs = [], [], []
        for i in range(min(last + 1, len(P) - 1)):  # every sample at once: one batch FK
            n = max(1, int(np.ceil(float(np.abs(P[i + 1] - P[i]) @ w.weights) / HAND_STEP)))
            f = np.arange(n + 1) / n
            parts.append(P[i] + f[:, None] * (P[i + 1] - P[i]))
            segs.append(np.full(n + 1, i))
            fracs.append(f)
        blocked = w.hand_blocked(np.concatenate(parts), hand_exempt)
        if not blocked.any():
            return hit
        k = int(np.argmax(blocked))
        i = int(np.concatenate(segs)[k])
        report = CollisionReport(True, (Contact("arm's hand",
                                                "where a recorded collision stopped it"),))
        mc = MotionCheck(float(np.concatenate(fracs)[k]), len(fracs[i]) - 1, report)
        return (i, mc) if hit is None or i <= hit[0] else hit

    def min_clearance_along(self, path: Sequence[Array], max_step: float = 0.01) -> float:
        return self.checker.min_clearance_along(path, max_step)
