"""What every robot looks like to the rest of the core: joints, links with collision shapes, FK/IK.

Modelled on pinocchio's split: a `Robot` is an immutable description that is safe to share
across threads (the planner, the simulated link and the UI use the same one); scratch buffers
live in the algorithms, not here. `with_tool` returns a new robot rather than mutating.

Frames: ``T_base_link`` is a link frame in the robot base frame; ``T_base_tool`` is the TCP.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
import trimesh

Array = np.ndarray


@dataclass(frozen=True)
class JointLimits:
    """Per-joint position and speed limits (rad, rad/s), in joint order."""

    lower: Array
    upper: Array
    velocity: Array

    def contains(self, q: Array, tol: float = 1e-9) -> bool:
        q = np.asarray(q, dtype=float)
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))

    def contains_batch(self, Q: Array, tol: float = 1e-9) -> Array:
        Q = np.asarray(Q, dtype=float)
        return np.all((Q >= self.lower - tol) & (Q <= self.upper + tol), axis=-1)

    def violations(self, q: Array, names: list[str]) -> list[str]:
        """Human-readable list of the joints outside their range (degrees at the edge)."""
        out = []
        for i, v in enumerate(np.asarray(q, dtype=float)):
            if v < self.lower[i] - 1e-9 or v > self.upper[i] + 1e-9:
                out.append(
                    f"{names[i]}={np.degrees(v):.1f} deg outside "
                    f"[{np.degrees(self.lower[i]):.1f}, {np.degrees(self.upper[i]):.1f}]"
                )
        return out


class ShapeKind(str, Enum):
    CAPSULE = "capsule"  # size = (radius, length); axis along local z, centred
    CYLINDER = "cylinder"  # size = (radius, length); axis along local z, centred
    BOX = "box"  # size = (x, y, z) full extents, centred
    SPHERE = "sphere"  # size = (radius,)
    MESH = "mesh"  # mesh in the shape frame


@dataclass(frozen=True)
class CollisionShape:
    """One primitive or mesh fixed to a link, placed by ``T_link_shape``.

    `margin` (m): everything within this distance of the shape counts as the shape. A
    simplified collision proxy of a big CAD part carries the measured distance by which the
    part itself may lie outside the proxy, so the proxy plus its margin holds all of the
    part. The collision checks honour it for obstacles (robot shapes keep 0)."""

    kind: ShapeKind
    size: tuple[float, ...] = ()
    T_link_shape: Array = field(default_factory=lambda: np.eye(4))
    mesh: trimesh.Trimesh | None = None
    margin: float = 0.0

    def bounding_radius(self) -> float:
        """Radius of a sphere around the shape's origin that contains it (for broad phases)."""
        if self.kind in (ShapeKind.CAPSULE,):
            return self.size[0] + self.size[1] / 2.0
        if self.kind == ShapeKind.CYLINDER:
            return float(np.hypot(self.size[0], self.size[1] / 2.0))
        if self.kind == ShapeKind.BOX:
            return float(np.linalg.norm(self.size) / 2.0)
        if self.kind == ShapeKind.SPHERE:
            return self.size[0]
        assert self.mesh is not None
        return float(np.max(np.linalg.norm(self.mesh.vertices, axis=1)))

    def to_trimesh(self) -> trimesh.Trimesh:
        """Triangle mesh of the shape in the link frame (for drawing and URDF export)."""
        if self.kind == ShapeKind.CAPSULE:
            m = trimesh.creation.capsule(height=self.size[1], radius=self.size[0], count=[16, 8])
        elif self.kind == ShapeKind.CYLINDER:
            m = trimesh.creation.cylinder(radius=self.size[0], height=self.size[1], sections=24)
        elif self.kind == ShapeKind.BOX:
            m = trimesh.creation.box(extents=self.size)
        elif self.kind == ShapeKind.SPHERE:
            m = trimesh.creation.icosphere(subdivisions=2, radius=self.size[0])
        else:
            assert self.mesh is not None
            m = self.mesh.copy()
        m.apply_transform(self.T_link_shape)
        return m

    @staticmethod
    def capsule_between(p0: Array, p1: Array, radius: float) -> CollisionShape:
        """A capsule whose segment runs from p0 to p1 (link frame), e.g. along a DH link."""
        p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
        axis = p1 - p0
        length = float(np.linalg.norm(axis))
        z = axis / length if length > 1e-12 else np.array([0.0, 0.0, 1.0])
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        T = np.eye(4)
        T[:3, 0], T[:3, 1], T[:3, 2] = x, y, z
        T[:3, 3] = (p0 + p1) / 2.0
        return CollisionShape(ShapeKind.CAPSULE, (float(radius), length), T)

    def transformed(self, T_new_link: Array) -> CollisionShape:
        """The same shape expressed in another frame (T_new_link @ T_link_shape)."""
        return CollisionShape(self.kind, self.size, T_new_link @ self.T_link_shape, self.mesh,
                              self.margin)


