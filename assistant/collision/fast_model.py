"""The fast conservative collision model: every robot shape as capsules, every obstacle as
boxes, checked entirely in the compiled broad phase - no FCL.

Why: planners ask thousands of questions a query (roadmap edges, joint-move candidates,
shortcuts, clearances). On a URDF arm each exact answer poses meshes through numpy and
asks FCL for the near pairs; a query cost seconds. Here a link is a few capsules around its
mesh (`capsule_cover`: every vertex and face inside, radii padded by `PAD`) and an obstacle
its oriented box, so "free" and the clearance are closed-form distances of the pass that
poses the arm (`broad_phase.certify_samples`, `margin_rows`, `clearance_scan`).

Conservative: the model's shapes contain the real ones, so what it calls free is free, and
its clearance is a lower bound of the real one; it may call a posture a collision that is
not (a false collision: `tightness`). Planners search and score on it; the path finally
chosen is certified by the exact checker (`CollisionChecker`), whose own answers stay FCL's.

Frames: the link frames come from the compiled DH-style chain (`dh.chain_row`). A URDF
chain rotates about any axis after a fixed placement; turning each link frame so that its
joint axis is z (`R_k`) and expressing everything in the frame of joint 1 (`G`) makes it
one: L'_k = L'_(k-1) F_(k-1) Rz(q_k) with F_(k-1) = R_(k-1)^T P_k R_k. Obstacles are
moved into that frame once; distances do not depend on it. A chain with a prismatic joint
gets no fast model (None).

Serves (the user-felt figure): a UR or Panda planning query (target <= 50 ms, seconds
before) and the world build (<= 10 s); it adds no kernel of its own.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass

import numpy as np

from assistant.collision.capsule_cover import Capsule, cover_shape
from assistant.collision.reports import Obstacle, ObstacleView
from assistant.collision.segment_box import oriented_bounds
from assistant.robots.dh import batch_chain_frames, chain_frames_numpy
from assistant.robots.model import (
    BatchPoses,
    CollisionShape,
    IKResult,
    LinkGeometry,
    Robot,
    ShapeKind,
)

Array = np.ndarray


@dataclass(frozen=True)
class _Stack:
    """What `dh.batch_chain_frames` reads of a chain."""

    fixed_stack: Array


def _z_to(axis: Array) -> Array:
    """A 4x4 rotation taking z to the unit `axis` (the identity for z itself)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    R = np.eye(4)
    if np.allclose(a, [0.0, 0.0, 1.0], atol=1e-15):
        return R
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, a)
    x /= np.linalg.norm(x)
    R[:3, :3] = np.column_stack([x, np.cross(a, x), a])
    return R


def chain_of(robot: Robot) -> tuple[Array, Array, list[Array]] | None:
    """(F (n, 4, 4), G, [R_k]) of the robot's chain in `dh.chain_row`'s form (module
    docstring): the built-in DH robots as they are, URDF chains of revolute joints turned
    into it; None for other robots."""
    hook = getattr(robot, "dh_fixed_stack", None)
    n = robot.dof
    if hook is not None:
        return np.ascontiguousarray(hook(), dtype=float), np.eye(4), [np.eye(4)] * (n + 1)
    chain = getattr(robot, "batch_chain", None)
    if chain is None or len(chain.joints) != n or \
            any(j.kind.value != "revolute" for j in chain.joints):
        return None
    R = [np.eye(4)] + [_z_to(j.axis) for j in chain.joints]
    P = [np.asarray(j.T_prev_joint, dtype=float) for j in chain.joints]
    G = P[0] @ R[1]
    F = [R[k].T @ P[k] @ R[k + 1] for k in range(1, n)]  # R: rotations, R.T is the inverse
    F.append(R[n].T @ np.asarray(chain.T_last_tip, dtype=float))
    return np.ascontiguousarray(np.array(F), dtype=float), G, R


