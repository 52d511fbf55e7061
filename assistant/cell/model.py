"""The robot cell: a robot and its base pose, named objects (CAD parts or primitives) and
named frames, all placed in the world frame.

Objects are immutable values (a new pose makes a new `CellObject`), so the UI and the planner
can hold one while the operator moves another; the `Cell` is the one mutable container.
Collision consumers see the cell only through `Cell.collision_objects_in_base()`.
Must not import the UI, planning or the world model.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from assistant.cell.cad.source import CadSource
from assistant.robots.catalog import RobotSpec
from assistant.robots.model import CollisionShape, Robot, ShapeKind
from assistant.transforms import inv_T

if TYPE_CHECKING:
    from assistant.cell.cad import CadImport

Array = np.ndarray

__all__ = [
    "CadSource",
    "Cell",
    "CellError",
    "CellObject",
    "CollisionObjectView",
    "ObjectRole",
    "PrimitiveKind",
    "PrimitiveSpec",
    "check_transform",
]


class CellError(ValueError):
    """A cell change that cannot be made (unknown name, duplicate, bad pose); nothing changed."""


class ObjectRole(str, Enum):
    OBSTACLE = "obstacle"  # must never be touched
    FIXTURE = "fixture"  # holds workpieces; touched only by what it holds
    WORKPIECE = "workpiece"  # what the robot works on or carries


#: Default colours (r, g, b 0-255) by role: obstacles warm, fixtures neutral, workpieces bright.
DEFAULT_COLORS: dict[ObjectRole, tuple[int, int, int]] = {
    ObjectRole.OBSTACLE: (200, 90, 70),
    ObjectRole.FIXTURE: (130, 145, 170),
    ObjectRole.WORKPIECE: (240, 175, 40),
}

_ROTATION_TOL = 1e-6
_NAME_RE = re.compile(r"^[^\x00-\x1f\x7f]{1,128}$")


def check_transform(T: Any, what: str) -> Array:
    """`T` as a float 4x4 rigid transform, or a CellError saying what is wrong with it."""
    try:
        M = np.array(T, dtype=float)
    except (TypeError, ValueError) as exc:
        raise CellError(f"{what}: not a 4x4 matrix of numbers ({exc})") from exc
    if M.shape != (4, 4):
        raise CellError(f"{what}: expected a 4x4 transform, got shape {M.shape}")
    if not np.isfinite(M).all():
        raise CellError(f"{what}: contains NaN or infinite values")
    if not np.allclose(M[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise CellError(f"{what}: last row must be 0 0 0 1")
    R = M[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=_ROTATION_TOL) or np.linalg.det(R) < 0.0:
        raise CellError(f"{what}: the rotation part is not a proper rotation (orthonormal, "
                        "det +1); scaling or mirroring is not a pose")
    M[3] = (0.0, 0.0, 0.0, 1.0)
    return M


def _check_name(name: Any, what: str = "object") -> str:
    if not isinstance(name, str) or not _NAME_RE.match(name) or name.strip() != name:
        raise CellError(f"{what} name {name!r} is not usable: give 1-128 printable characters "
                        "without leading/trailing spaces")
    return name


def _check_color(color: Any) -> tuple[int, int, int]:
    try:
        c = tuple(int(v) for v in color)
        ok = len(c) == 3 and all(0 <= v <= 255 for v in c) and all(
            float(v) == int(v) for v in color)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise CellError(f"colour {color!r}: give three whole numbers 0-255 (r, g, b)")
    return c  # type: ignore[return-value]


class PrimitiveKind(str, Enum):
    BOX = "box"  # size = (x, y, z) full extents, centred on the object frame
    CYLINDER = "cylinder"  # size = (radius, height), axis = object z, centred
    SPHERE = "sphere"  # size = (radius,)


_PRIMITIVE_SIZES = {PrimitiveKind.BOX: 3, PrimitiveKind.CYLINDER: 2, PrimitiveKind.SPHERE: 1}


@dataclass(frozen=True)
class PrimitiveSpec:
    """A box, cylinder or sphere in metres: exact for collision, cheap to store."""

    kind: PrimitiveKind
    size: tuple[float, ...]

    def __post_init__(self) -> None:
        try:
            kind = PrimitiveKind(self.kind)
        except ValueError:
            raise CellError(f"unknown primitive {self.kind!r} (box, cylinder, sphere)") from None
        try:
            size = tuple(float(v) for v in self.size)
        except (TypeError, ValueError):
            raise CellError(f"{kind.value} size {self.size!r}: not numbers") from None
        if len(size) != _PRIMITIVE_SIZES[kind]:
            raise CellError(f"a {kind.value} needs {_PRIMITIVE_SIZES[kind]} size value(s), "
                            f"got {len(size)}")
        if not all(math.isfinite(v) and v > 0.0 for v in size):
            raise CellError(f"{kind.value} size {size}: every dimension must be > 0")
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "size", size)

    def collision_shape(self) -> CollisionShape:
        shape_kind = {PrimitiveKind.BOX: ShapeKind.BOX, PrimitiveKind.CYLINDER: ShapeKind.CYLINDER,
                      PrimitiveKind.SPHERE: ShapeKind.SPHERE}[self.kind]
        return CollisionShape(shape_kind, self.size)

    def mesh(self) -> trimesh.Trimesh:
        if self.kind == PrimitiveKind.BOX:
            return trimesh.creation.box(extents=self.size)
        if self.kind == PrimitiveKind.CYLINDER:
            return trimesh.creation.cylinder(radius=self.size[0], height=self.size[1],
                                             sections=48)
        return trimesh.creation.icosphere(subdivisions=3, radius=self.size[0])

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind.value, "size": list(self.size)}

    @staticmethod
    def from_json(d: Any) -> PrimitiveSpec:
        if not isinstance(d, dict) or "kind" not in d or "size" not in d:
            raise CellError("a primitive needs 'kind' and 'size'")
        if not isinstance(d["size"], list):
            raise CellError("primitive size must be a list of numbers")
        return PrimitiveSpec(d["kind"], tuple(d["size"]))


@dataclass(frozen=True, eq=False)
class CellObject:
    """A placed part. Geometry is in the object frame (metres); `T_world_object` places it."""

    name: str
    role: ObjectRole
    T_world_object: Array
    display_mesh: trimesh.Trimesh
    collision: tuple[CollisionShape, ...]
    color: tuple[int, int, int] | None = None
    #: How far the collision proxy deviates from the part (0 when it is exact).
    proxy_deviation_m: float = 0.0
    primitive: PrimitiveSpec | None = None
    source: CadSource | None = None
    #: The part at full resolution (picking, sizes, reports) when `display_mesh` is a
    #: decimated copy of a big part; else `display_mesh` itself.
    full_mesh: trimesh.Trimesh | None = None

    def __post_init__(self) -> None:
        _check_name(self.name)
        try:
            role = ObjectRole(self.role)
        except ValueError:
            raise CellError(f"object {self.name!r}: unknown role {self.role!r} "
                            "(obstacle, fixture, workpiece)") from None
        object.__setattr__(self, "role", role)
        color = DEFAULT_COLORS[role] if self.color is None else _check_color(self.color)
        object.__setattr__(self, "color", color)
        T = check_transform(self.T_world_object, f"pose of {self.name!r}")
        T.setflags(write=False)  # shared between threads: a new pose is a new object
        object.__setattr__(self, "T_world_object", T)
        object.__setattr__(self, "collision", tuple(self.collision))
        if self.full_mesh is None:
            object.__setattr__(self, "full_mesh", self.display_mesh)
        if not self.collision:
            raise CellError(f"object {self.name!r} has no collision geometry")

    @property
    def part_mesh(self) -> trimesh.Trimesh:
        """The part at full resolution (`full_mesh`, which making the object sets)."""
        return self.full_mesh if self.full_mesh is not None else self.display_mesh

    # -- factories --------------------------------------------------------------------------

    @staticmethod
    def from_primitive(name: str, primitive: PrimitiveSpec, T_world_object: Array | None = None,
                       *, role: ObjectRole | str = ObjectRole.OBSTACLE,
                       color: tuple[int, int, int] | None = None) -> CellObject:
        return CellObject(name=name, role=role,  # type: ignore[arg-type]
                          T_world_object=np.eye(4) if T_world_object is None else T_world_object,
                          display_mesh=primitive.mesh(), collision=(primitive.collision_shape(),),
                          color=color, primitive=primitive)

    @staticmethod
    def box(name: str, size: Iterable[float], T_world_object: Array | None = None, *,
            role: ObjectRole | str = ObjectRole.OBSTACLE,
            color: tuple[int, int, int] | None = None) -> CellObject:
        """A box with full extents `size` (x, y, z metres), centred on its frame."""
        return CellObject.from_primitive(name, PrimitiveSpec(PrimitiveKind.BOX, tuple(size)),
                                         T_world_object, role=role, color=color)

    @staticmethod
    def cylinder(name: str, radius: float, height: float, T_world_object: Array | None = None,
                 *, role: ObjectRole | str = ObjectRole.OBSTACLE,
                 color: tuple[int, int, int] | None = None) -> CellObject:
        """A cylinder along its frame's z axis, centred on the frame."""
        spec = PrimitiveSpec(PrimitiveKind.CYLINDER, (radius, height))
        return CellObject.from_primitive(name, spec, T_world_object, role=role, color=color)

    @staticmethod
    def sphere(name: str, radius: float, T_world_object: Array | None = None, *,
               role: ObjectRole | str = ObjectRole.OBSTACLE,
               color: tuple[int, int, int] | None = None) -> CellObject:
        spec = PrimitiveSpec(PrimitiveKind.SPHERE, (radius,))
        return CellObject.from_primitive(name, spec, T_world_object, role=role, color=color)

    @staticmethod
    def from_cad(name: str, cad_import: CadImport, T_world_object: Array | None = None, *,
                 role: ObjectRole | str = ObjectRole.OBSTACLE,
                 color: tuple[int, int, int] | None = None) -> CellObject:
        """A part from `assistant.cell.cad.load_cad`; its frame is the CAD file's own origin."""
        return CellObject(name=name, role=role,  # type: ignore[arg-type]
                          T_world_object=np.eye(4) if T_world_object is None else T_world_object,
                          display_mesh=cad_import.display_mesh,
                          collision=cad_import.collision, color=color,
                          proxy_deviation_m=cad_import.proxy.deviation_m,
                          source=cad_import.source, full_mesh=cad_import.mesh)

    def with_pose(self, T_world_object: Array) -> CellObject:
        return replace(self, T_world_object=T_world_object)

    @property
    def collision_margin_m(self) -> float:
        """How far around its collision shapes the part may reach (a big part's proxy)."""
        return max((float(s.margin) for s in self.collision), default=0.0)


