"""The exact check of one finished path by conservative advancement: FCL distances, pair by pair.

Why: a mesh arm's checks ask the fast model first (`fast_checker`), and a finished path is
certified without it (`planning.certify`). The checker's own pass over a UR5's dense path
(1000-2300 samples) cost 30-130 ms: the shoulder and the upper arm sit a few centimetres
above the table in every posture, and a few self pairs side by side, so the sphere broad
phase passes those pairs at every sample and FCL's collide ran ~4 times a sample. Here each
pair the broad phase passes is measured by FCL's distance at one sample, and the samples
after it are free for that pair while the pair's own travel from it stays below that
distance - the shoulder's travel is its small radius times q1's change, so one distance
covers most of a path.

Exact: nothing here comes from the fast model. Shapes, kinematics (`Robot.batch_link_poses`),
broad phase (covering spheres and the mesh capsules of `CollisionChecker`) and FCL are the
checker's own. The samples are `MotionChecks.check_path`'s (every `max_step` of arm
travel along each segment), each either measured or within a measured distance's travel.

The travel bound of a pair: a point of a shape on link k moves by at most sum_i |dq_i| R[i]
for the joints i that move it (R: `shape_radii`, the triangle inequality along the chain, as
`Robot.arm_radii` per shape); relative to link a, a point of link b moves by at most the same
sum over the joints between them.
"""

from __future__ import annotations

import fcl
import numpy as np

from assistant.collision.broad_phase import prune_round_pairs
from assistant.collision.fcl_shapes import fcl_transform
from assistant.robots.model import Robot

Array = np.ndarray


def link_radii(robot: Robot) -> Array:
    """R (dof, links): an upper bound (m) on the distance from joint i's axis to any point
    of link k (0 where joint i does not move link k); link k (k >= 1) is moved by joints
    0..k-1, the TCP counts as a point of the last link (as `Robot.arm_radii`)."""
    n = robot.dof
    T_last_tool = np.linalg.inv(robot.link_poses(np.zeros(n))[n]) @ robot.fk(np.zeros(n))
    R = np.zeros((n, len(robot.links)))
    for k, link in enumerate(robot.links):
        if k == 0:
            continue
        e = max((_extent(s) for s in link.collision), default=0.0)
        if k == n:
            e = max(e, float(np.linalg.norm(T_last_tool[:3, 3])))
        R[:, k] = _radii_to(robot, k, e)
    return R


def shape_radii(robot: Robot, link: int, shape) -> Array:
    """(dof,): an upper bound (m) on the distance from each joint's axis to any point of one
    shape of `link` (0 for the joints that do not move it): `link_radii` for that shape
    alone (a UR's wrist housing, not the tool on the same link)."""
    return _radii_to(robot, link, _extent(shape))


def _extent(shape) -> float:
    """How far the shape reaches from its link's frame origin (m)."""
    return float(np.linalg.norm(shape.T_link_shape[:3, 3])) + shape.bounding_radius()


def _radii_to(robot: Robot, k: int, e: float) -> Array:
    """Per joint, the chain's length from its axis to link k's frame plus `e`."""
    n = robot.dof
    frames = robot.link_poses(np.zeros(n))
    origins = frames[1 : n + 1, :3, 3]
    j = min(k, n) - 1  # the last joint that moves link k
    if k > n:  # a link fixed beyond the last joint: its frame's offset from that axis
        e += float(np.linalg.norm(frames[k, :3, 3] - origins[j]))
    out = np.zeros(n)
    for i in range(0, j + 1):
        out[i] = sum(float(np.linalg.norm(origins[m] - origins[m - 1]))
                     for m in range(i + 1, j + 1)) + e
    return out


