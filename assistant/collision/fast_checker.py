"""`FastChecker`: the `CollisionChecker` interface on the fast conservative model
(`fast_model`), for searching and scoring.

A `FastChecker` is a `CollisionChecker` of the capsule robot against the obstacle boxes in
which FCL never runs for obstacles: a pair the capsule-to-box distance cannot clear is a
contact (`PRUNE_APART` 0, the capsules padded by `capsule_cover.PAD`). Every method the
planners use (batches, motion samples with margins, motion and path checks, clearances)
works as on the exact checker, in the same compiled passes.

Self pairs are the exact checker's, capsule by capsule, never sampled again - with one
exception. Links two joints apart sit side by side in every posture (a UR5's shoulder
housing 0-3 cm above its base, its wrists 1-3 cm apart), and capsules around short fat
housings overlap there in most postures: such a *close* pair (`close_pairs`) would make the
model call most postures a collision. A close pair is left out of the compiled pass and
decided after it by its joint-space table (`pair_tables`: a lower bound of its distance
from the two joints it depends on), and by FCL on the real shapes where that bound is not
positive; its other pairs, and every obstacle, stay closed-form.

Get one with `CollisionChecker.fast` (built once per checker, None for a robot the model
cannot pose).
"""

from __future__ import annotations

import hashlib
import threading

import fcl
import numpy as np

from assistant.collision.broad_phase import prune_round_pairs
from assistant.collision.capsule_cover import Capsule
from assistant.collision.capsule_phase import CERTIFIED, FREE, capsule_rows, capsule_samples
from assistant.collision.certify_path import FACE_SLACK, beyond_a_face
from assistant.collision.exact_checker import ExactChecker
from assistant.collision.fast_model import FastRobot, fast_obstacles
from assistant.collision.fcl_shapes import fcl_geometry, fcl_transform
from assistant.collision.motion_rows import motion_marks, rows_inside
from assistant.collision.pair_tables import PairTable, axis_capsules, pair_table
from assistant.collision.prune_numpy import segment_box_distances
from assistant.collision.reports import MotionCheck
from assistant.robots.model import CollisionShape

Array = np.ndarray

#: A self pair is close when its capsules overlap, with the real shapes apart, in more
#: than this share of the uniform postures the real pair is apart in.
CLOSE_SHARE = 0.05
_CLOSE_CACHE: dict[str, frozenset[int]] = {}
_CLOSE_LOCK = threading.Lock()