@dataclass(frozen=True, eq=False)
class CollisionObjectView:
    """What the collision checker needs of one object, in the robot base frame
    (`assistant.collision.checker.ObstacleView`)."""

    name: str
    role: ObjectRole
    T_base_object: Array
    #: Collision shapes in the object frame (as `CellObject.collision`).
    collision: tuple[CollisionShape, ...]


@functools.lru_cache(maxsize=8)
def _robot_for(spec: RobotSpec) -> Robot:
    # Robots are immutable, so cells with equal specs can share one (and its caches).
    return spec.build()


@dataclass(eq=False)
class Cell:
    """A robot at `T_world_base`, named objects in insertion order, and named frames."""

    robot_spec: RobotSpec = field(default_factory=RobotSpec)
    T_world_base: Array = field(default_factory=lambda: np.eye(4))
    objects: dict[str, CellObject] = field(default_factory=dict)
    #: Named frames (taught reference frames, pallet origins...): name -> T_world_frame.
    frames: dict[str, Array] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.T_world_base = check_transform(self.T_world_base, "robot base pose")
        objects, self.objects = dict(self.objects), {}
        for key, obj in objects.items():
            if key != obj.name:
                raise CellError(f"object stored as {key!r} is named {obj.name!r}")
            self.add_object(obj)
        frames, self.frames = dict(self.frames), {}
        for name, T in frames.items():
            self.add_frame(name, T)

    # -- robot --------------------------------------------------------------------------------

    def robot(self) -> Robot:
        """The robot built from `robot_spec` (built once per spec and shared)."""
        return _robot_for(self.robot_spec)

    def set_base_pose(self, T_world_base: Array) -> None:
        self.T_world_base = check_transform(T_world_base, "robot base pose")

    # -- objects ------------------------------------------------------------------------------

    def unique_name(self, base: str) -> str:
        """`base` if free, else `base_2`, `base_3`, ... (for imports named after files)."""
        base = re.sub(r"[\x00-\x1f\x7f]", "", str(base)).strip()[:120] or "object"
        if base not in self.objects:
            return base
        k = 2
        while f"{base}_{k}" in self.objects:
            k += 1
        return f"{base}_{k}"

    def add_object(self, obj: CellObject) -> CellObject:
        if not isinstance(obj, CellObject):
            raise CellError(f"expected a CellObject, got {type(obj).__name__}")
        if obj.name in self.objects:
            raise CellError(f"an object named {obj.name!r} already exists; choose another name "
                            f"(e.g. {self.unique_name(obj.name)!r})")
        self.objects[obj.name] = obj
        return obj

    def get_object(self, name: str) -> CellObject:
        try:
            return self.objects[name]
        except KeyError:
            known = ", ".join(self.objects) or "none"
            raise CellError(f"no object named {name!r} (objects: {known})") from None

    def remove_object(self, name: str) -> CellObject:
        obj = self.get_object(name)
        del self.objects[name]
        return obj

    def set_object_pose(self, name: str, T_world_object: Array) -> CellObject:
        obj = self.get_object(name).with_pose(T_world_object)
        self.objects[name] = obj
        return obj

    def T_base_object(self, name: str) -> Array:
        return inv_T(self.T_world_base) @ self.get_object(name).T_world_object

    def collision_objects_in_base(self) -> list[CollisionObjectView]:
        """Every object's collision shapes and pose in the robot base frame, in cell order."""
        T_base_world = inv_T(self.T_world_base)
        return [CollisionObjectView(o.name, o.role, T_base_world @ o.T_world_object, o.collision)
                for o in self.objects.values()]

    # -- frames -------------------------------------------------------------------------------

    def add_frame(self, name: str, T_world_frame: Array, *, replace_existing: bool = False) -> None:
        _check_name(name, "frame")
        if name in self.frames and not replace_existing:
            raise CellError(f"a frame named {name!r} already exists")
        self.frames[name] = check_transform(T_world_frame, f"frame {name!r}")

    def remove_frame(self, name: str) -> None:
        if name not in self.frames:
            known = ", ".join(self.frames) or "none"
            raise CellError(f"no frame named {name!r} (frames: {known})")
        del self.frames[name]

    def T_base_frame(self, name: str) -> Array:
        if name not in self.frames:
            raise CellError(f"no frame named {name!r}")
        return inv_T(self.T_world_base) @ self.frames[name]
