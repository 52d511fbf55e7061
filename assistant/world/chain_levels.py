"""Validity of table joint positions against CAD (and self-collision), link by link along the chain.

Link k's pose depends only on q1..qk, so a collision of the upper arm found on the (q1, q2)
grid rules out every (q3, q5, ...) below it at once. A link whose shapes are symmetric about
its own joint axis (a sphere centred on it, a capsule/cylinder along it - the RV-2AJ's turret,
wrist ball, flange and straight tool) does not even depend on its own joint, so it is checked
one level earlier: for the RV-2AJ the levels are (q1, q2) for the upper arm, (q1, q2, q3) for
the forearm and wrist, and (q1, q2, q3, q5) for flange + tool (J6 never matters).

Each level is checked by the project's `CollisionChecker` on a *view* of the robot that keeps
the collision shapes of the links up to that level only; its self-collision pairs are the full
robot's pairs among those links (the robot's one rule, `collision.self_rule`). So a position
that passes every level passes the full checker (same shapes, same pairs). A robot of
primitive shapes (the RV-2AJ) is checked exactly (broad phase + FCL): one that fails a level
really collides; a mesh robot (URDF arms) on its fast conservative model
(`CollisionChecker.fast`): a position it keeps is free, one it drops may not have collided -
its leaf offers its next positions. Results are cached per level prefix, so repeated calls
(e.g. refilling a leaf) never check a prefix twice.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np

from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import ObstacleView
from assistant.progress import Progress
from assistant.robots.model import BatchPoses, CollisionShape, IKResult, Robot, ShapeKind
from assistant.world.leaf_store import JointStore

Array = np.ndarray

UNKNOWN, VALID, INVALID = 0, 1, 2
#: Penetration (m) the exact pre-test needs before it calls a contact certain without FCL.
_SURE_MARGIN = 1e-5
#: Prefix spaces larger than this keep their cache in a dict instead of a dense int8 array.
_DENSE_LIMIT = 1 << 27


class _FrameMemo:
    """The last batch of link frames, shared by the views of one validator: several checkers
    look at the same configurations in turn and FK needs computing only once."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self._key: bytes | None = None
        self._frames: Array | None = None

    def frames(self, Q: Array) -> Array:
        Q = np.ascontiguousarray(Q, dtype=float)
        key = Q.tobytes()
        if key != self._key or self._frames is None:
            self._frames = self.robot.batch_link_poses(Q)
            self._key = key
        return self._frames


class LinkSubsetRobot(Robot):
    """The same robot with collision shapes only on the links in `keep` (a checker's view)."""

    def __init__(self, robot: Robot, keep: Iterable[int], tag: str,
                 memo: _FrameMemo | None = None):
        self._robot = robot
        keep = set(keep)
        self._tag = tag
        self._memo = memo
        self.name = robot.name
        self.joint_names = list(robot.joint_names)
        self.limits = robot.limits
        self.T_flange_tool = robot.T_flange_tool
        self.links = [lk if i in keep else replace(lk, collision=())
                      for i, lk in enumerate(robot.links)]
        #: The robot this views (its fast model's capsules serve the view's: `fast_model`).
        self.subset_parent = robot
        hook = getattr(robot, "dh_fixed_stack", None)
        if hook is not None:
            self.dh_fixed_stack = hook
        chain = getattr(robot, "batch_chain", None)
        if chain is not None:
            self.batch_chain = chain

    def root_description(self) -> str:
        """The viewed robot's description: geometry keyed by it is the same here."""
        root = getattr(self._robot, "root_description", self._robot.description_hash)
        return root()

    def fk(self, q: Array) -> Array:
        return self._robot.fk(q)

    def link_poses(self, q: Array) -> Array:
        return self._robot.link_poses(q)

    def batch_fk(self, Q: Array) -> BatchPoses:
        return self._robot.batch_fk(Q)

    def batch_link_poses(self, Q: Array) -> Array:
        if self._memo is not None:
            return self._memo.frames(Q)
        return self._robot.batch_link_poses(Q)

    def ik(self, T_base_tool: Array, seed: Array | None = None, *,
           position_only: bool = False) -> IKResult:
        return self._robot.ik(T_base_tool, seed, position_only=position_only)

    def with_tool(self, T_flange_tool: Array) -> Robot:
        raise NotImplementedError("a link-subset view is read-only")

    def urdf(self) -> str:
        return self._robot.urdf()

    def description_hash(self) -> str:
        return f"{self._robot.description_hash()}:{self._tag}"

    def rule_robot(self) -> Robot:
        """The whole robot: its self-collision rule is this view's (`collision.self_rule`)."""
        return self._robot