class FastRobot(Robot):
    """`robot` with every shape replaced by its capsules (`capsule_cover`), posed by the
    compiled chain, everything in the frame of joint 1 (`chain_of`'s G). Shapes keep the
    order of the robot's own: `owner[i]` is the robot shape (in link order) capsule i
    covers."""

    def __init__(self, robot: Robot, max_capsules: int = 4, gain: float = 0.2):
        got = chain_of(robot)
        if got is None:
            raise ValueError(f"{robot.name}: no revolute chain for the fast model")
        F, G, R = got
        self._robot = robot
        self._F = F
        self._G = G
        self._Ginv = np.linalg.inv(G)
        self._params = (max_capsules, gain)
        self.name = robot.name
        self.joint_names = list(robot.joint_names)
        self.limits = robot.limits
        self.T_flange_tool = robot.T_flange_tool
        #: Per link: its old frame -> its frame here (a shape at T there is at to_fast @ T).
        self.to_fast = [self._Ginv if k == 0 else R[k].T for k in range(len(robot.links))]
        parent = getattr(robot, "subset_parent", None)
        parent_fast = fast_robot(parent, **self._kw()) if parent is not None else None
        fits = parent_fast.fits if parent_fast is not None else _load(self._fit_key())
        cached = fits is not None
        fits = {} if fits is None else fits
        links, owner, capsules = [], [], []
        i = 0
        for k, link in enumerate(robot.links):
            shapes = []
            for j, s in enumerate(link.collision):
                if (k, j) not in fits:
                    fits[(k, j)] = self._fit(s, k, F)
                for c in fits[(k, j)]:
                    shapes.append(c.shape())
                    capsules.append(c)
                    owner.append(i)
                i += 1
            links.append(LinkGeometry(link.name, tuple(shapes), None, link.color))
        #: (link, shape in link) -> its capsules here: the fit, shared with link subsets.
        self.fits = fits
        self.links = links
        #: Per fast shape: the index of the robot shape it covers (robot shapes numbered in
        #: link order, as `CollisionChecker` numbers them), and its capsule.
        self.owner = np.array(owner, dtype=np.int64)
        self.capsules = capsules
        if not cached:
            _save(self._fit_key(), fits)
        self.__dict__["_arm_radii"] = np.maximum(robot.arm_radii(), self._compute_arm_radii())

    def _kw(self) -> dict:
        return dict(max_capsules=self._params[0], gain=self._params[1])

    def _fit_key(self) -> str:
        return self.description_hash()

    def _fit(self, shape, k: int, F: Array) -> list[Capsule]:
        """The capsules of one shape of link k, in this model's frame of the link; the
        link's joint axes (its own, the next one's) and the segment between them as the
        lines a housing or a tube is fitted along (`capsule_cover.mesh_capsules`)."""
        to_fast = self.to_fast[k]
        back = np.linalg.inv(to_fast)
        o0 = back[:3, 3].copy()
        lines = [(o0, back[:3, :3] @ np.array([0.0, 0.0, 1.0]))]
        if 1 <= k < len(F):
            o1 = (back @ F[k - 1])[:3, 3]
            lines.append((o1, back[:3, :3] @ F[k - 1][:3, 2]))
            if np.linalg.norm(o1 - o0) > 1e-6:
                lines.append((o0, (o1 - o0) / np.linalg.norm(o1 - o0)))
        axes = np.array([d for _, d in lines])
        out = []
        for c in cover_shape(shape, max_capsules=self._params[0], gain=self._params[1],
                             axes=axes, lines=lines):
            out.append(Capsule(to_fast[:3, :3] @ c.a + to_fast[:3, 3],
                               to_fast[:3, :3] @ c.b + to_fast[:3, 3], c.r))
        return out

    @property
    def base_robot(self) -> Robot:
        return self._robot

    @property
    def G(self) -> Array:
        """Base frame -> this model's frame (joint 1's, its axis z)."""
        return self._G.copy()

    def dh_fixed_stack(self) -> Array:
        return self._F

    def fk(self, q: Array) -> Array:
        return self._Ginv @ self._robot.fk(q)

    def link_poses(self, q: Array) -> Array:
        return chain_frames_numpy(np.asarray(q, dtype=float).reshape(1, -1), self._F)[0]

    def batch_fk(self, Q: Array) -> BatchPoses:
        p = self._robot.batch_fk(Q)
        Rg, tg = self._Ginv[:3, :3], self._Ginv[:3, 3]
        return BatchPoses(np.asarray(p.positions) @ Rg.T + tg, Rg @ np.asarray(p.rotations))

    def batch_link_poses(self, Q: Array) -> Array:
        Q = np.ascontiguousarray(np.atleast_2d(Q), dtype=float)
        return batch_chain_frames(_Stack(self._F), Q)[0]

    def ik(self, T_base_tool: Array, seed: Array | None = None, *,
           position_only: bool = False) -> IKResult:
        raise NotImplementedError("the fast model answers collision questions only")

    def with_tool(self, T_flange_tool: Array) -> Robot:
        raise NotImplementedError("the fast model is read-only")

    def urdf(self) -> str:
        return self._robot.urdf()

    def description_hash(self) -> str:
        return f"{self._robot.description_hash()}:fast:{self._params}"


