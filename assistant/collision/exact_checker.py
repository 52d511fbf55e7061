"""Exact collision checking of the robot against the cell and itself (python-fcl): the checks
that `CollisionChecker` (checker.py) puts behind its fast model and `FastChecker` runs on the
capsule robot.

Every answer comes from FCL's exact narrow phase; the broad phase only decides which pairs
cannot touch. It covers each link shape with a few spheres (`fcl_shapes.covering_spheres`)
and each obstacle with its axis-aligned box, over many configurations in one compiled loop
(`broad_phase`), so a batch of configurations in free space costs microseconds and only the
pairs that might touch reach FCL. Because the bounds are conservative the result equals the
brute-force FCL answer (checked by the tests and `benchmarks/collision.py`).

Self-collision checks the pairs of the robot's one rule (`self_rule.self_collision_rule`:
not adjacent, not always or never touching over random postures), the rule teach, plan,
jog and the world model share.

An obstacle shape with a margin (`CollisionShape.margin`, a big CAD part's proxy) counts
everything within the margin as the obstacle: its bounds grow by the margin, and FCL tests
it against the robot shape grown by the margin (`fcl_shapes.inflated_geometry`), so the
answer is still one FCL collision test; clearances to it are FCL's distance less the margin.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable
from dataclasses import dataclass

import fcl
import numpy as np

from assistant.collision.bounding_capsule import mesh_capsule
from assistant.collision.broad_phase import (
    ASK_FCL,
    CERTIFIED,
    FREE,
    OUTSIDE_LIMITS,
    certify_samples,
    margin_rows,
    prune_round_pairs,
    sphere_broad_phase,
)
from assistant.collision.fcl_shapes import (
    covering_spheres,
    fcl_geometry,
    fcl_transform,
    inflated_geometry,
    world_aabb,
)
from assistant.collision.motion_checks import MotionChecks
from assistant.collision.motion_rows import (
    motion_marks,
    rows_before_first_bad,
    rows_inside,
    valid_before_first_bad,
)
from assistant.collision.reports import (
    CollisionReport,
    Contact,
    ObstacleView,
)
from assistant.collision.segment_box import OrientedBox, axis_segment, oriented_bounds
from assistant.collision.self_rule import SelfCollisionRule, link_words, self_collision_rule
from assistant.collision.shape_poses import shape_poses
from assistant.robots.model import CollisionShape, Robot, ShapeKind

Array = np.ndarray


@dataclass
class _RobotShape:
    link: int
    shape: CollisionShape
    obj: fcl.CollisionObject


@dataclass
class _EnvShape:
    owner: str
    obj: fcl.CollisionObject
    #: Everything within this distance (m) of the shape counts as the obstacle.
    margin: float = 0.0


class ExactChecker(MotionChecks):
    """Robot vs obstacles (+ self) for one configuration, a batch, a motion, or a clearance.

    Not thread-safe (FCL objects are re-posed in place): give each thread its own checker;
    building one is cheap next to the checks it will run.
    """

    #: Motions are checked every `max_step` of arm travel; `is_valid_samples` gives every
    #: this-many-th sample an exact check with a free margin, which then covers the samples
    #: around it (at `max_step` 5 mm, those up to 10 mm of travel away). The margins are
    #: small - the arm's own links stay 10-20 mm apart in many postures - so a short stride
    #: pays: on the planning benchmark's motion checks a stride of 4 saves ~17 % of the
    #: time of checking every sample, 3 about the same, 8 only half as much.
    CERTIFY_STRIDE = 4
    #: The clearance report bounds every this-many-th sample of a path with the covering
    #: spheres and the samples between from those by the arm's travel
    #: (`clearance_scan.pruned_clearance`); only samples whose bound is below the answer so
    #: far get frames and bounds of their own.
    CLEARANCE_STRIDE = 8
    #: Broad-phase pairs whose round shapes' axis segments prove them farther apart than
    #: this (m) never reach FCL (`broad_phase.prune_round_pairs`); nearer ones, and every
    #: pair with a mesh or box robot shape, FCL decides. 0.1 mm stays far above FCL's own
    #: tolerance, so the answers remain FCL's. On the planning benchmark's cells the bound
    #: clears ~80 % of the obstacle pairs the covering spheres pass.
    PRUNE_APART = 1e-4
    #: Most covering spheres per capsule or cylinder (`fcl_shapes.covering_spheres`).
    COVER_SPHERES = 6

    def __init__(
        self,
        robot: Robot,
        obstacles: Iterable[ObstacleView] = (),
        *,
        self_collision: bool = True,
        max_step: float = 0.005,
        chunk: int = 2048,
        pairs_of: ExactChecker | None = None,
    ):
        self.robot = robot
        self.max_step = float(max_step)
        self.chunk = chunk
        self._req = fcl.CollisionRequest()
        self._dreq = fcl.DistanceRequest(enable_nearest_points=True)
        self._sreq = fcl.DistanceRequest(enable_nearest_points=True,
                                         enable_signed_distance=True)
        self._link_names = [lk.name for lk in robot.links]
        self._radii = robot.arm_radii()
        # Robot shapes, and the spheres covering them (link frame).
        self._rshapes: list[_RobotShape] = []
        sph_c, sph_r, sph_owner = [], [], []
        for li, link in enumerate(robot.links):
            for shape in link.collision:
                idx = len(self._rshapes)
                self._rshapes.append(
                    _RobotShape(li, shape, fcl.CollisionObject(fcl_geometry(shape)))
                )
                c, r = covering_spheres(shape, self.COVER_SPHERES)
                sph_c.append(c)
                sph_r.append(r)
                sph_owner += [idx] * len(r)
        self._sph_local = np.ascontiguousarray(np.concatenate(sph_c) if sph_c else
                                               np.zeros((0, 3)), dtype=float)
        self._sph_r = np.ascontiguousarray(np.concatenate(sph_r) if sph_r else np.zeros(0),
                                           dtype=float)
        self._sph_shape = np.asarray(sph_owner, dtype=np.int64)
        self._sph_link = np.array([self._rshapes[i].link for i in sph_owner], dtype=np.int64)
        # Obstacles. The fixed base link takes part in self-collision only: an object that
        # overlaps the base is a placement error for the cell to report, not a motion issue.
        self._env: list[_EnvShape] = []
        lo, hi, obb, env_box = [], [], [], []
        self.obstacle_names: list[str] = []
        #: The obstacles as given (the fast model takes its boxes from them).
        self.obstacles: list[ObstacleView] = list(obstacles)
        for ob in self.obstacles:
            self.obstacle_names.append(ob.name)
            for shape in ob.collision:
                T = np.asarray(ob.T_base_object, dtype=float) @ shape.T_link_shape
                obj = fcl.CollisionObject(fcl_geometry(shape), fcl_transform(T))
                margin = float(shape.margin)
                if not (np.isfinite(margin) and margin >= 0.0):
                    raise ValueError(f"obstacle {ob.name!r}: a collision margin must be a "
                                     f"length >= 0, got {shape.margin!r}")
                self._env.append(_EnvShape(ob.name, obj, margin))
                a, b = world_aabb(shape, np.asarray(ob.T_base_object, dtype=float))
                lo.append(a)
                hi.append(b)
                box = oriented_bounds(shape, np.asarray(ob.T_base_object, dtype=float))
                obb.append(OrientedBox(box.R, box.centre, box.half + margin))
                env_box.append(shape.kind == ShapeKind.BOX and margin == 0.0)
        # Oriented boxes around the obstacles and the axis segments of the round robot
        # shapes: the clearance report's tight bounds (`segment_box`).
        self._env_R = np.array([o.R for o in obb]).reshape(-1, 3, 3)
        self._env_c = np.array([o.centre for o in obb]).reshape(-1, 3)
        self._env_h = np.array([o.half for o in obb]).reshape(-1, 3)
        # (mesh links: a capsule around the mesh, a bound only - `bounding_capsule`)
        segs = [axis_segment(rs.shape) or mesh_capsule(rs.shape) for rs in self._rshapes]
        self._seg_a = np.array([g[0] if g else np.full(3, np.nan) for g in segs]).reshape(-1, 3)
        self._seg_b = np.array([g[1] if g else np.full(3, np.nan) for g in segs]).reshape(-1, 3)
        self._seg_r = np.array([g[2] if g else np.nan for g in segs])
        self._seg_exact = np.array([rs.shape.kind in (ShapeKind.CAPSULE, ShapeKind.SPHERE)
                                    for rs in self._rshapes], dtype=bool)
        self._env_exact = np.array(env_box, dtype=bool)
        self._env_lo = np.array(lo).reshape(-1, 3) - 1e-9
        self._env_hi = np.array(hi).reshape(-1, 3) + 1e-9
        #: A checker of the robot this one views (a link subset): its self pairs among
        #: these links are the pairs here (the same rule's).
        self._pairs_of = pairs_of
        #: The robot's self-collision rule (None without self-collision checks) and its
        #: links in the operator's words (`CollisionReport.describe`).
        self.rule: SelfCollisionRule | None = None
        self.link_words = dict(zip(self._link_names, link_words(robot), strict=True))
        self._self_pairs = self._self_shape_pairs() if self_collision else []
        # Sphere pairs for the self broad phase.
        sp_a, sp_b, sp_pair = [], [], []
        for pi, (a, b) in enumerate(self._self_pairs):
            ia = np.nonzero(self._sph_shape == a)[0]
            ib = np.nonzero(self._sph_shape == b)[0]
            for x in ia:
                for y in ib:
                    sp_a.append(x)
                    sp_b.append(y)
                    sp_pair.append(pi)
        self._pair_a = np.array([a for a, _ in self._self_pairs], dtype=np.int64)
        self._pair_b = np.array([b for _, b in self._self_pairs], dtype=np.int64)
        self._round = ~np.isnan(self._seg_r)
        #: The DH chain's fixed parts when the robot is one (`RV2AJ.dh_fixed_stack`): the
        #: link frames of checked samples are then computed with the certification's
        #: bookkeeping (`motion_rows`), else by `robot.batch_link_poses`.
        hook = getattr(robot, "dh_fixed_stack", None)
        self._chain_F = hook() if hook is not None else None
        self._sp_a = np.asarray(sp_a, dtype=np.int64)
        self._sp_b = np.asarray(sp_b, dtype=np.int64)
        self._sp_pair = np.asarray(sp_pair, dtype=np.int64)
        # Each robot shape's link and pose in it, for posing many shapes in one product.
        self._shape_link = np.array([rs.link for rs in self._rshapes], dtype=np.int64)
        self._shape_T = (np.stack([rs.shape.T_link_shape for rs in self._rshapes])
                         if self._rshapes else np.zeros((0, 4, 4)))
        #: Links below this one are never checked against obstacles: the fixed base (the
        #: cell reports an overlap), and in the fast model a link it proved clear in every
        #: posture (`fast_checker`).
        self._env_from = 1
        #: A lower bound (m) of those links' distance to every obstacle (`min_clearance_along`).
        self._env_floor = np.inf
        self._fast_model: ExactChecker | None | bool = False  # `fast`: not built yet
        #: Mesh robots (URDF arms) ask the fast model first (`fast_prefilter`).
        self._has_mesh = any(rs.shape.kind == ShapeKind.MESH for rs in self._rshapes)
        self._frame_fix: tuple[Array, Array] | None = None  # `_link_frames`
        #: False in the view `exact_only` returns: FCL and the robot's own kinematics only.
        self._use_fast = True
        #: Robot shapes grown by an obstacle's margin, by (shape index, margin), made when
        #: first needed (`_grown`).
        self._grown_objs: dict[tuple[int, float], fcl.CollisionObject] = {}

    def exact_only(self) -> ExactChecker:
        """This checker without the fast model: its own broad phase and FCL on the shapes
        posed by the robot's own kinematics (not the fast model's compiled chain). What
        certifies a finished path, so a fault of the fast model cannot pass one; the
        same as this checker for a robot of primitive shapes (it asks no fast model)."""
        if not self._has_mesh:
            return self
        view = copy.copy(self)
        view._use_fast = False
        view._fast_model = None
        view._frame_fix = None
        return view

    @property
    def fast(self) -> ExactChecker | None:
        """The fast conservative model behind this checker (`CollisionChecker.fast`); none
        here: the exact checks alone."""
        return None

    def _grown(self, i: int, margin: float) -> fcl.CollisionObject:
        """Robot shape i grown by `margin` (unposed; see `fcl_shapes.inflated_geometry`)."""
        key = (i, margin)
        obj = self._grown_objs.get(key)
        if obj is None:
            obj = fcl.CollisionObject(inflated_geometry(self._rshapes[i].shape, margin))
            self._grown_objs[key] = obj
        return obj

    def _touches_env(self, i: int, es: _EnvShape) -> bool:
        """Robot shape i (posed) against an obstacle shape, the obstacle's margin counted."""
        a = self._rshapes[i].obj
        if es.margin > 0.0:
            g = self._grown(i, es.margin)
            g.setTransform(a.getTransform())
            a = g
        return bool(fcl.collide(a, es.obj, self._req, fcl.CollisionResult()))

    @property
    def self_pairs(self) -> list[tuple[str, str]]:
        """The self-collision pairs checked, as (link name, link name), one per shape pair."""
        return [(self._link_names[self._rshapes[a].link], self._link_names[self._rshapes[b].link])
                for a, b in self._self_pairs]

    @property
    def self_shape_pairs(self) -> list[tuple[int, int, int, int]]:
        """The same as (link index, shape index in link, link index, shape index in link)."""
        out = []
        for a, b in self._self_pairs:
            ra, rb = self._rshapes[a], self._rshapes[b]
            out.append((ra.link, self._shape_index_in_link(a), rb.link,
                        self._shape_index_in_link(b)))
        return out

    def _shape_index_in_link(self, i: int) -> int:
        link = self._rshapes[i].link
        return sum(1 for k in range(i) if self._rshapes[k].link == link)

    # ------------------------------------------------------------------ self-collision pairs
    def _self_shape_pairs(self) -> list[tuple[int, int]]:
        """The shape pairs the robot's one self-collision rule checks (`self_rule`), as
        indices into this checker's shapes (a view of some links keeps the pairs among
        them, from the rule or from the checker of the robot it views)."""
        index = {(rs.link, self._shape_index_in_link(i)): i
                 for i, rs in enumerate(self._rshapes)}
        if self._pairs_of is not None:
            self.rule = self._pairs_of.rule
            chosen = self._pairs_of.self_shape_pairs
        else:
            self.rule = self_collision_rule(self.robot)
            assert self.rule is not None
            chosen = self.rule.shape_pairs
        return [(index[(la, ka)], index[(lb, kb)]) for la, ka, lb, kb in chosen
                if (la, ka) in index and (lb, kb) in index]

    # ------------------------------------------------------------------ posing
    def _pose_robot(self, frames: Array, which: Iterable[int] | None = None) -> None:
        idx = range(len(self._rshapes)) if which is None else which
        for i in idx:
            rs = self._rshapes[i]
            rs.obj.setTransform(fcl_transform(frames[rs.link] @ rs.shape.T_link_shape))

    # ------------------------------------------------------------------ checks
    def _candidates(self, frames: Array, with_gap: bool = False,
                    ) -> tuple[Array, Array, Array | None]:
        """Broad phase: for each config, which (robot shape, env shape) and self pairs may touch.

        Returns two boolean arrays, (N, R, E) and (N, P), and with `with_gap` a third, (N,):
        how far every moving sphere stays outside every obstacle box and the sphere pairs of
        the self pairs stay apart (m; <= 0 when something is near). An arm whose travel
        (`travel`) stays below that cannot bring anything near: it bounds each sphere's move
        against the boxes, and in the frame of one link of a pair the other link's spheres
        move by no more than the travel of the joints between them (see
        `is_valid_batch_margin`).
        """
        N = frames.shape[0]
        R, E, P = len(self._rshapes), len(self._env), len(self._self_pairs)
        if len(self._sph_r) == 0:
            return (np.zeros((N, R, E), dtype=bool), np.zeros((N, P), dtype=bool),
                    np.full(N, -np.inf) if with_gap else None)
        env_c, self_c, gap = sphere_broad_phase(
            np.ascontiguousarray(frames, dtype=float), self._sph_link, self._sph_local,
            self._sph_r, self._sph_shape, self._env_lo, self._env_hi, self._sp_a, self._sp_b,
            self._sp_pair, R, P, self._env_from)
        return env_c, self_c, (gap if with_gap else None)

    def _contacts(self, frames_n: Array, env_c: Array, self_c: Array) -> list[Contact]:
        """Every (link, obstacle) and self contact among one configuration's broad-phase
        candidates (reports; the batches only need the first, see `_first_contacts`)."""
        shapes_needed = set(np.nonzero(env_c.any(axis=1))[0].tolist())
        for p in np.nonzero(self_c)[0]:
            shapes_needed.update(self._self_pairs[p])
        if not shapes_needed:
            return []
        self._pose_robot(frames_n, shapes_needed)
        contacts: list[Contact] = []
        seen: set[tuple[str, str]] = set()
        for s, e in zip(*np.nonzero(env_c), strict=True):
            rs, es = self._rshapes[s], self._env[e]
            key = (self._link_names[rs.link], es.owner)
            if key not in seen and self._touches_env(int(s), es):
                seen.add(key)
                contacts.append(Contact(*key))
        for p in np.nonzero(self_c)[0]:
            a, b = self._self_pairs[p]
            ra, rb = self._rshapes[a], self._rshapes[b]
            key = (self._link_names[ra.link], self._link_names[rb.link])
            if key not in seen and fcl.collide(ra.obj, rb.obj, self._req,
                                               fcl.CollisionResult()):
                seen.add(key)
                contacts.append(Contact(*key, self_collision=True))
        return contacts

    def check(self, q: Array) -> CollisionReport:
        """Full report for one configuration: every (link, obstacle) contact and limit issue."""
        q = np.asarray(q, dtype=float)
        frames = self.robot.link_poses(q)[None]
        env_c, self_c, _ = self._candidates(frames)
        contacts = self._contacts(frames[0], env_c[0], self_c[0])
        viol = self.robot.limits.violations(q, self.robot.joint_names)
        return CollisionReport(not viol, tuple(contacts), tuple(viol))

    def is_valid(self, q: Array) -> bool:
        q = np.asarray(q, dtype=float)
        if not self.robot.limits.contains(q):
            return False
        return not self.in_collision_batch(q[None])[0]

    def is_valid_batch(self, Q: Array) -> Array:
        Q = np.asarray(Q, dtype=float)
        ok = self.robot.limits.contains_batch(Q)
        if ok.any():
            ok[ok] = ~self.in_collision_batch(Q[ok])
        return ok

    def in_collision_batch(self, Q: Array) -> Array:
        """Exact collision flag (ignoring joint limits) for each configuration."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        fast = self._prefilter()
        if fast is None or not len(Q):
            return self._collide_batch(Q, with_gap=False)[0]
        hit = fast.in_collision_batch(Q)
        if hit.any():
            hit[hit] = self._collide_batch(Q[hit], with_gap=False)[0]
        return hit

    def _prefilter(self) -> ExactChecker | None:
        """The fast model, asked first by a mesh robot's checks (`fast_prefilter`): what
        it calls free is free, only the rest reaches this checker's own passes and FCL.
        Robots of primitive shapes (the RV-2AJ) are answered as fast without it."""
        return self.fast if self._has_mesh and self._use_fast else None

    def _fast_scale(self) -> float:
        """Factor that turns the fast model's margins into this checker's: its arm radii
        may be larger (its capsules reach beyond the shapes), and a margin is compared with
        this checker's `travel`."""
        fast = self.fast
        assert fast is not None
        r = np.maximum(fast._radii, 1e-12)
        return float(min(1.0, np.min(np.maximum(self._radii, 0.0) / r)))

    def is_valid_batch_margin(self, Q: Array, certified: Array | None = None,
                              ) -> tuple[Array, Array]:
        """`is_valid_batch` and a certified free margin per row (m).

        Any configuration q' with `travel(q, q') < margin` is collision-free as well (joint
        limits aside): no sphere moves farther than the travel, so the broad phase cannot find
        anything near q' and the exact answer is "free". Rows flagged `certified` (already
        proven free that way by the caller) get only the joint-limit test; their margin is
        NaN. The margin is <= 0 (no guarantee) where something is near, and NaN where the row
        is invalid. This is what lets an iterative smoother skip the exact check of small
        moves far from everything - the answers stay exactly those of `is_valid_batch`.
        """
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        fast = self._prefilter()
        if fast is not None and len(Q):
            ok, margin = fast.is_valid_batch_margin(Q, certified)
            margin = margin * self._fast_scale()
            inside = self.robot.limits.contains_batch(Q)
            todo = ~ok & inside
            if certified is not None:
                todo &= ~np.asarray(certified, dtype=bool)
            if todo.any():
                hit, gap = self._margin_rows(np.ascontiguousarray(Q[todo]))
                ok[todo] = ~hit
                margin[todo] = np.where(hit, np.nan, gap)
            return ok, margin
        ok = self.robot.limits.contains_batch(Q)
        margin = np.full(len(Q), np.nan)
        todo = ok.copy() if certified is None else ok & ~np.asarray(certified, dtype=bool)
        if todo.any():
            hit, gap = self._margin_rows(np.ascontiguousarray(Q[todo]))
            ok[todo] = ~hit
            margin[todo] = np.where(hit, np.nan, gap)
        return ok, margin

    def _margin_rows(self, Q: Array) -> tuple[Array, Array]:
        """`_collide_batch(Q, with_gap=True)` with the posing, broad phase and pruning in
        one compiled pass (`broad_phase.margin_rows`, the same arithmetic: the elastic net
        asks this for its particles, where the separate numpy and compiled steps cost
        about twice as much); FCL for the rows it leaves."""
        if len(self._sph_r) == 0:
            return self._collide_batch(Q, with_gap=True)
        frames, ready, chain = self._frames_to_fill(Q)
        status, gap, env_c, self_c = margin_rows(
            frames, ready, chain, Q, self._sph_link, self._sph_local, self._sph_r,
            self._sph_shape, self._env_lo, self._env_hi, self._sp_a, self._sp_b,
            self._sp_pair, len(self._rshapes), len(self._self_pairs), self._shape_link,
            self._seg_a, self._seg_b, self._seg_r, self._env_R, self._env_c, self._env_h,
            self._pair_a, self._pair_b, self.PRUNE_APART, self._env_from)
        hit = np.zeros(len(Q), dtype=bool)
        rows = np.flatnonzero(status == ASK_FCL)
        if len(rows):
            hit[rows] = self._first_contacts(frames[rows], env_c[rows], self_c[rows])
        return hit, gap

    def is_valid_samples(self, Q: Array, groups: Array | None = None, *,
                         first_only: bool = False, known_invalid: Array | None = None,
                         ) -> Array:
        """`is_valid_batch` of the samples of one or more motions, exactly, at less cost.

        Q holds the samples of motions in order (rows of one motion consecutive; `groups`
        tells which motion each row belongs to, all one motion if None). Every
        `CERTIFY_STRIDE`-th sample of a motion (and its last) is checked with its free margin
        (as `is_valid_batch_margin`); a sample whose arm travel from a checked neighbour of
        its motion stays inside that neighbour's margin is free as well, and only the rest
        get an exact check. The answers are those of `is_valid_batch` row for row (a margin
        is a proof, and the joint limits are tested on every row); in open space a motion
        costs a few checks instead of one per `max_step` of arm travel. All but FCL runs in
        one compiled pass (`broad_phase.certify_samples`): as numpy calls, the bookkeeping
        of a 70-sample roadmap edge cost more than its checks.

        `known_invalid` flags rows the caller already refuses (e.g. recorded collision
        postures). With `first_only` only each motion's first invalid row matters (what a
        motion check reports): rows after it are returned invalid without FCL. An edge
        into an obstacle has dozens of samples inside it, each an FCL question otherwise.
        """
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        fast = self._prefilter()
        if fast is not None and len(Q):
            return self._prefiltered_samples(fast, Q, groups, first_only, known_invalid)
        return self._exact_samples(Q, groups, first_only, known_invalid)

    def _prefiltered_samples(self, fast: ExactChecker, Q: Array, groups: Array | None,
                             first_only: bool, known_invalid: Array | None) -> Array:
        """`is_valid_samples` asking the fast model first: the rows it calls free are free;
        the others (within the limits, not known invalid) get this checker's own passes."""
        ok = fast.is_valid_samples(Q, groups, known_invalid=known_invalid)
        ask = ~ok & self.robot.limits.contains_batch(Q)
        if known_invalid is not None:
            ask &= ~known_invalid
        if ask.any() and first_only:
            self._first_asked(Q, groups, ok, ask)
        elif ask.any():
            g = None if groups is None else np.asarray(groups)[ask]
            ok[ask] = self._exact_samples(Q[ask], g, False, None)
        if first_only and not ok.all():
            g = np.zeros(len(Q), dtype=np.int64) if groups is None else np.asarray(groups)
            motion = motion_marks(np.ascontiguousarray(g, dtype=np.int64))[2]
            bad = np.flatnonzero(~ok)
            first_bad = np.full(int(motion[-1]) + 1, len(Q))
            np.minimum.at(first_bad, motion[bad], bad)
            ok &= np.arange(len(Q)) <= first_bad[motion]
        return ok

    def _first_asked(self, Q: Array, groups: Array | None, ok: Array, ask: Array,
                     rounds: int = 3) -> None:
        """Exact answers (into ok) for the `ask` rows up to each motion's first invalid
        one: each round checks every motion's first unanswered row (a motion into an
        obstacle is done with one exact check); a row the fast model called a collision
        that is free lets its motion go on to its next; after `rounds` the rest at once."""
        g = np.zeros(len(Q), dtype=np.int64) if groups is None else np.asarray(groups)
        motion = motion_marks(np.ascontiguousarray(g, dtype=np.int64))[2]
        ok[ask] = False  # until answered
        open_rows = np.flatnonzero(ask)
        for _ in range(rounds):
            if not len(open_rows):
                return
            m = motion[open_rows]
            first = open_rows[np.r_[True, m[1:] != m[:-1]]]  # each motion's first
            hit = self.in_collision_batch_exact(Q[first])
            done = set(m_ for m_, h in zip(motion[first].tolist(), hit.tolist(),
                                           strict=True) if h)
            ok[first[~hit]] = True
            keep = ~np.isin(open_rows, first) & ~np.isin(motion[open_rows], list(done))
            open_rows = open_rows[keep]
        if len(open_rows):
            ok[open_rows] = self._exact_samples(Q[open_rows], g[open_rows], True, None)

    def in_collision_batch_exact(self, Q: Array) -> Array:
        """This checker's own passes and FCL, without the fast model."""
        return self._collide_batch(np.atleast_2d(np.asarray(Q, dtype=float)),
                                   with_gap=False)[0]

    def _exact_samples(self, Q: Array, groups: Array | None, first_only: bool,
                       known_invalid: Array | None) -> Array:
        """`is_valid_samples` by this checker's own passes and FCL."""
        n = len(Q)
        stride = self.CERTIFY_STRIDE
        if n <= 2 or stride <= 1 or len(self._sph_r) == 0:
            ok = self.is_valid_batch(Q)
            return ok if known_invalid is None else ok & ~known_invalid
        frames, status, env_c, self_c, motion = self._certify(Q, groups)
        bad = status == OUTSIDE_LIMITS
        if known_invalid is not None:
            bad |= known_invalid
        ok = ((status == FREE) | (status == CERTIFIED)) & ~bad
        if not first_only:
            rows = np.flatnonzero((status == ASK_FCL) & ~bad)
            if len(rows):
                ok[rows] = ~self._first_contacts(frames[rows], env_c[rows], self_c[rows])
            return ok
        rows, first_bad = rows_before_first_bad(status == ASK_FCL, bad, motion)
        hit = (self._first_contacts(frames[rows], env_c[rows], self_c[rows], motion[rows])
               if len(rows) else np.zeros(0, dtype=bool))
        valid_before_first_bad(ok, rows, hit, motion, first_bad)
        return ok

    def _certify(self, Q: Array, groups: Array | None,
                 ) -> tuple[Array, Array, Array, Array, Array]:
        """Link frames of the rows of Q (of the rows checked, for a DH chain: those are
        posed by the pass itself), `broad_phase.certify_samples`' answers for them (the
        sampling, broad phase, margins and pruning in one compiled pass) and each row's
        motion number."""
        n = len(Q)
        g = np.zeros(n, dtype=np.int64) if groups is None else np.asarray(groups)
        first, last, motion = motion_marks(g)
        Q = np.ascontiguousarray(Q, dtype=float)
        lim = self.robot.limits
        inside = rows_inside(Q, lim.lower, lim.upper)
        frames, ready, chain = self._frames_to_fill(Q)
        status, env_c, self_c = certify_samples(
            frames, ready, chain, Q, inside, first, last, self.CERTIFY_STRIDE,
            self._radii, self._sph_link, self._sph_local, self._sph_r, self._sph_shape,
            self._env_lo, self._env_hi, self._sp_a, self._sp_b, self._sp_pair,
            len(self._rshapes), len(self._self_pairs), self._shape_link, self._seg_a,
            self._seg_b, self._seg_r, self._env_R, self._env_c, self._env_h, self._pair_a,
            self._pair_b, self.PRUNE_APART, self._env_from)
        return frames, status, env_c, self_c, motion

    def _frames_to_fill(self, Q: Array) -> tuple[Array, Array, Array]:
        """(frames, ready, DH fixed parts) for a compiled pass over the rows of Q that poses
        only the rows it needs (`dh.chain_row`): for a DH chain nothing is posed yet; a
        robot without one gets every row's frames from `batch_link_poses` now (ready)."""
        n = len(Q)
        if self._chain_F is not None:
            chain = np.ascontiguousarray(self._chain_F, dtype=float)
            return np.empty((n, len(chain) + 1, 4, 4)), np.zeros(n, dtype=bool), chain
        frames = np.ascontiguousarray(
            np.concatenate([self._link_frames(Q[i : i + self.chunk])
                            for i in range(0, n, self.chunk)]), dtype=float)
        return frames, np.ones(n, dtype=bool), np.zeros((0, 4, 4))

    def _link_frames(self, Q: Array) -> Array:
        """The robot's link frames of the rows of Q: a mesh robot's from the fast model's
        compiled chain (`fast_model.FastRobot`: its frames turned back into the robot's,
        L_k = G L'_k to_fast_k), where numpy's batch FK costs ~1 ms a call; else the
        robot's own."""
        if not self._has_mesh or not self._use_fast or len(Q) == 0:
            return self.robot.batch_link_poses(Q)
        fast = self.fast
        if fast is None:
            return self.robot.batch_link_poses(Q)
        if self._frame_fix is None:
            fr = fast.robot
            self._frame_fix = (fr.G, np.stack(fr.to_fast))
        G, fix = self._frame_fix
        return np.matmul(np.matmul(G, fast.robot.batch_link_poses(Q)), fix)

    def net_kernel_checker(self) -> tuple | None:
        """The broad phase's and the pruning's arrays in `trajectory.net_kernel`'s order,
        or None without covering spheres (the broad phase then has nothing to decide)."""
        if len(self._sph_r) == 0:
            return None
        return (self._radii, self._sph_link, self._sph_local, self._sph_r, self._sph_shape,
                self._env_lo, self._env_hi, self._sp_a, self._sp_b, self._sp_pair,
                len(self._rshapes), len(self._self_pairs), self._shape_link, self._seg_a,
                self._seg_b, self._seg_r, self._env_R, self._env_c, self._env_h,
                self._pair_a, self._pair_b, float(self.PRUNE_APART))

    def net_kernel_validity(self) -> tuple[tuple, Array, Array, object] | None:
        """(`net_kernel_checker`, recorded postures, box half-widths, exact check): the
        validity of the elastic net's particles for `trajectory.net_kernel`, no recorded
        collisions here (see `KnownValidity`)."""
        model = self.net_kernel_checker()
        if model is None:
            return None
        dof = len(self._radii)
        return model, np.zeros((0, dof)), np.full(dof, np.inf), self._first_contacts

    def travel(self, Q0: Array, Q1: Array) -> Array:
        """Upper bound (m) on how far any point of the arm moves between rows of Q0 and Q1
        (straight joint motion): sum(arm radius x |joint change|)."""
        d = np.abs(np.asarray(Q1, dtype=float) - np.asarray(Q0, dtype=float))
        # Summed joint by joint, in order, like the compiled checks (`certify_samples`,
        # `net_kernel`): a matrix product may add in another order, and the certificates
        # must come out the same to the bit on every path.
        out = d[..., 0] * self._radii[0]
        for j in range(1, len(self._radii)):
            out = out + d[..., j] * self._radii[j]
        return out

    def _collide_batch(self, Q: Array, with_gap: bool) -> tuple[Array, Array | None]:
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        out = np.zeros(len(Q), dtype=bool)
        gaps = np.empty(len(Q)) if with_gap else None
        for start in range(0, len(Q), self.chunk):
            block = Q[start : start + self.chunk]
            frames = self._link_frames(block)
            env_c, self_c, gap = self._candidates(frames, with_gap)
            if gaps is not None:
                gaps[start : start + len(block)] = gap
            maybe = np.nonzero(env_c.any(axis=(1, 2)) | self_c.any(axis=1))[0]
            if len(maybe) and self._round.any():
                prune_round_pairs(frames, maybe, env_c, self_c, self._shape_link,
                                  self._seg_a, self._seg_b, self._seg_r, self._env_R,
                                  self._env_c, self._env_h, self._pair_a, self._pair_b,
                                  self.PRUNE_APART)
                maybe = maybe[env_c[maybe].any(axis=(1, 2)) | self_c[maybe].any(axis=1)]
            if len(maybe):
                out[start + maybe] = self._first_contacts(frames[maybe], env_c[maybe],
                                                          self_c[maybe])
        return out, gaps

    def _first_contacts(self, frames: Array, env_c: Array, self_c: Array,
                        motions: Array | None = None) -> Array:
        """Exact flag per row for the broad phase's candidate pairs: obstacle pairs, then
        self pairs, stopping at the first contact. The bookkeeping is done for all rows at
        once and a shape is posed only when a pair of its row first needs it. With
        `motions` (a label per row, rows in order), a row after a hit row of its motion is
        not checked and counts as a hit."""
        n = len(frames)
        hit = np.zeros(n, dtype=bool)
        ek, es, ee = np.nonzero(env_c)  # ordered by row, then robot shape, then obstacle
        pk, pp = np.nonzero(self_c)
        e_at = np.searchsorted(ek, np.arange(n + 1)).tolist()
        p_at = np.searchsorted(pk, np.arange(n + 1)).tolist()
        es_l, ee_l = es.tolist(), ee.tolist()
        pairs = [self._self_pairs[p] for p in pp.tolist()]
        # Every robot shape's pose in every row, in one compiled pass (`shape_poses`).
        R, t = shape_poses(np.ascontiguousarray(frames, dtype=float), self._shape_link,
                           self._shape_T)
        objs = [rs.obj for rs in self._rshapes]
        env = [es.obj for es in self._env]
        env_margin = [es.margin for es in self._env]
        posed_in = [-1] * len(objs)  # the row each shape is posed for now
        grown_in: dict[tuple[int, float], int] = {}  # the same for grown shapes

        def posed(i: int, k: int) -> fcl.CollisionObject:
            if posed_in[i] != k:
                posed_in[i] = k
                objs[i].setTransform(fcl.Transform(R[k, i], t[k, i]))
            return objs[i]

        def posed_for(i: int, k: int, e: int) -> fcl.CollisionObject:
            """Robot shape i posed for row k, grown by obstacle e's margin if it has one."""
            m = env_margin[e]
            if m <= 0.0:
                return posed(i, k)
            g = self._grown(i, m)
            if grown_in.get((i, m)) != k:
                grown_in[(i, m)] = k
                g.setTransform(fcl.Transform(R[k, i], t[k, i]))
            return g

        def collide(a: fcl.CollisionObject, b: fcl.CollisionObject) -> bool:
            return bool(fcl.collide(a, b, self._req, fcl.CollisionResult()))

        stop = None if motions is None else motions.tolist()
        stopped = set()
        for k in range(n):
            if stop is not None and stop[k] in stopped:
                hit[k] = True
                continue
            hit[k] = (any(collide(posed_for(es_l[j], k, ee_l[j]), env[ee_l[j]])
                          for j in range(e_at[k], e_at[k + 1]))
                      or any(collide(posed(pairs[j][0], k), posed(pairs[j][1], k))
                             for j in range(p_at[k], p_at[k + 1])))
            if hit[k] and stop is not None:
                stopped.add(stop[k])
        return hit

    def in_collision_naive(self, q: Array) -> bool:
        """Brute force: every robot shape against every obstacle and self pair through FCL.

        The reference the fast path is checked against (tests, benchmarks).
        """
        frames = self.robot.link_poses(np.asarray(q, dtype=float))
        self._pose_robot(frames)
        for i, rs in enumerate(self._rshapes):
            if rs.link == 0:
                continue
            for es in self._env:
                if self._touches_env(i, es):
                    return True
        for a, b in self._self_pairs:
            if fcl.collide(self._rshapes[a].obj, self._rshapes[b].obj, self._req,
                           fcl.CollisionResult()):
                return True
        return False