def _key_points(shape: CollisionShape) -> Array:
    """Points (shape's link frame) that pin the shape down up to rotation about a line
    through them: centre of a sphere, axis ends of a capsule/cylinder, box corners, vertices."""
    T = shape.T_link_shape
    if shape.kind == ShapeKind.SPHERE:
        local = np.zeros((1, 3))
    elif shape.kind in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
        h = shape.size[1] / 2.0
        local = np.array([[0.0, 0.0, -h], [0.0, 0.0, h]])
    elif shape.kind == ShapeKind.BOX:
        s = np.asarray(shape.size) / 2.0
        local = np.array([[x, y, z] for x in (-s[0], s[0]) for y in (-s[1], s[1])
                          for z in (-s[2], s[2])])
    else:
        assert shape.mesh is not None
        local = np.asarray(shape.mesh.vertices, dtype=float)
        # A mesh is only invariant if it is a solid of revolution; treat it as not invariant
        # unless all vertices lie on the axis, which the point test below handles.
    return local @ T[:3, :3].T + T[:3, 3]


def _inner_balls(shape: CollisionShape) -> tuple[Array, Array]:
    """Balls (centres in the shape's owner frame, radii) that lie inside the shape."""
    T = shape.T_link_shape
    if shape.kind == ShapeKind.SPHERE:
        local, rad = np.zeros((1, 3)), np.array([float(shape.size[0])])
    elif shape.kind in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
        r, h = float(shape.size[0]), float(shape.size[1]) / 2.0
        if shape.kind == ShapeKind.CYLINDER:
            if h <= r:
                return T[:3, 3][None].copy(), np.array([h])
            h = h - r  # balls must not stick out of the flat ends
        n = max(2, int(np.ceil(2 * h / r)) + 1)
        local = np.zeros((n, 3))
        local[:, 2] = np.linspace(-h, h, n)
        rad = np.full(n, r)
    elif shape.kind == ShapeKind.BOX:
        e = np.asarray(shape.size, dtype=float) / 2.0
        r = float(e.min())
        ax = int(np.argmax(e))
        n = max(1, int(np.ceil((e[ax] - r) / r)) + 1)
        local = np.zeros((n, 3))
        local[:, ax] = np.linspace(-(e[ax] - r), e[ax] - r, n)
        rad = np.full(n, r)
    else:
        return np.zeros((0, 3)), np.zeros(0)
    return local @ T[:3, :3].T + T[:3, 3], rad


def _link_balls(robot: Robot, links: list[int]) -> tuple[list[int], Array, Array]:
    """Inner balls of the given links: (link index per ball, centres in link frame, radii)."""
    owner, cs, rs = [], [], []
    for k in links:
        for shape in robot.links[k].collision:
            c, r = _inner_balls(shape)
            owner += [k] * len(r)
            cs.append(c)
            rs.append(r)
    if not rs:
        return [], np.zeros((0, 3)), np.zeros(0)
    return owner, np.concatenate(cs), np.concatenate(rs)


def _obstacle_solids(obstacles: list[ObstacleView],
                     ) -> tuple[list[tuple[Array, Array, Array]], tuple[Array, Array]]:
    """Obstacle boxes as (R_box_base, t_box_base, half extents) and the inner balls of the
    other primitive shapes (base frame)."""
    boxes = []
    cs, rs = [], []
    for ob in obstacles:
        T_base_object = np.asarray(ob.T_base_object, dtype=float)
        for shape in ob.collision:
            T = T_base_object @ shape.T_link_shape
            if shape.kind == ShapeKind.BOX:
                R = T[:3, :3].T
                boxes.append((R, -R @ T[:3, 3], np.asarray(shape.size, dtype=float) / 2.0))
            else:
                c, r = _inner_balls(shape)
                if len(r):
                    cs.append(c @ T_base_object[:3, :3].T + T_base_object[:3, 3])
                    rs.append(r)
    balls = ((np.concatenate(cs), np.concatenate(rs)) if rs
             else (np.zeros((0, 3)), np.zeros(0)))
    return boxes, balls