#: Bump when the capsule fitting changes: cached fits of the old one are not reused.
FIT_VERSION = 3
_FITS: dict[str, dict[tuple[int, int], list[Capsule]]] = {}


def _fit_file(key: str):
    from pathlib import Path

    env = os.environ.get("CELLTEACH_CACHE")
    root = Path(env) if env else Path.home() / ".cache" / "cellteach"
    name = hashlib.sha256(f"{key}:v{FIT_VERSION}".encode()).hexdigest()[:24]
    return root / "fast_model" / f"{name}.npz"


def _load(key: str) -> dict[tuple[int, int], list[Capsule]] | None:
    """A robot's capsules fitted before (this process, else the disk cache): the fit
    takes seconds, the robot's description decides it."""
    if key in _FITS:
        return _FITS[key]
    path = _fit_file(key)
    try:
        with np.load(path) as z:
            got: dict[tuple[int, int], list[Capsule]] = {}
            for kj, a, b, r in zip(z["shape"].tolist(), z["a"], z["b"], z["r"].tolist(),
                                   strict=True):
                got.setdefault((int(kj[0]), int(kj[1])), []).append(
                    Capsule(a.copy(), b.copy(), float(r)))
    except (OSError, KeyError, ValueError):
        return None
    _FITS[key] = got
    return got


def _save(key: str, fits: dict[tuple[int, int], list[Capsule]]) -> None:
    _FITS[key] = fits
    rows = [(kj, c) for kj, caps in sorted(fits.items()) for c in caps]
    path = _fit_file(key)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, shape=np.array([kj for kj, _ in rows], dtype=np.int64).reshape(-1, 2),
                 a=np.array([c.a for _, c in rows]).reshape(-1, 3),
                 b=np.array([c.b for _, c in rows]).reshape(-1, 3),
                 r=np.array([c.r for _, c in rows], dtype=float))
        os.replace(tmp, path)
    except OSError:  # a read-only cache: fitted again next time
        pass


_ROBOTS: dict[str, FastRobot] = {}


def fast_robot(robot: Robot, **params) -> FastRobot | None:
    """The fast model of `robot`, or None for a chain it cannot pose (`chain_of`); one per
    robot description and parameters in this process (a link subset of a robot, as the
    world build's chain levels view it, takes its capsules from the robot's own)."""
    if chain_of(robot) is None:
        return None
    key = f"{robot.description_hash()}:{sorted(params.items())}"
    got = _ROBOTS.get(key)
    if got is None:
        got = _ROBOTS.setdefault(key, FastRobot(robot, **params))
    return got


def fast_obstacles(obstacles: list[ObstacleView], G: Array) -> list[Obstacle]:
    """The obstacles in the fast model's frame, every shape as the box around it
    (`segment_box.oriented_bounds`: a box is itself) grown by its margin
    (`CollisionShape.margin`)."""
    Ginv = np.linalg.inv(G)
    out = []
    for ob in obstacles:
        T_ob = np.asarray(ob.T_base_object, dtype=float)
        boxes = []
        for s in ob.collision:
            o = oriented_bounds(s, T_ob)
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = o.R, o.centre
            half = o.half + float(s.margin)  # within its margin is the obstacle
            boxes.append(CollisionShape(ShapeKind.BOX, tuple(float(v) for v in 2.0 * half),
                                        Ginv @ T))
        out.append(Obstacle(ob.name, np.eye(4), tuple(boxes)))
    return out