class FastChecker(ExactChecker):
    """The fast model behind the checker interface (module docstring)."""

    PRUNE_APART = 0.0

    def __init__(self, exact: ExactChecker, robot: FastRobot,
                 close: frozenset[int] | None = None):
        caps_of: dict[int, list[int]] = {}
        for f, i in enumerate(robot.owner.tolist()):
            caps_of.setdefault(i, []).append(f)
        self._caps_of = caps_of
        self.exact = exact
        self._all_pairs = [(fa, fb, e) for e, (a, b) in enumerate(exact._self_pairs)
                           for fa in caps_of.get(a, ()) for fb in caps_of.get(b, ())]
        self._given_pairs = [(fa, fb) for fa, fb, _ in self._all_pairs]
        #: Per self pair here: the exact checker's pair it covers.
        self.exact_pair = np.array([e for _, _, e in self._all_pairs], dtype=np.int64)
        super().__init__(robot, fast_obstacles(exact.obstacles, robot.G),
                         self_collision=bool(self._given_pairs), max_step=exact.max_step,
                         chunk=exact.chunk)
        self._exact_objs: dict[int, fcl.CollisionObject] = {}
        self._exact_T: dict[int, Array] = {}
        self._req = fcl.CollisionRequest()
        if close is None:
            close = close_pairs(self)
        self.close = close
        if close:  # the compiled pass without them; `_close_hits` after it
            self._set_self_pairs([(fa, fb) for fa, fb, e in self._all_pairs
                                  if e not in close])
        self._tables = {e: self._table(e) for e in sorted(close)}
        floor = first_link_floor(self)
        if floor > 0.0:
            self._env_from, self._env_floor = 2, floor

    def _self_shape_pairs(self) -> list[tuple[int, int]]:
        return list(self._given_pairs)

    def _set_self_pairs(self, pairs: list[tuple[int, int]]) -> None:
        """The compiled pass's self pairs (the sphere pairs and segment pairs it reads)."""
        self._self_pairs = list(pairs)
        sp_a, sp_b, sp_pair = [], [], []
        for pi, (a, b) in enumerate(self._self_pairs):
            for x in np.flatnonzero(self._sph_shape == a):
                for y in np.flatnonzero(self._sph_shape == b):
                    sp_a.append(x)
                    sp_b.append(y)
                    sp_pair.append(pi)
        self._sp_a = np.asarray(sp_a, dtype=np.int64)
        self._sp_b = np.asarray(sp_b, dtype=np.int64)
        self._sp_pair = np.asarray(sp_pair, dtype=np.int64)
        self._pair_a = np.array([a for a, _ in self._self_pairs], dtype=np.int64)
        self._pair_b = np.array([b for _, b in self._self_pairs], dtype=np.int64)

    def _table(self, e: int) -> PairTable | None:
        """The joint-space table of close pair e, if its links are two or three joints
        apart (`pair_tables`)."""
        a, b = self.exact._self_pairs[e]
        ra, rb = self.exact._rshapes[a], self.exact._rshapes[b]
        gap = rb.link - ra.link
        if gap not in (2, 3):
            return None
        rob = self.robot
        root = getattr(rob.base_robot, "root_description", rob.base_robot.description_hash)
        key = (root(), rob.description_hash().rsplit(":fast:", 1)[-1], ra.link,
               self.exact._shape_index_in_link(a), rb.link, self.exact._shape_index_in_link(b))
        F = rob.dh_fixed_stack()
        la = ra.link
        A = np.eye(4) if la == 0 else F[la - 1]
        caps_a = [(c.a, c.b, c.r) for c in (rob.capsules[f] for f in self._caps_of[a])]
        caps_b = [(c.a, c.b, c.r) for c in (rob.capsules[f] for f in self._caps_of[b])]
        # a node holds distances of these capsules: a table kept for others is not theirs
        key += (_digest(caps_a + caps_b),)
        if gap == 2:
            C = np.eye(4)
            pieces = [(rb.shape, rob.to_fast[rb.link] @ rb.shape.T_link_shape)]
        else:  # what the last link sweeps about its own axis
            C = F[la + 1]
            caps_b = axis_capsules(caps_b)
            pieces = [(Capsule(ca, cb, cr).shape(), Capsule(ca, cb, cr).shape().T_link_shape)
                      for ca, cb, cr in caps_b]
            pieces = [(CollisionShape(sh.kind, sh.size), T) for sh, T in pieces]
        return pair_table(key, lambda: PairTable(
            A, F[la], C, la, ra.shape, rob.to_fast[la] @ ra.shape.T_link_shape, pieces,
            caps_a, caps_b, rob.limits.lower, rob.limits.upper))

    def _close_hits(self, Q: Array, rows: Array, motion: Array | None = None,
                    ) -> tuple[Array, Array]:
        """(hit, bound) for the rows of Q: a close pair's table bound is not positive and
        FCL finds its real shapes touching; bound: the smallest table bound (m). With
        `motion` (each row's motion, rows in order) only each motion's first hit matters:
        FCL is asked row by row from each motion's first uncertain row, and the rows after
        a motion's first hit are left unasked (the caller counts them invalid)."""
        hit = np.zeros(len(rows), dtype=bool)
        bound = np.full(len(rows), np.inf)
        if not self.close or not len(rows):
            return hit, bound
        Qr = Q[rows]
        lbs = []
        for e, table in self._tables.items():
            lb = np.full(len(rows), -np.inf) if table is None else table.bounds(Qr)
            lbs.append((e, lb))
            bound = np.minimum(bound, lb)
        unsure = np.flatnonzero(bound <= 0.0)
        if not len(unsure):
            return hit, bound
        m = (np.zeros(len(rows), dtype=np.int64) if motion is None
             else np.asarray(motion)[rows])
        while len(unsure):
            if motion is None:
                ask = unsure
            else:  # each motion's first unsure row
                ask = unsure[np.r_[True, m[unsure][1:] != m[unsure][:-1]]]
            frames = self.robot.batch_link_poses(Qr[ask])
            for j, i in enumerate(ask.tolist()):
                hit[i] = any(lb[i] <= 0.0 and self._exact_collide(frames[j], e)
                             for e, lb in lbs)
            if motion is None:
                break
            done = m[ask[hit[ask]]]  # motions with their first hit (the caller ends them)
            unsure = unsure[~np.isin(unsure, ask) & ~np.isin(m[unsure], done)]
        return hit, bound

    def is_valid_samples(self, Q: Array, groups: Array | None = None, *,
                         first_only: bool = False, known_invalid: Array | None = None,
                         ) -> Array:
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        ok = super().is_valid_samples(Q, groups, first_only=first_only,
                                      known_invalid=known_invalid)
        g = np.zeros(len(Q), dtype=np.int64) if groups is None else np.asarray(groups)
        motion = motion_marks(np.ascontiguousarray(g, dtype=np.int64))[2] if len(Q) else g
        if first_only and not ok.all():  # the rows before each motion's first invalid one
            bad = np.flatnonzero(~ok)
            first_bad = np.full(int(motion[-1]) + 1, len(Q))
            np.minimum.at(first_bad, motion[bad], bad)
            rows = np.flatnonzero(ok & (np.arange(len(Q)) < first_bad[motion]))
        else:
            rows = np.flatnonzero(ok)
        if len(rows):
            ok[rows] = ~self._close_hits(Q, rows, motion if first_only else None)[0]
        if first_only and not ok.all():
            bad = np.flatnonzero(~ok)
            first_bad = np.full(int(motion[-1]) + 1, len(Q))
            np.minimum.at(first_bad, motion[bad], bad)
            ok &= np.arange(len(Q)) <= first_bad[motion]
        return ok

    def is_valid_batch_margin(self, Q: Array, certified: Array | None = None,
                              ) -> tuple[Array, Array]:
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        ok, margin = super().is_valid_batch_margin(Q, certified)
        rows = np.flatnonzero(ok)
        if len(rows):
            hit, bound = self._close_hits(Q, rows)
            ok[rows] = ~hit
            margin[rows] = np.where(hit, np.nan, np.fmin(margin[rows], bound))
        return ok, margin

    @property
    def fast(self) -> ExactChecker:
        return self

    def _caps(self) -> tuple:
        """The capsule pass's model arrays (`capsule_phase`), in its argument order."""
        return (self._shape_link, self._seg_a, self._seg_b, self._seg_r, self._env_from,
                self._env_R, self._env_c, self._env_h, self._pair_a, self._pair_b)

    def _margin_rows(self, Q: Array) -> tuple[Array, Array]:
        """(hit, margin) of each row: its smallest capsule distance (`capsule_rows`)."""
        Q = np.ascontiguousarray(Q, dtype=float)
        frames, ready, chain = self._frames_to_fill(Q)
        gap = capsule_rows(frames, ready, chain, Q, *self._caps())
        return gap <= 0.0, gap

    def _exact_samples(self, Q: Array, groups: Array | None, first_only: bool,
                       known_invalid: Array | None) -> Array:
        """The samples by the capsule pass (`capsule_samples`, margins certifying the
        samples near a checked one); the close pairs come after it (`is_valid_samples`)."""
        Q = np.ascontiguousarray(np.atleast_2d(Q), dtype=float)
        g = np.zeros(len(Q), dtype=np.int64) if groups is None else np.asarray(groups)
        first, last, _ = motion_marks(np.ascontiguousarray(g, dtype=np.int64))
        lim = self.robot.limits
        inside = rows_inside(Q, lim.lower, lim.upper)
        frames, ready, chain = self._frames_to_fill(Q)
        status, _ = capsule_samples(frames, ready, chain, Q, inside, first, last,
                                    self.CERTIFY_STRIDE, self._radii, *self._caps(),
                                    first_only)
        ok = (status == FREE) | (status == CERTIFIED)
        return ok if known_invalid is None else ok & ~known_invalid

    def min_clearance_along(self, path, max_step: float = 0.01) -> float:
        """The capsule model's smallest distance to an obstacle along the path, sampled as
        `MotionChecks.min_clearance_along` samples it (every `max_step` of arm travel): one
        compiled pass of capsule-to-box distances (`capsule_rows` without self pairs), and
        the links the model leaves out of its obstacle checks at their proven floor. A lower
        bound of the real clearance; <= 0 where a capsule meets a box."""
        if not self._env:
            return float("inf")
        P = np.asarray(path, dtype=float).reshape(-1, self.robot.dof)
        if len(P) == 1:
            Q = P
        else:
            S, Fr, _ = self._path_samples(P, max_step)
            Q = P[S] + Fr[:, None] * (P[S + 1] - P[S])
        Q = np.ascontiguousarray(Q)
        frames, ready, chain = self._frames_to_fill(Q)
        none = np.zeros(0, dtype=np.int64)
        caps = self._caps()[:8]
        gap = capsule_rows(frames, ready, chain, Q, *caps, none, none)
        return float(min(float(gap.min()), self._env_floor))

    def keeps_clearance(self, path, target: float, max_step: float = 0.01) -> bool:
        """Whether the real shapes stay at least `target` (m) from every obstacle along the
        path (sampled as `min_clearance_along`) - exactly, at a fraction of the cost of the
        exact clearance: samples whose capsule clearance reaches the target pass; at the
        others, each (shape, obstacle) pair whose capsule bound is below the target is
        measured by FCL, nearest bound first, and the first below the target fails it.
        For a decision the fast model's lower bound alone would refuse (its capsules reach
        up to a few centimetres beyond a UR's housings)."""
        if not self._env:
            return True
        P = np.asarray(path, dtype=float).reshape(-1, self.robot.dof)
        if not self.exact._has_mesh:  # capsules and spheres: the model is the shapes
            return self.min_clearance_along(P, max_step) >= target
        if len(P) == 1:
            Q = P
        else:
            S, Fr, _ = self._path_samples(P, max_step)
            Q = P[S] + Fr[:, None] * (P[S + 1] - P[S])
        Q = np.ascontiguousarray(Q)
        if self._env_floor < target:  # a link left out of the checks comes closer
            return False
        frames, ready, chain = self._frames_to_fill(Q)
        none = np.zeros(0, dtype=np.int64)
        gap = capsule_rows(frames, ready, chain, Q, *self._caps()[:8], none, none)
        near = np.flatnonzero(gap < target)
        near = near[np.argsort(gap[near], kind="stable")]  # the nearest samples first
        if not len(near):
            return True
        open_ = self._face_open(Q[near], target)
        still = open_.reshape(len(near), -1).any(axis=1)
        near, open_ = near[still], open_[still]
        for i in range(0, len(near), 16):
            if not self._rows_keep(Q, frames, near[i:i + 16], target, open_[i:i + 16]):
                return False
        return True

    def _face_open(self, Qn: Array, target: float) -> Array:
        """(rows, shapes, obstacles): False where the real shape lies wholly more than the
        target beyond a face plane of the obstacle's exact box - that pair keeps the
        clearance, proven on the real vertices (`certify_path.beyond_a_face`). Why: a
        transfer that keeps it measured every pair the capsules left near - in numpy and
        by FCL - most of a UR10 query that ends in the via form; this test is compiled and
        clears nearly all of them."""
        ex = self.exact
        frames_x = ex._link_frames(Qn)
        shapes = np.unique(self.robot.owner[np.flatnonzero(self._shape_link >= self._env_from)])
        rows = np.arange(len(Qn))
        out = np.ones((len(Qn), len(shapes), len(self._env)), dtype=bool)
        for si, sh in enumerate(shapes.tolist()):
            for e in range(len(self._env)):
                out[:, si, e] = ~beyond_a_face(ex, frames_x, rows, sh, e, target + FACE_SLACK)
        return out

    def _rows_keep(self, Q: Array, frames: Array, rows: Array, target: float,
                   open_: Array) -> bool:
        """`keeps_clearance` at the given samples (frames posed); `open_` (rows, shapes,
        obstacles): the pairs no face plane has cleared (`_face_open`)."""
        r_i, s_i, e_i = np.nonzero(open_)
        if not len(r_i):
            return True
        # the capsule bound of each open (sample, shape, obstacle): its capsules' nearest
        caps = np.flatnonzero(self._shape_link >= self._env_from)
        owner = self.robot.owner[caps]  # the exact shape each capsule covers
        shapes = np.unique(owner)
        per = [caps[owner == sh] for sh in shapes]
        width = max(len(c) for c in per)
        cap_of = np.full((len(shapes), width), -1, dtype=np.int64)
        for si, c in enumerate(per):
            cap_of[si, :len(c)] = c
        k_t, k_c = np.nonzero(cap_of[s_i] >= 0)  # (open triple, one of its capsules)
        c = cap_of[s_i[k_t], k_c]
        e = e_i[k_t]
        F = frames[rows[r_i[k_t]], self._shape_link[c]]  # (K, 4, 4)
        A = np.einsum("kij,kj->ki", F[:, :3, :3], self._seg_a[c]) + F[:, :3, 3]
        B = np.einsum("kij,kj->ki", F[:, :3, :3], self._seg_b[c]) + F[:, :3, 3]
        R, ctr = self._env_R[e], self._env_c[e]
        d = segment_box_distances(np.einsum("ki,kij->kj", A - ctr, R),
                                  np.einsum("ki,kij->kj", B - ctr, R), self._env_h[e])
        d -= self._seg_r[c]
        bound = np.full(len(r_i), np.inf)
        np.minimum.at(bound, k_t, d)
        near = np.flatnonzero(bound < target)
        if not len(near):
            return True
        r_i, s_i, e_i = r_i[near], s_i[near], e_i[near]
        ex = self.exact
        frames_x = ex._link_frames(Q[rows])
        order = np.argsort(bound[near], kind="stable")
        for j in order.tolist():
            rs = ex._rshapes[int(shapes[s_i[j]])]
            rs.obj.setTransform(fcl_transform(frames_x[r_i[j], rs.link] @ rs.shape.T_link_shape))
            es = ex._env[int(e_i[j])]
            if ex._pair_distance(rs.obj, es.obj)[0] - es.margin < target:
                return False
        return True

    def check_motion(self, q0: Array, q1: Array, max_step: float | None = None) -> MotionCheck:
        """`MotionChecks.check_motion` without the contact report (it would pose the
        capsules through FCL once more): the planners ask only where a motion fails."""
        q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
        n = self.motion_samples(q0, q1, max_step)
        f = np.arange(0, n + 1) / n
        ok = self.is_valid_samples(q0[None] + f[:, None] * (q1 - q0)[None], first_only=True)
        if ok.all():
            return MotionCheck(None, n)
        return MotionCheck(float(f[int(np.argmin(ok))]), n)

    def in_collision_batch(self, Q: Array) -> Array:
        """One compiled pass (`broad_phase.margin_rows`) decides every row, the close
        pairs' tables after it."""
        Q = np.ascontiguousarray(np.atleast_2d(np.asarray(Q, dtype=float)))
        if not len(Q):
            return np.zeros(0, dtype=bool)
        hit = self._margin_rows(Q)[0]
        rows = np.flatnonzero(~hit)
        if len(rows):
            hit[rows] = self._close_hits(Q, rows)[0]
        return hit

    def _first_contacts(self, frames: Array, env_c: Array, self_c: Array,
                        motions: Array | None = None) -> Array:
        """A row handed here has a pair within the model's distance: a contact."""
        return np.ones(len(frames), dtype=bool)

    def _exact_collide(self, frames: Array, e: int) -> bool:
        """FCL on the real shapes of the exact checker's self pair e, posed from this
        model's link frames."""
        a, b = self.exact._self_pairs[e]
        return bool(fcl.collide(self._posed(frames, a), self._posed(frames, b), self._req,
                                fcl.CollisionResult()))

    def _posed(self, frames: Array, i: int) -> fcl.CollisionObject:
        obj = self._exact_objs.get(i)
        rs = self.exact._rshapes[i]
        if obj is None:
            obj = fcl.CollisionObject(fcl_geometry(rs.shape))
            self._exact_objs[i] = obj
            self._exact_T[i] = self.robot.to_fast[rs.link] @ rs.shape.T_link_shape
        T = frames[rs.link] @ self._exact_T[i]
        obj.setTransform(fcl.Transform(np.ascontiguousarray(T[:3, :3]),
                                       np.ascontiguousarray(T[:3, 3])))
        return obj