def _pairless_groups(older: list[int], new: list[int], n_links: int) -> list[list[int]]:
    """Split the older links into groups of chain neighbours (adjacent links never form a
    self-collision pair), dropping those adjacent to every new link."""
    cand = [i for i in older if any(abs(i - j) > 1 for j in new)]
    groups: list[list[int]] = []
    for i in cand:
        if groups and len(groups[-1]) == 1 and groups[-1][0] == i - 1:
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


def link_levels(robot: Robot, *, seed: int = 3) -> list[int]:
    """For each link, the number of leading joints its collision geometry depends on.

    Link k (moved by joint k) depends on q1..qk, or on q1..q(k-1) if turning joint k leaves all
    its shapes where they were (checked numerically: key points of spheres/capsules/cylinders
    stay put; boxes and meshes only if they really are symmetric).
    """
    rng = np.random.default_rng(seed)
    lo, hi = robot.limits.lower, robot.limits.upper
    levels = [0] * len(robot.links)
    for k in range(1, len(robot.links)):
        levels[k] = k
        shapes = robot.links[k].collision
        if not shapes:
            continue
        invariant = True
        for _ in range(3):
            q = rng.uniform(lo, hi)
            q2 = q.copy()
            q2[k - 1] += 0.7
            F1, F2 = robot.link_poses(q)[k], robot.link_poses(q2)[k]
            for s in shapes:
                kp = _key_points(s)
                w1 = kp @ F1[:3, :3].T + F1[:3, 3]
                w2 = kp @ F2[:3, :3].T + F2[:3, 3]
                if not np.allclose(w1, w2, atol=1e-9):
                    invariant = False
                    break
            if not invariant:
                break
        if invariant:
            levels[k] = k - 1
    return levels


