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

Before any FCL call, the rows where one shape lies wholly beyond a face plane of a box -
an obstacle box, or the box that holds the other shape of a self pair - are free for that
pair: every vertex of the mesh is tested against the plane (`_outside_box`, `face_planes`).
On the UR5 benchmark cell that clears the upper arm over the table and the upper arm over
the base at every sample, which were ~4000 FCL tests a transfer.

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
from assistant.collision.face_planes import vertices_beyond
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
    pose = _Poser(checker, frames)
    R = _radii(checker)  # (dof, robot shapes)
    dq = np.abs(np.diff(Q, axis=0))  # (n - 1, dof)
    first = len(Q)
    for s, e in zip(*np.nonzero(env_c.any(axis=0)), strict=True):
        w = R[:, int(s)]  # the joints that move it, by its reach from their axes
        es = checker._env[int(e)]
        rows = np.flatnonzero(env_c[:, s, e])
        rows = rows[~beyond_a_face(checker, frames, rows, int(s), int(e))]
        hit = _advance(rows, np.r_[0.0, np.cumsum(dq @ w)], first,
                       lambda k, s=int(s), es=es: _env_distance(checker, pose, k, s, es),
                       lambda k, s=int(s), es=es: _env_touches(checker, pose, k, s, es))
        first = min(first, hit)
    for p in np.flatnonzero(self_c.any(axis=0)).tolist():
        a, b = checker._self_pairs[p]
        if checker._rshapes[a].link > checker._rshapes[b].link:
            a, b = b, a
        w = R[:, b].copy()
        w[: checker._rshapes[a].link] = 0.0  # joints below link a move both links alike
        rows = np.flatnonzero(self_c[:, p])
        rows = rows[~_pair_apart(checker, frames, rows, a, b)]
        hit = _advance(rows, np.r_[0.0, np.cumsum(dq @ w)], first,
                       lambda k, a=a, b=b: _distance(checker, pose, k, a, b),
                       lambda k, a=a, b=b: pose.pair_touches(a, b, k))
        first = min(first, hit)
    return None if first >= len(Q) else int(first)


#: What `_Poser._at` holds for a shape posed at its own frame, or relative to another one.
_AT_OWN_FRAME, _AT_RELATIVE = -1, -2
_IDENTITY = fcl.Transform()


class _Poser:
    """Poses the checker's robot shapes at one sample: each shape's rotations (quaternions)
    and positions for every sample are computed in one batch when the shape is first asked
    for, and a shape already at the sample asked for is not posed again. Why: building an
    `fcl.Transform` and the 4x4 product cost ~7 us per pose, more than FCL's collision test
    itself (~2.5 us of a UR5's close pair), and a path asks thousands of them."""

    def __init__(self, checker, frames: Array):
        self._checker, self._frames = checker, frames
        self._rows: dict[int, tuple[Array, Array]] = {}
        self._at: dict[int, int] = {}
        #: b's pose relative to a, by self pair (a, b), for every sample (`pair_touches`)
        self._rel: dict[tuple[int, int], tuple[list, Array]] = {}
        #: one result object for every test: `fcl.collide`'s return value is the answer
        self._result = fcl.CollisionResult()

    def __call__(self, i: int, k: int):  # noqa: ANN204 - an fcl.CollisionObject
        rs = self._checker._rshapes[i]
        if self._at.get(i) == k:
            return rs.obj
        got = self._rows.get(i)
        if got is None:
            T = self._frames[:, rs.link] @ rs.shape.T_link_shape
            got = (_quaternions(T[:, :3, :3]), np.ascontiguousarray(T[:, :3, 3]))
            self._rows[i] = got
        rs.obj.setQuatRotation(got[0][k])
        rs.obj.setTranslation(got[1][k])
        self._at[i] = k
        return rs.obj

    def pair_touches(self, a: int, b: int, k: int) -> bool:
        """Whether robot shapes a and b touch at sample k (FCL's collision test), b posed
        relative to a and a at its own frame: one pose per test, not two (a UR5's base and
        upper arm stay 16 mm apart along a whole path and are tested at most samples). The
        test is the same: FCL's collision of two objects depends on their relative pose
        only (it works in one's frame), so the answer differs from posing both at most by
        rounding of metre-sized numbers."""
        c = self._checker
        ra, rb = c._rshapes[a], c._rshapes[b]
        rel = self._rel.get((a, b))
        if rel is None:
            Ta = self._frames[:, ra.link] @ ra.shape.T_link_shape
            Tb = self._frames[:, rb.link] @ rb.shape.T_link_shape
            Rt = np.swapaxes(Ta[:, :3, :3], 1, 2)
            Rr = Rt @ Tb[:, :3, :3]
            tr = np.einsum("nij,nj->ni", Rt, Tb[:, :3, 3] - Ta[:, :3, 3])
            rel = (_quaternions(Rr).tolist(), np.ascontiguousarray(tr))
            self._rel[(a, b)] = rel
        if self._at.get(a) != _AT_OWN_FRAME:
            ra.obj.setTransform(_IDENTITY)
            self._at[a] = _AT_OWN_FRAME
        rb.obj.setQuatRotation(rel[0][k])
        rb.obj.setTranslation(rel[1][k])
        self._at[b] = _AT_RELATIVE  # posed at no sample of its own
        return bool(fcl.collide(ra.obj, rb.obj, c._req, self._result))