def _digest(caps: list[tuple[Array, Array, float]]) -> str:
    """A short hash of capsules' numbers (a table key's part)."""
    h = hashlib.sha256()
    for a, b, r in caps:
        h.update(np.concatenate([a, b, [r]]).astype(float).tobytes())
    return h.hexdigest()[:16]


def close_pairs(fast: FastChecker, n: int = 600, seed: int = 7) -> frozenset[int]:
    """The exact checker's self pairs (indices) whose capsules overlap while the real
    shapes are apart in more than `CLOSE_SHARE` of the pair's free postures among `n`
    uniform ones (cached per robot
    description: one sweep per robot and tool)."""
    # the answer is indices into the exact checker's self pairs: another checker of the
    # same robot may check other pairs (none, or a link subset's)
    key = f"{fast.robot.description_hash()}:{fast.exact._self_pairs}"
    with _CLOSE_LOCK:
        if key in _CLOSE_CACHE:
            return _CLOSE_CACHE[key]
    n_exact = len(fast.exact._self_pairs)
    if not n_exact or not len(fast._self_pairs):
        return frozenset()
    rng = np.random.default_rng(seed)
    lim = fast.robot.limits
    Q = rng.uniform(lim.lower, lim.upper, size=(n, fast.robot.dof))
    frames = np.ascontiguousarray(fast.robot.batch_link_poses(Q))
    env_c, self_c, _ = fast._candidates(frames)
    prune_round_pairs(frames, np.arange(n), env_c, self_c, fast._shape_link, fast._seg_a,
                      fast._seg_b, fast._seg_r, fast._env_R, fast._env_c, fast._env_h,
                      fast._pair_a, fast._pair_b, 0.0)
    overlap = np.zeros((n, n_exact), dtype=bool)
    for p in range(self_c.shape[1]):
        overlap[:, fast.exact_pair[p]] |= self_c[:, p]
    false = np.zeros(n_exact)
    apart = np.full(n_exact, float(n))  # postures with the real pair apart
    for e in range(n_exact):
        rows = np.flatnonzero(overlap[:, e])
        touch = sum(fast._exact_collide(frames[k], e) for k in rows.tolist())
        false[e] = len(rows) - touch
        apart[e] -= touch
    # a share of the postures the pair is apart in: a pair that folds onto itself in most
    # of its range (a KUKA's upper arm and forearm) is close all the same where it is not
    out = frozenset(int(e) for e in np.flatnonzero(false / np.maximum(apart, 1.0)
                                                   > CLOSE_SHARE))
    with _CLOSE_LOCK:
        _CLOSE_CACHE[key] = out
    return out