class ChainValidator:
    """Valid (collision-free against the obstacles and itself) table joint positions.

    `validate(ids)` takes ids of the joint-position store and returns a bool per id; every
    check goes through a `CollisionChecker`. Per level L the checkers are: one for the links
    new at L against the obstacles, and one per group of older links that can touch a new link
    (self-collision), the groups chosen so that no two older links in a group form a pair - an
    older pair was already settled at its own level and must not be re-checked for every
    configuration below it. Not thread-safe (the checkers are not).
    """

    def __init__(self, robot: Robot, obstacles: Iterable[ObstacleView], table: JointStore,
                 *, self_collision: bool = True):
        self.robot = robot
        self.table = table
        self.obstacles = list(obstacles)
        self.link_level = link_levels(robot)
        n_links = len(robot.links)
        shaped = [i for i in range(n_links) if robot.links[i].collision]
        self.levels = sorted({self.link_level[i] for i in shaped if i > 0})
        self._space = {L: table.prefix_space(L) for L in self.levels}
        memo = _FrameMemo(robot)
        # the views' self pairs are the robot's own among their links (sampled once)
        full = CollisionChecker(robot, (), self_collision=self_collision) \
            if self_collision else None
        self._checkers: dict[int, list[CollisionChecker]] = {}
        self._cache: dict[int, Array | dict[int, int]] = {}
        for L in self.levels:
            new = [i for i in shaped if i > 0 and self.link_level[i] == L]
            checkers = [CollisionChecker(LinkSubsetRobot(robot, new, f"L{L}:env", memo),
                                         self.obstacles, self_collision=self_collision,
                                         pairs_of=full)]
            if self_collision:
                older = [i for i in shaped if self.link_level[i] < L or i == 0]
                for group in _pairless_groups(older, new, n_links):
                    tag = f"L{L}:self:" + ",".join(map(str, group))
                    checkers.append(CollisionChecker(
                        LinkSubsetRobot(robot, set(group) | set(new), tag, memo), (),
                        self_collision=True, pairs_of=full))
            self._checkers[L] = checkers
            self._cache[L] = (np.zeros(self._space[L], dtype=np.int8)
                              if self._space[L] <= _DENSE_LIMIT else {})
        #: Joint values used for the joints beyond a level (irrelevant to that level's links).
        self._rest = np.clip(0.0, robot.limits.lower, robot.limits.upper)
        fixed = table.counts == 1
        self._rest[fixed] = table.lower[fixed]
        self.checks = {L: 0 for L in self.levels}
        self.sure_hits = {L: 0 for L in self.levels}
        self._balls = {L: _link_balls(robot, [i for i in shaped if i > 0
                                              and self.link_level[i] == L])
                       for L in self.levels}
        self._boxes, self._obstacle_balls = _obstacle_solids(self.obstacles)
        #: Whether the levels are checked on the fast model (`_collides`).
        self._fast_levels = all(c._has_mesh and c.fast is not None
                                for cs in self._checkers.values() for c in cs)

    def _sure_hits(self, L: int, Q: Array) -> Array:
        """Configurations whose new links certainly touch an obstacle, without FCL.

        Balls that lie inside a link shape (along a capsule's axis, a sphere itself) are tested
        against obstacle boxes (exact point-box distance) and balls inside other obstacles: a
        ball that touches the obstacle proves contact. Almost every configuration that reaches
        FCL near the table is a real hit, so this spares most narrow-phase calls; whatever it
        does not prove goes to the checkers as usual.
        """
        links, centres, radii = self._balls[L]
        # Demand a clear overlap: touching (distance == radius) is left to FCL.
        radii = radii - _SURE_MARGIN
        hit = np.zeros(len(Q), dtype=bool)
        if not len(radii) or not (self._boxes or self._obstacle_balls[1].size):
            return hit
        frames = self.robot.batch_link_poses(Q)[:, links]  # (N, m, 4, 4)
        C = np.einsum("nmij,mj->nmi", frames[..., :3, :3], centres) + frames[..., :3, 3]
        for R_box_base, t_box_base, half in self._boxes:
            p = C @ R_box_base.T + t_box_base
            d = np.maximum(np.abs(p) - half, 0.0)
            hit |= np.any(np.einsum("nmk,nmk->nm", d, d) <= radii ** 2, axis=1)
        oc, orad = self._obstacle_balls
        if orad.size:
            diff = C[:, :, None, :] - oc[None, None]
            d2 = np.einsum("nmok,nmok->nmo", diff, diff)
            hit |= np.any(d2 <= (radii[:, None] + orad[None]) ** 2, axis=(1, 2))
        return hit

    @staticmethod
    def _collides(chk: CollisionChecker, Q: Array) -> Array:
        """The level's check: a mesh robot's (URDF arms) on the fast conservative model
        alone (`CollisionChecker.fast`: its capsules contain the meshes, so a position it
        keeps is free; one it drops may have been free, and the leaf offers its next
        positions) - FCL on the meshes of every position near an obstacle cost most of the
        world build; a robot of primitive shapes (the RV-2AJ) exactly, as fast."""
        fast = chk.fast if chk._has_mesh else None
        return fast.in_collision_batch(Q) if fast is not None else chk.in_collision_batch(Q)

    def _prefix_configs(self, L: int, prefixes: Array) -> Array:
        return self.table.prefix_configs(L, prefixes, self._rest)

    def _lookup(self, L: int, prefixes: Array) -> Array:
        cache = self._cache[L]
        if isinstance(cache, np.ndarray):
            return cache[prefixes]
        return np.array([cache.get(int(p), UNKNOWN) for p in prefixes.tolist()], dtype=np.int8)

    def _store(self, L: int, prefixes: Array, states: Array) -> None:
        cache = self._cache[L]
        if isinstance(cache, np.ndarray):
            cache[prefixes] = states
        else:
            cache.update(zip(prefixes.tolist(), states.tolist(), strict=True))

    def validate(self, ids: Array, progress: Progress | None = None) -> Array:
        """Bool per flat joint-grid id: no link hits an obstacle and no self-collision."""
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        alive = np.ones(len(ids), dtype=bool)
        n_levels = max(1, len(self.levels))
        for li, L in enumerate(self.levels):
            if not alive.any():
                break
            pre = self.table.prefixes(ids[alive], L)
            st = self._lookup(L, pre)
            todo = np.unique(pre[st == UNKNOWN])
            if len(todo):
                step = 2048
                for s in range(0, len(todo), step):
                    part = todo[s:s + step]
                    Q = self._prefix_configs(L, part)
                    # (the exact pre-test spares FCL calls; the fast model asks none)
                    bad = np.zeros(len(Q), dtype=bool) if self._fast_levels else \
                        self._sure_hits(L, Q)
                    self.sure_hits[L] += int(bad.sum())
                    for chk in self._checkers[L]:
                        rest = ~bad
                        if rest.any():
                            bad[rest] = self._collides(chk, Q[rest])
                    self._store(L, part, np.where(bad, INVALID, VALID).astype(np.int8))
                    self.checks[L] += len(part)
                    if progress is not None:
                        progress.update((li + (s + len(part)) / len(todo)) / n_levels,
                                        f"checking links up to joint {L} against CAD")
                st = self._lookup(L, pre)
            alive[alive] = st == VALID
        return alive