#: A distance that clears fewer rows than this is followed by as many rows of plain
#: collision tests before the next distance. FCL's mesh distance costs 30-250 of its tests
#: (a UR5's base and upper arm, 16 mm apart at every sample: 640 us against 2.5 us, plus
#: 9 us to pose the pair), so each further distance that clears few doubles the run of
#: tests after it: a pair that stays close is measured a few times, not every 40 rows.
SPREAD = 32


def _advance(rows: Array, travel: Array, stop: int, distance, touches) -> int:
    """The first of `rows` (samples where the broad phase passes one pair) before `stop`
    where the pair touches, else `stop`: each measured distance clears the rows after it
    whose travel from it stays below it; where a distance clears few, the next rows (`SPREAD`,
    doubling each time) are tested one by one (`touches`) before the next distance."""
    i = 0
    spread = SPREAD
    while i < len(rows) and rows[i] < stop:
        k = int(rows[i])
        d = distance(k)
        if d <= 0.0:
            return k
        # rows whose travel from k stays below d are free for this pair
        nxt = int(np.searchsorted(rows, np.searchsorted(travel, travel[k] + d, side="left"),
                                  side="left"))
        nxt = max(nxt, i + 1)
        if nxt - i < spread:
            for j in range(nxt, min(len(rows), nxt + spread)):
                if rows[j] >= stop:
                    return stop
                if touches(int(rows[j])):
                    return int(rows[j])
            nxt = min(len(rows), nxt + spread)
            spread *= 2
        i = nxt
    return stop


def _quaternions(R: Array) -> Array:
    """(w, x, y, z) of rotation matrices (N, 3, 3), each from its largest component
    (Shepperd's method: no square root of a small number, so no loss of accuracy)."""
    n = len(R)
    tr = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    cand = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    pick = np.argmax(cand, axis=1)
    q = np.empty((n, 4))
    for c in range(4):
        m = pick == c
        if not m.any():
            continue
        r = R[m]
        if c == 0:
            s = 2.0 * np.sqrt(1.0 + tr[m])
            q[m] = np.stack([0.25 * s, (r[:, 2, 1] - r[:, 1, 2]) / s,
                             (r[:, 0, 2] - r[:, 2, 0]) / s, (r[:, 1, 0] - r[:, 0, 1]) / s], 1)
            continue
        i = c - 1
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[:, i, i] - r[:, j, j] - r[:, k, k])
        v = np.empty((len(r), 4))
        v[:, 0] = (r[:, k, j] - r[:, j, k]) / s
        v[:, 1 + i] = 0.25 * s
        v[:, 1 + j] = (r[:, j, i] + r[:, i, j]) / s
        v[:, 1 + k] = (r[:, k, i] + r[:, i, k]) / s
        q[m] = v
    return q


#: A row is cleared by a box's face plane only when every vertex lies this far (m) beyond
#: it: rounding of metre-sized poses is ~1e-15 m; closer rows go to FCL as before.
FACE_SLACK = 1e-6


def beyond_a_face(checker, frames: Array, rows: Array, s: int, e: int,
                   slack: float = FACE_SLACK) -> Array:
    """Of `rows`, those where robot shape s lies wholly beyond one face plane of obstacle
    shape e (a box without a margin), every vertex more than `slack` beyond it - so the
    shape is more than `slack` from the box: no FCL test is needed there (`_outside_box`).

    Why: a UR5's upper arm passes 30 mm above the table in every posture of a transfer,
    and the broad phase's capsule around it overlaps the table: that pair cost one FCL
    test per sample (1500-2700 a path, about a third of the certificate)."""
    V = _corners(checker)[s]
    if not len(rows) or not checker._env_exact[e] or V is None:
        return np.zeros(len(rows), dtype=bool)
    rs = checker._rshapes[s]
    T = frames[rows, rs.link] @ rs.shape.T_link_shape
    n = len(rows)
    return _outside_box(V, T, np.broadcast_to(checker._env_R[e], (n, 3, 3)),
                        np.broadcast_to(checker._env_c[e], (n, 3)), checker._env_h[e], slack)