@dataclass(frozen=True)
class LinkGeometry:
    """A rigid body of the robot: its collision shapes and a mesh to draw (both in link frame)."""

    name: str
    collision: tuple[CollisionShape, ...]
    visual: trimesh.Trimesh | None = None
    color: tuple[int, int, int] = (220, 220, 220)


@dataclass(frozen=True)
class Tool:
    """What is on the flange: the TCP offset and the tool's collision shapes (flange frame)."""

    name: str = "flange"
    T_flange_tool: Array = field(default_factory=lambda: np.eye(4))
    collision: tuple[CollisionShape, ...] = ()
    has_gripper: bool = False

    @staticmethod
    def straight(length: float, radius: float = 0.02, *, name: str = "gripper",
                 has_gripper: bool = True) -> Tool:
        """A tool along the flange z axis with its TCP `length` metres out (a pen, a gripper)."""
        T = np.eye(4)
        T[2, 3] = length
        shapes: tuple[CollisionShape, ...] = ()
        if length > 3 * radius:
            # The body stops one radius short of the TCP: touching a taught point on a part
            # is the application, not a collision.
            shapes = (CollisionShape.capsule_between([0, 0, radius], [0, 0, length - 2 * radius],
                                                     radius),)
        return Tool(name, T, shapes, has_gripper)


class IKFailure(str, Enum):
    REACH = "reach"
    JOINT_LIMIT = "joint_limit"
    ORIENTATION = "orientation"  # the 5-axis constraint, or no numeric convergence in orientation
    NO_CONVERGENCE = "no_convergence"


@dataclass(frozen=True)
class IKResult:
    """All solutions found (best first), or an honest reason and a nearby reachable pose."""

    solutions: list[Array]
    failure: IKFailure | None = None
    message: str = ""
    #: The closest pose the robot can reach (e.g. the orientation projected into the arm plane
    #: of a 5-axis robot). Offered to the operator; never silently substituted.
    nearest_T_base_tool: Array | None = None

    @property
    def ok(self) -> bool:
        return bool(self.solutions)

    def best(self, seed: Array | None = None) -> Array:
        """The solution closest to `seed` in joint space (or the first one)."""
        if not self.solutions:
            raise UnreachableError(self.message, self)
        if seed is None:
            return self.solutions[0]
        d = [float(np.linalg.norm(s - seed)) for s in self.solutions]
        return self.solutions[int(np.argmin(d))]


class UnreachableError(ValueError):
    """A target the robot cannot reach; carries the IK result with the reason."""

    def __init__(self, message: str, result: IKResult | None = None):
        super().__init__(message)
        self.result = result


@dataclass(frozen=True)
class BatchPoses:
    """TCP poses of N configurations: positions (N, 3) and rotation matrices (N, 3, 3)."""

    positions: Array
    rotations: Array