#: Largest rounding (m) of the first link's clearance sweep: samples this close in arm
#: travel of that link (`first_link_floor`).
SWEEP_TOL = 5e-4


def first_link_floor(fast: FastChecker) -> float:
    """A lower bound (m) of the first moving link's distance to every obstacle over all its
    postures, or 0 when it may touch one.

    Why: that link turns about joint 1's axis only (a UR's shoulder, 24 mm above the table
    it stands on), so its distance to an obstacle depends on q1 alone; its capsules reach
    the table in every posture (a capsule's round end under a flat housing), and the model
    would call every posture a collision. Swept over q1, its real shapes (FCL, exact) stay
    clear of each obstacle its capsules can reach: the model then leaves that link out of
    its obstacle checks (`CollisionChecker._env_from`) and counts this bound in every
    clearance. Samples are `SWEEP_TOL` apart in the link's own travel, and each distance
    less that tolerance bounds its neighbourhood."""
    exact, robot = fast.exact, fast.robot
    shapes = [i for i, rs in enumerate(exact._rshapes) if rs.link == 1]
    if not exact._env or not shapes:
        return np.inf if not exact._env else 0.0
    caps = [c for c, o in zip(robot.capsules, robot.owner.tolist(), strict=True)
            if exact._rshapes[o].link == 1]
    reach = max(max(np.hypot(*c.a[:2]), np.hypot(*c.b[:2])) + c.r for c in caps)
    lo, hi = float(robot.limits.lower[0]), float(robot.limits.upper[0])
    if hi - lo > 2.0 * np.pi:
        lo, hi = 0.0, 2.0 * np.pi
    n = max(2, int(np.ceil((hi - lo) * reach / SWEEP_TOL)) + 1)
    Q = np.zeros((n, robot.dof))
    Q[:, 0] = np.linspace(lo, hi, n)
    frames = np.ascontiguousarray(robot.batch_link_poses(Q))
    env_c, _, _ = fast._candidates(frames)
    near = np.flatnonzero(env_c[:, [i for i, rs in enumerate(fast._rshapes) if rs.link == 1]]
                          .any(axis=(0, 1)))  # obstacles the link's capsules reach
    # the others: their boxes' distance to the link's covering spheres
    far = np.setdiff1d(np.arange(len(fast._env)), near)
    s1 = np.flatnonzero(fast._sph_link == 1)
    floor = np.inf
    if len(far) and len(s1):
        F = frames[:, 1, :3]  # (n, 3, 4)
        C = np.einsum("nij,sj->nsi", F[:, :, :3], fast._sph_local[s1]) + F[:, None, :, 3]
        lo_b, hi_b = fast._env_lo[far], fast._env_hi[far]
        d = C[:, :, None, :] - np.clip(C[:, :, None, :], lo_b, hi_b)
        gaps = np.sqrt((d * d).sum(axis=-1)) - fast._sph_r[s1][None, :, None]
        floor = float(gaps.min())
    if len(near):
        dreq = fcl.DistanceRequest()
        env = [fcl.CollisionObject(fcl_geometry(s), fcl.Transform(
               np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3])))
               for s, T in _exact_obstacles_in(fast)]
        margin = [float(s.margin) for s, _ in _exact_obstacles_in(fast)]
        for k in range(n):
            for i in shapes:
                a = fast._posed(frames[k], i)
                for e in near.tolist():
                    d = float(fcl.distance(a, env[e], dreq, fcl.DistanceResult())) - margin[e]
                    floor = min(floor, d)
                    if floor <= SWEEP_TOL:
                        return 0.0
    # beyond the samples: the clearance of the capsules the link never brings near
    return float(floor - SWEEP_TOL)


def _exact_obstacles_in(fast: FastChecker) -> list:
    """(shape, pose in the fast model's frame) of every obstacle shape, in the exact
    checker's order."""
    Ginv = np.linalg.inv(fast.robot.G)
    out = []
    for ob in fast.exact.obstacles:
        T_ob = np.asarray(ob.T_base_object, dtype=float)
        for s in ob.collision:
            out.append((s, Ginv @ T_ob @ s.T_link_shape))
    return out