def _pair_apart(checker, frames: Array, rows: Array, a: int, b: int) -> Array:
    """Of `rows`, those where robot shape b lies wholly beyond one face plane of the box
    that holds shape a in its own frame, or a beyond one of b's: the pair does not touch
    there, no FCL test is needed. Why: a UR5's base and upper arm stay 16 mm apart along
    a whole path (the upper arm ~8 mm above the top of the base's box), and were tested at
    every sample: 1600-2700 FCL tests a path."""
    out = np.zeros(len(rows), dtype=bool)
    for x, y in ((a, b), (b, a)):
        V = _corners(checker)[y]
        left = rows[~out]
        if V is None or not len(left):
            continue
        rx, ry = checker._rshapes[x], checker._rshapes[y]
        R0, c0, h = _boxes(checker)[x]
        F = frames[left, rx.link]
        T = frames[left, ry.link] @ ry.shape.T_link_shape
        out[~out] = _outside_box(V, T, F[:, :3, :3] @ R0, F[:, :3, :3] @ c0 + F[:, :3, 3], h)
    return out


def _outside_box(V: Array, T: Array, Rb: Array, cb: Array, h: Array,
                 slack: float = FACE_SLACK) -> Array:
    """Per row: whether every point V (the vertex set of a shape, in its frame) posed by
    T (n, 4, 4) lies more than `slack` beyond one face plane of the box (n rows of
    rotation Rb, centre cb; half extents h along Rb's columns; `face_planes`).

    Why exact: a mesh is its triangles, each the convex hull of three of its vertices (a
    box: of its corners), so if every vertex lies beyond one face plane of a box, every
    point of the shape does, and whatever the box holds (on the other side) is not
    touched. The vertices are the mesh's own, those FCL tests (`_corners`); the boxes hold
    the shapes exactly (`segment_box.oriented_bounds`); nothing comes from the fast model."""
    out = np.zeros(len(T), dtype=bool)
    if len(T):
        c = np.ascontiguousarray
        vertices_beyond(c(T, dtype=float), c(Rb, dtype=float), c(cb, dtype=float),
                        c(h, dtype=float), c(V, dtype=float), slack, out)
    return out


_SIGNS = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def _boxes(checker) -> list[tuple[Array, Array, Array]]:
    """Per robot shape: the box that holds it in its link's frame (rotation, centre, half
    extents; `oriented_bounds`: exact for a box, the vertices' bounds for a mesh, the
    axis-aligned bounds of a round shape). Kept on the checker."""
    got = checker.__dict__.get("_shape_boxes")
    if got is None:
        from assistant.collision.segment_box import oriented_bounds

        got = []
        for rs in checker._rshapes:
            ob = oriented_bounds(rs.shape, np.eye(4))
            got.append((ob.R, ob.centre, ob.half))
        checker.__dict__["_shape_boxes"] = got
    return got


def _corners(checker) -> list[Array | None]:
    """Per robot shape: the points whose convex hull holds it, or None for a round shape:
    a mesh's own vertices (a UR5 link's 230-600), a box's eight corners. Kept on the
    checker."""
    got = checker.__dict__.get("_shape_corners")
    if got is None:
        from assistant.robots.model import ShapeKind

        got = []
        for rs in checker._rshapes:
            sh = rs.shape
            if sh.kind == ShapeKind.BOX:
                got.append(_SIGNS * (np.asarray(sh.size, dtype=float) / 2))
            elif sh.kind == ShapeKind.MESH and sh.mesh is not None and len(sh.mesh.vertices):
                got.append(np.ascontiguousarray(sh.mesh.vertices, dtype=np.float64))
            else:
                got.append(None)
        checker.__dict__["_shape_corners"] = got
    return got


def _env_distance(checker, pose: _Poser, k: int, i: int, es) -> float:
    """FCL distance (m) of robot shape i posed at sample k to an obstacle shape, less the
    obstacle's margin (<= 0: touching)."""
    d = float(fcl.distance(pose(i, k), es.obj, checker._dreq, fcl.DistanceResult())) - es.margin
    if d <= 0.0 and not checker._touches_env(i, es):
        d = 1e-9  # touching within FCL's tolerance, not overlapping: free, no cover
    return d


def _env_touches(checker, pose: _Poser, k: int, i: int, es) -> bool:
    pose(i, k)
    return checker._touches_env(i, es)


def _distance(checker, pose: _Poser, k: int, a: int, b: int) -> float:
    """FCL distance (m) of robot shapes a and b posed at sample k (<= 0: touching)."""
    oa, ob = pose(a, k), pose(b, k)
    d = float(fcl.distance(oa, ob, checker._dreq, fcl.DistanceResult()))
    if d <= 0.0 and not fcl.collide(oa, ob, checker._req, fcl.CollisionResult()):
        d = 1e-9  # touching within FCL's tolerance, not overlapping: free, no cover
    return d


def _radii(checker) -> Array:
    """(dof, shapes): `shape_radii` of every robot shape of the checker, kept on it."""
    R = checker.__dict__.get("_shape_radii")
    if R is None:
        R = np.stack([shape_radii(checker.robot, rs.link, rs.shape)
                      for rs in checker._rshapes], axis=1).reshape(checker.robot.dof, -1)
        checker.__dict__["_shape_radii"] = R
    return R