def first_contact(checker, path: Array, max_step: float | None = None) -> int | None:
    """Index of the first sample (of `checker._path_samples`) where a shape touches an
    obstacle or a self pair touches, or None if the whole path is free; `checker` is a
    `CollisionChecker` that asks no fast model (`CollisionChecker.exact_only`)."""
    P = np.asarray(path, dtype=float).reshape(-1, checker.robot.dof)
    if len(P) == 1:
        Q = P
    else:
        S, Fr, _ = checker._path_samples(P, max_step)
        Q = P[S] + Fr[:, None] * (P[S + 1] - P[S])
    Q = np.ascontiguousarray(Q)
    if not len(checker._sph_r):
        return None
    frames = np.ascontiguousarray(checker._link_frames(Q), dtype=float)
    env_c, self_c, _ = checker._candidates(frames)
    rows = np.flatnonzero(env_c.any(axis=(1, 2)) | self_c.any(axis=1))
    if len(rows) and checker._round.any():
        prune_round_pairs(frames, rows, env_c, self_c, checker._shape_link, checker._seg_a,
                          checker._seg_b, checker._seg_r, checker._env_R, checker._env_c,
                          checker._env_h, checker._pair_a, checker._pair_b,
                          checker.PRUNE_APART)
    R = _radii(checker)  # (dof, robot shapes)
    dq = np.abs(np.diff(Q, axis=0))  # (n - 1, dof)
    first = len(Q)
    for s, e in zip(*np.nonzero(env_c.any(axis=0)), strict=True):
        w = R[:, int(s)]  # the joints that move it, by its reach from their axes
        es = checker._env[int(e)]
        hit = _advance(np.flatnonzero(env_c[:, s, e]), np.r_[0.0, np.cumsum(dq @ w)], first,
                       lambda k, s=int(s), es=es: _env_distance(checker, frames[k], s, es),
                       lambda k, s=int(s), es=es: _env_touches(checker, frames[k], s, es))
        first = min(first, hit)
    for p in np.flatnonzero(self_c.any(axis=0)).tolist():
        a, b = checker._self_pairs[p]
        if checker._rshapes[a].link > checker._rshapes[b].link:
            a, b = b, a
        ra, rb = checker._rshapes[a], checker._rshapes[b]
        w = R[:, b].copy()
        w[: ra.link] = 0.0  # joints below link a move both links alike
        hit = _advance(np.flatnonzero(self_c[:, p]), np.r_[0.0, np.cumsum(dq @ w)], first,
                       lambda k, ra=ra, rb=rb: _distance(checker, frames[k], ra, rb),
                       lambda k, ra=ra, rb=rb: _touches(checker, frames[k], ra, rb))
        first = min(first, hit)
    return None if first >= len(Q) else int(first)


#: A distance that clears fewer rows than this is followed by as many rows of plain
#: collision tests before the next distance (FCL's mesh distance costs ~30 of its tests).
SPREAD = 32


def _advance(rows: Array, travel: Array, stop: int, distance, touches) -> int:
    """The first of `rows` (samples where the broad phase passes one pair) before `stop`
    where the pair touches, else `stop`: each measured distance clears the rows after it
    whose travel from it stays below it; where a distance clears few, the next `SPREAD`
    rows are tested one by one (`touches`) before the next distance."""
    i = 0
    while i < len(rows) and rows[i] < stop:
        k = int(rows[i])
        d = distance(k)
        if d <= 0.0:
            return k
        # rows whose travel from k stays below d are free for this pair
        nxt = int(np.searchsorted(rows, np.searchsorted(travel, travel[k] + d, side="left"),
                                  side="left"))
        nxt = max(nxt, i + 1)
        if nxt - i < SPREAD:
            for j in range(nxt, min(len(rows), nxt + SPREAD)):
                if rows[j] >= stop:
                    return stop
                if touches(int(rows[j])):
                    return int(rows[j])
            nxt = min(len(rows), nxt + SPREAD)
        i = nxt
    return stop


def _pose(frames_k: Array, rs) -> None:
    rs.obj.setTransform(fcl_transform(frames_k[rs.link] @ rs.shape.T_link_shape))


def _env_distance(checker, frames_k: Array, i: int, es) -> float:
    """FCL distance (m) of robot shape i posed at one sample to an obstacle shape, less the
    obstacle's margin (<= 0: touching)."""
    rs = checker._rshapes[i]
    _pose(frames_k, rs)
    d = float(fcl.distance(rs.obj, es.obj, checker._dreq, fcl.DistanceResult())) - es.margin
    if d <= 0.0 and not checker._touches_env(i, es):
        d = 1e-9  # touching within FCL's tolerance, not overlapping: free, no cover
    return d


def _env_touches(checker, frames_k: Array, i: int, es) -> bool:
    _pose(frames_k, checker._rshapes[i])
    return checker._touches_env(i, es)


def _distance(checker, frames_k: Array, ra, rb) -> float:
    """FCL distance (m) of robot shapes ra and rb posed at one sample (<= 0: touching)."""
    _pose(frames_k, ra)
    _pose(frames_k, rb)
    d = float(fcl.distance(ra.obj, rb.obj, checker._dreq, fcl.DistanceResult()))
    if d <= 0.0 and not fcl.collide(ra.obj, rb.obj, checker._req, fcl.CollisionResult()):
        d = 1e-9  # touching within FCL's tolerance, not overlapping: free, no cover
    return d


def _touches(checker, frames_k: Array, ra, rb) -> bool:
    _pose(frames_k, ra)
    _pose(frames_k, rb)
    return bool(fcl.collide(ra.obj, rb.obj, checker._req, fcl.CollisionResult()))


def _radii(checker) -> Array:
    """(dof, shapes): `shape_radii` of every robot shape of the checker, kept on it."""
    R = checker.__dict__.get("_shape_radii")
    if R is None:
        R = np.stack([shape_radii(checker.robot, rs.link, rs.shape)
                      for rs in checker._rshapes], axis=1).reshape(checker.robot.dof, -1)
        checker.__dict__["_shape_radii"] = R
    return R
