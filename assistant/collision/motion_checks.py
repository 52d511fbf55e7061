"""Motions and clearance of `CollisionChecker` (mixed into it): continuous motion checks
stepped so that no point of the arm moves more than `max_step` between checks, path checks,
clearance along a path."""


from __future__ import annotations

from collections.abc import Sequence

import fcl
import numpy as np

from assistant.collision.clearance_scan import pruned_clearance
from assistant.collision.fcl_shapes import fcl_transform
from assistant.collision.motion_rows import (
    path_samples,
)
from assistant.collision.reports import (
    Clearance,
    MotionCheck,
)

Array = np.ndarray


class MotionChecks:
    """Motion, path and clearance checks of `CollisionChecker`."""

    # ------------------------------------------------------------------ motions
    def motion_samples(self, q0: Array, q1: Array, max_step: float | None = None) -> int:
        """Number of steps so that no point of the arm moves more than max_step per step."""
        return int(self.motion_samples_along(np.stack([np.asarray(q0), np.asarray(q1)]),
                                             max_step)[0])

    def motion_samples_between(self, Q0: Array, Q1: Array, max_step: float | None = None,
                               ) -> Array:
        """`motion_samples` of each motion Q0[i] -> Q1[i], in one pass."""
        step = self.max_step if max_step is None else max_step
        travel = (self._radii * np.abs(np.asarray(Q1, dtype=float)
                                       - np.asarray(Q0, dtype=float))).sum(1)
        return np.maximum(1, np.ceil(travel / step).astype(np.int64))

    def motion_samples_along(self, path: Array, max_step: float | None = None) -> Array:
        """`motion_samples` of each segment of a joint path (M, dof), in one pass."""
        step = self.max_step if max_step is None else max_step
        travel = (self._radii * np.abs(np.diff(np.asarray(path, dtype=float), axis=0))).sum(1)
        return np.maximum(1, np.ceil(travel / step).astype(np.int64))

    def _path_samples(self, P: Array, max_step: float | None) -> tuple[Array, Array, Array]:
        """Segment index, fraction and step count of the samples `check_motion` takes on
        each segment of the path P (M, dof), concatenated, each vertex once: a segment's
        samples but its end (the next segment's start, the path's vertex itself), the last
        segment's end too. A dense path's segments hold two or three samples each, so
        sampling every segment whole asked a third of the samples twice."""
        counts = self.motion_samples_along(P, max_step)
        per = counts.copy()
        per[-1] += 1
        seg = np.repeat(np.arange(len(counts)), per)
        first = np.cumsum(per) - per
        k = np.arange(len(seg)) - first[seg]
        return seg, k / counts[seg], counts

    def check_motion(self, q0: Array, q1: Array, max_step: float | None = None) -> MotionCheck:
        """Continuous check of q0 -> q1, in order, returning the first invalid fraction."""
        q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
        n = self.motion_samples(q0, q1, max_step)
        fr = np.arange(0, n + 1) / n
        for start in range(0, n + 1, self.chunk):
            f = fr[start : start + self.chunk]
            Q = q0[None] + f[:, None] * (q1 - q0)[None]
            ok = self.is_valid_samples(Q, first_only=True)
            if not ok.all():
                k = int(np.argmin(ok))
                return MotionCheck(float(f[k]), n, self.check(Q[k]))
        return MotionCheck(None, n)

    def first_invalid_fraction(self, q0: Array, q1: Array) -> float | None:
        return self.check_motion(q0, q1).first_invalid_fraction

    def check_path(self, path: Sequence[Array], max_step: float | None = None,
                   trusted: Array | None = None) -> tuple[int, MotionCheck] | None:
        """First invalid segment (index, check) of a joint path, or None if all of it is valid.

        The samples of `check_motion` on each segment in turn, each vertex once (an invalid
        vertex is reported at the start of the segment it begins), checked in batches
        across segments: a dense path of short segments would otherwise pay the per-call
        cost once per segment. `trusted` (a flag per segment) names segments this checker
        already passed, sampled the same way (a caller that checked part of the path
        before): their samples are not asked again; a sample's answer does not depend on
        the others it is checked with.
        """
        if len(path) < 2:
            return None
        A = np.ascontiguousarray(_path_array(path), dtype=float)
        counts = np.ascontiguousarray(self.motion_samples_along(A, max_step), dtype=np.int64)
        skip = _NONE_TRUSTED if trusted is None else np.ascontiguousarray(trusted, dtype=bool)
        S, F, Qs = path_samples(A, counts, skip)  # `_path_samples`' samples, compiled
        for start in range(0, len(S), self.chunk):
            Q = Qs[start : start + self.chunk]
            ok = self.is_valid_samples(Q, first_only=True)
            if not ok.all():
                k = int(np.argmin(ok))
                i = int(S[start + k])
                return i, MotionCheck(float(F[start + k]), int(counts[i]), self.check(Q[k]))
        return None

    # ------------------------------------------------------------------ clearance
    def clearance(self, q: Array, include_self: bool = False) -> Clearance | None:
        """Minimum distance between the arm and any obstacle (None without obstacles)."""
        frames = self.robot.link_poses(np.asarray(q, dtype=float))
        self._pose_robot(frames)
        best: Clearance | None = None
        # (robot shape, other object, its name, its margin): the distance to an obstacle with
        # a margin is measured to everything within the margin of it
        pairs = [(rs, es.obj, es.owner, es.margin) for rs in self._rshapes if rs.link > 0
                 for es in self._env]
        if include_self:
            pairs += [(self._rshapes[a], self._rshapes[b].obj,
                       self._link_names[self._rshapes[b].link], 0.0)
                      for a, b in self._self_pairs]
        for rs, obj, owner, margin in pairs:
            d, res = self._pair_distance(rs.obj, obj)
            d -= margin
            if best is None or d < best.distance:
                best = Clearance(d, self._link_names[rs.link], owner,
                                 np.array(res.nearest_points[0]), np.array(res.nearest_points[1]))
        return best

    def min_clearance_along(self, path: Sequence[Array], max_step: float = 0.01) -> float:
        """Smallest clearance over a joint path sampled every `max_step` of arm travel.

        What `clearance` at each sample would give, with few or no FCL calls: each link
        shape lies inside its covering spheres and each obstacle inside its box, so
        sphere-to-box gaps bound every (sample, shape, obstacle) distance from below, and
        a sample's distances are at least a nearby sample's bound less the arm's travel
        between them. One compiled pass (`clearance_scan.pruned_clearance`) visits the
        samples whose bound is below the smallest distance so far and gives their pairs
        below it a tight bound, the distance from the shape's axis segment to the
        obstacle's oriented box (`segment_box`), which for a capsule or sphere link and a
        box obstacle is the exact distance itself (FCL's GJK answer there is up to ~0.1 mm
        high). The rest are measured with FCL in the order of their bounds until the next
        bound is not below the smallest distance found: no pair left could be closer.
        """
        best = np.inf
        if not self._env:
            return float(best)
        P = _path_array(path)
        if len(P) == 1:
            Q = P
        else:
            S, F, _ = self._path_samples(P, max_step)
            Q = P[S] + F[:, None] * (P[S + 1] - P[S])
        movable = np.array([i for i, rs in enumerate(self._rshapes)
                            if rs.link >= self._env_from], dtype=np.int64)
        best = self._env_floor  # what the links left out keep in every posture (m)
        if not len(movable):
            return float(best)
        Q = np.ascontiguousarray(Q, dtype=float)
        frames, ready, chain = self._frames_to_fill(Q)  # the pass poses what it visits
        found, cand, bound = pruned_clearance(
            Q, frames, ready, chain, self.travel(Q[:-1], Q[1:]), self.CLEARANCE_STRIDE,
            movable, len(self._rshapes), self._sph_link, self._sph_local, self._sph_r,
            self._sph_shape, self._env_lo, self._env_hi, self._shape_link, self._seg_a,
            self._seg_b, self._seg_r, self._seg_exact, self._env_R, self._env_c,
            self._env_h, self._env_exact)
        best = min(best, found)
        n_mov, n_env = len(movable), len(self._env)
        order = np.lexsort((cand, bound))  # by bound, ties in sample order
        for j, b in zip(cand[order].tolist(), bound[order].tolist(), strict=True):
            if b >= best:
                break
            k, r, e = j // (n_mov * n_env), (j // n_env) % n_mov, j % n_env
            rs, es = self._rshapes[int(movable[r])], self._env[e]
            rs.obj.setTransform(fcl_transform(frames[k][rs.link] @ rs.shape.T_link_shape))
            best = min(best, self._pair_distance(rs.obj, es.obj)[0] - es.margin)
        return float(best)

    def _pair_distance(self, a: fcl.CollisionObject, b: fcl.CollisionObject,
                       ) -> tuple[float, fcl.DistanceResult]:
        """FCL distance of two posed objects (negative: penetration depth, 0: touching).

        FCL answers -1 for shapes that touch or overlap. Its signed distance segfaults on a
        capsule that only touches a mesh (python-fcl 0.7), so it is asked only when the
        shapes really overlap; touching is distance 0.
        """
        res = fcl.DistanceResult()
        d = float(fcl.distance(a, b, self._dreq, res))
        if d < 0.0:
            if fcl.collide(a, b, self._req, fcl.CollisionResult()):
                res = fcl.DistanceResult()
                d = float(fcl.distance(a, b, self._sreq, res))
            else:
                d = 0.0
        return d, res


_NONE_TRUSTED = np.zeros(0, dtype=bool)


def _path_array(path: Sequence[Array] | Array) -> Array:
    """A joint path as one (M, dof) float array: a dense path that already is one is used
    as it is (stacking its rows again would cost ~0.2 ms per verification)."""
    if isinstance(path, np.ndarray) and path.ndim == 2:
        return np.asarray(path, dtype=float)
    return np.stack([np.asarray(q, dtype=float) for q in path])