class Robot(abc.ABC):
    """An immutable serial robot. Subclasses provide kinematics; geometry lives in `links`."""

    name: str
    joint_names: list[str]
    limits: JointLimits
    #: Exactly dof + 1 entries: the base, then the link moved by each joint in chain order.
    #: Bodies fixed to a moving link (flange, hand, tool) are merged into that link.
    links: list[LinkGeometry]
    #: Flange -> tool centre point.
    T_flange_tool: Array

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @abc.abstractmethod
    def fk(self, q: Array) -> Array:
        """T_base_tool for one configuration."""

    @abc.abstractmethod
    def link_poses(self, q: Array) -> Array:
        """T_base_link for every entry of `links`, shape (len(links), 4, 4)."""

    @abc.abstractmethod
    def batch_fk(self, Q: Array) -> BatchPoses:
        """TCP poses of many configurations at once, Q shape (N, dof)."""

    @abc.abstractmethod
    def batch_link_poses(self, Q: Array) -> Array:
        """T_base_link for many configurations: shape (N, len(links), 4, 4)."""

    @abc.abstractmethod
    def ik(
        self,
        T_base_tool: Array,
        seed: Array | None = None,
        *,
        position_only: bool = False,
    ) -> IKResult:
        """All solutions within limits for a TCP pose (or only its position)."""

    @abc.abstractmethod
    def with_tool(self, T_flange_tool: Array) -> Robot:
        """The same robot with another tool (TCP offset)."""

    @abc.abstractmethod
    def urdf(self) -> str:
        """A URDF of the robot (visual + collision) for drawing and for pinocchio."""

    @abc.abstractmethod
    def description_hash(self) -> str:
        """A stable hash of everything that changes kinematics or geometry (cache keys)."""

    @property
    def model_limits(self) -> JointLimits:
        """The model's own joint ranges (the URDF's, the data sheet's), whatever the operator
        narrowed `limits` to: the self-collision rule is sampled over these."""
        return self.limits

    def rule_key(self) -> str:
        """A stable hash of what decides the self-collision rule: the links, their shapes,
        the tool and `model_limits` (not the operator's narrowed limits)."""
        return self.description_hash()

    def adjacent_link_pairs(self) -> set[tuple[int, int]]:
        """Pairs of link indices joined by a joint (never checked for self-collision)."""
        n = 1 + self.dof
        return {(i, i + 1) for i in range(n - 1)}

    def tcp_position(self, q: Array) -> Array:
        return self.fk(q)[:3, 3]

    def fixed_frame(self, name: str) -> Array | None:
        """Pose in the base frame of a named frame that does not move with the joints (e.g.
        the frame a controller reports poses in); None when the model has no such frame."""
        return None

    def program_frame(self) -> tuple[Array, str]:
        """(T_base_frame, its name in words): the frame the robot's controller takes poses
        in, as a program for it writes them. Default: the robot's mounting frame (the model
        base) itself."""
        return np.eye(4), "the robot's mounting frame"

    def arm_radii(self) -> Array:
        """Per joint, an upper bound (m) on the distance from its axis to any point beyond it.

        A joint step dq then moves no point of the arm more than sum(r_i |dq_i|): this steps
        the continuous collision check. Triangle inequality along the chain: link frames sit
        on their joint axes at fixed distances (true for DH and URDF frames) and each shape
        lies within its bounding sphere; the TCP counts as a point of the last link.
        Computed once per robot (robots are immutable): every joint interpolation asks.
        """
        cached = self.__dict__.get("_arm_radii")
        if cached is None:
            cached = self._compute_arm_radii()
            self.__dict__["_arm_radii"] = cached
        return cached.copy()

    def _compute_arm_radii(self) -> Array:
        frames = self.link_poses(np.zeros(self.dof))
        origins = frames[1 : self.dof + 1, :3, 3]
        T_last_tool = np.linalg.inv(frames[self.dof]) @ self.fk(np.zeros(self.dof))
        extents = []
        for k, link in enumerate(self.links[1 : self.dof + 1]):
            e = max((float(np.linalg.norm(s.T_link_shape[:3, 3])) + s.bounding_radius()
                     for s in link.collision), default=0.0)
            if k == self.dof - 1:
                e = max(e, float(np.linalg.norm(T_last_tool[:3, 3])))
            extents.append(e)
        radii = np.zeros(self.dof)
        for i in range(self.dof):
            acc, best = 0.0, 0.0
            for j in range(i, self.dof):
                if j > i:
                    acc += float(np.linalg.norm(origins[j] - origins[j - 1]))
                best = max(best, acc + extents[j])
            radii[i] = best
        return radii
