"""Any serial robot described by a URDF: kinematics from pinocchio, geometry from the URDF.

What it owns: reading a URDF and its meshes (``package://``, ``file://`` and relative paths),
choosing the base and tool frames, turning the kinematic tree into the `Robot` interface (one
actuated serial chain, everything else locked), FK (single through pinocchio, batched through
`assistant.robots.batch_chain`) and numeric IK (damped least squares on pinocchio's frame Jacobian).
It does not draw, check collisions or plan; it must not import viser.

Why the split: pinocchio parses the kinematics and is the reference every result is tested
against; lxml reads the XML ourselves because the operator needs an error that names the file,
the line and the element, and because collision/visual geometry is needed as trimesh meshes and
primitives, not as pinocchio geometry objects.
"""

from __future__ import annotations

import hashlib
import json
import threading
import urllib.parse
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
import trimesh
from lxml import etree

from assistant.robots.batch_chain import BatchChain, ChainJoint, JointKind
from assistant.robots.catalog import RobotModelError
from assistant.robots.model import (
    BatchPoses,
    CollisionShape,
    IKFailure,
    IKResult,
    JointLimits,
    LinkGeometry,
    Robot,
    ShapeKind,
    Tool,
)
from assistant.transforms import inv_T, orthonormalized, rotation_angle

Array = np.ndarray

#: Collision meshes with more faces than this are replaced by their convex hull. FCL's cost
#: grows with the triangle count and the planner checks millions of poses; a hull is a safe
#: (conservative) proxy for a link. Visual meshes are never simplified.
COLLISION_FACE_LIMIT = 3000
#: Default speed (rad/s or m/s) for a chain joint whose URDF <limit> gives none.
DEFAULT_VELOCITY = 1.0
#: Range given to continuous (unbounded) joints: one turn each way.
CONTINUOUS_RANGE = 2.0 * np.pi
#: Name of the TCP frame added to the pinocchio model.
TCP_FRAME = "cellteach_tcp"

_ACTUATED = {"revolute": JointKind.REVOLUTE, "continuous": JointKind.REVOLUTE,
             "prismatic": JointKind.PRISMATIC}
_JOINT_TYPES = {"revolute", "continuous", "prismatic", "fixed", "floating", "planar"}


# ============================================================================ parsed document
@dataclass(frozen=True)
class _Geometry:
    """One <visual> or <collision> element, placed in its URDF link's frame."""

    kind: ShapeKind
    size: tuple[float, ...]
    T_link_geom: Array
    line: int
    filename: str | None = None  # as written in the URDF
    path: Path | None = None  # resolved file
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rgba: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class _Link:
    name: str
    line: int
    visuals: tuple[_Geometry, ...]
    collisions: tuple[_Geometry, ...]


@dataclass(frozen=True)
class _Joint:
    name: str
    type: str
    parent: str
    child: str
    line: int
    axis: Array
    lower: float
    upper: float
    velocity: float


@dataclass
class _Document:
    """A parsed URDF with resolved mesh paths; shared by the robots derived from it.

    Immutable after construction except `meshes`, a load cache (so `with_tool`/`with_limits`
    never reload files).
    """

    source: str
    base_dir: Path
    text: str
    tree: etree._Element
    name: str
    links: dict[str, _Link]
    joints: dict[str, _Joint]
    parent_joint: dict[str, _Joint]
    children: dict[str, list[_Joint]]
    root: str
    model: pin.Model
    mesh_digests: dict[str, str]
    meshes: dict[tuple[Path, bool], trimesh.Trimesh] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def where(self, line: int) -> str:
        return f"{self.source}:{line}"


def _parse(text: str, source: str, base_dir: Path, package_dirs: Sequence[str | Path]
           ) -> _Document:
    try:
        root_el = etree.fromstring(text.encode() if isinstance(text, str) else text)
    except etree.XMLSyntaxError as e:
        raise RobotModelError(f"{source}:{e.lineno}: malformed XML: {e.msg}") from None
    if root_el.tag != "robot":
        raise RobotModelError(f"{source}:{root_el.sourceline}: the root element is "
                              f"<{root_el.tag}>, a URDF needs <robot>")
    materials = _materials(root_el, source)
    mesh_digests: dict[str, str] = {}
    links: dict[str, _Link] = {}
    for el in root_el.findall("link"):
        name = _required(el, "name", source)
        if name in links:
            raise RobotModelError(f"{source}:{el.sourceline}: link {name!r} is defined twice")
        geoms = {}
        for tag in ("visual", "collision"):
            geoms[tag] = tuple(
                _geometry(g, tag, name, source, base_dir, package_dirs, materials, mesh_digests)
                for g in el.findall(tag))
        links[name] = _Link(name, el.sourceline, geoms["visual"], geoms["collision"])
    if not links:
        raise RobotModelError(f"{source}: the URDF has no <link>")
    joints: dict[str, _Joint] = {}
    parent_joint: dict[str, _Joint] = {}
    children: dict[str, list[_Joint]] = {n: [] for n in links}
    for el in root_el.findall("joint"):
        j = _joint(el, source, links)
        if j.name in joints:
            raise RobotModelError(f"{source}:{el.sourceline}: joint {j.name!r} is defined twice")
        if j.child in parent_joint:
            raise RobotModelError(
                f"{source}:{el.sourceline}: joint {j.name!r}: link {j.child!r} already has a "
                f"parent joint ({parent_joint[j.child].name!r}); a URDF must be a tree")
        joints[j.name] = j
        parent_joint[j.child] = j
        children[j.parent].append(j)
    roots = [n for n in links if n not in parent_joint]
    if len(roots) != 1:
        what = ", ".join(repr(r) for r in roots) if roots else "none (the joints form a loop)"
        raise RobotModelError(f"{source}: a URDF needs exactly one root link, found {what}")
    _check_reachable(roots[0], links, children, source)
    try:
        model = pin.buildModelFromXML(text if isinstance(text, str) else text.decode())
    except Exception as e:  # pinocchio raises plain RuntimeError/ValueError
        raise RobotModelError(f"{source}: pinocchio cannot build a model: {e}") from None
    return _Document(source, base_dir, text, root_el, root_el.get("name", "robot"), links,
                     joints, parent_joint, children, roots[0], model, mesh_digests)


def _check_reachable(root: str, links: dict[str, _Link], children: dict[str, list[_Joint]],
                     source: str) -> None:
    seen, stack = {root}, [root]
    while stack:
        for j in children[stack.pop()]:
            if j.child not in seen:
                seen.add(j.child)
                stack.append(j.child)
    lost = [n for n in links if n not in seen]
    if lost:
        raise RobotModelError(f"{source}:{links[lost[0]].line}: link {lost[0]!r} is not "
                              "connected to the root (the joints form a loop)")


def _required(el: etree._Element, attr: str, source: str) -> str:
    v = el.get(attr)
    if v is None or not v.strip():
        raise RobotModelError(f"{source}:{el.sourceline}: <{el.tag}> needs a {attr!r} attribute")
    return v.strip()


def _floats(el: etree._Element, attr: str, n: int, source: str, default: str | None = None
            ) -> Array:
    raw = el.get(attr, default)
    if raw is None:
        raise RobotModelError(f"{source}:{el.sourceline}: <{el.tag}> needs a {attr!r} attribute")
    try:
        v = np.array([float(t) for t in raw.split()], dtype=float)
    except ValueError:
        v = np.array([])
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise RobotModelError(f"{source}:{el.sourceline}: <{el.tag} {attr}={raw!r}> must be "
                              f"{n} finite number{'s' if n > 1 else ''}")
    return v


def _origin(parent: etree._Element, source: str) -> Array:
    """The <origin xyz rpy> of an element; URDF rpy is R = Rz(yaw) Ry(pitch) Rx(roll)."""
    el = parent.find("origin")
    T = np.eye(4)
    if el is None:
        return T
    xyz = _floats(el, "xyz", 3, source, "0 0 0")
    rpy = _floats(el, "rpy", 3, source, "0 0 0")
    T[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
    T[:3, 3] = xyz
    return T


def _materials(root_el: etree._Element, source: str) -> dict[str, tuple[float, ...]]:
    """Top-level named materials, which <visual> elements may refer to by name."""
    out = {}
    for m in root_el.findall("material"):
        c = m.find("color")
        if m.get("name") and c is not None and c.get("rgba"):
            out[m.get("name")] = tuple(float(v) for v in _floats(c, "rgba", 4, source))
    return out


def _geometry(el: etree._Element, tag: str, link: str, source: str, base_dir: Path,
              package_dirs: Sequence[str | Path], materials: dict, digests: dict[str, str]
              ) -> _Geometry:
    T = _origin(el, source)
    g = el.find("geometry")
    if g is None or len(g) == 0:
        raise RobotModelError(f"{source}:{el.sourceline}: link {link!r}: <{tag}> has no "
                              "<geometry>")
    shape = next((c for c in g if isinstance(c.tag, str)), None)
    if shape is None:
        raise RobotModelError(f"{source}:{g.sourceline}: link {link!r}: <geometry> is empty")
    rgba = None
    mat = el.find("material")
    if mat is not None:
        c = mat.find("color")
        if c is not None and c.get("rgba"):
            rgba = tuple(_floats(c, "rgba", 4, source))
        else:
            rgba = materials.get(mat.get("name", ""))
    kind = shape.tag
    if kind == "box":
        return _Geometry(ShapeKind.BOX, tuple(_floats(shape, "size", 3, source)), T,
                         el.sourceline, rgba=rgba)
    if kind in ("cylinder", "capsule"):
        r = float(_floats(shape, "radius", 1, source)[0])
        length = float(_floats(shape, "length", 1, source)[0])
        sk = ShapeKind.CYLINDER if kind == "cylinder" else ShapeKind.CAPSULE
        return _Geometry(sk, (r, length), T, el.sourceline, rgba=rgba)
    if kind == "sphere":
        return _Geometry(ShapeKind.SPHERE, (float(_floats(shape, "radius", 1, source)[0]),), T,
                         el.sourceline, rgba=rgba)
    if kind == "mesh":
        filename = _required(shape, "filename", source)
        s = shape.get("scale")
        scale = (1.0, 1.0, 1.0)
        if s is not None:
            parts = s.split()
            scale = tuple(_floats(shape, "scale", 1, source)) * 3 if len(parts) == 1 else \
                tuple(_floats(shape, "scale", 3, source))
        path = resolve_mesh_path(filename, base_dir, package_dirs,
                                 where=f"{source}:{shape.sourceline}: link {link!r} <{tag}>")
        if filename not in digests:
            digests[filename] = hashlib.sha256(path.read_bytes()).hexdigest()
        return _Geometry(ShapeKind.MESH, (), T, el.sourceline, filename, path,
                         tuple(float(v) for v in scale), rgba)
    raise RobotModelError(f"{source}:{shape.sourceline}: link {link!r}: unknown geometry "
                          f"<{kind}> (box, cylinder, sphere, capsule or mesh)")


def resolve_mesh_path(filename: str, base_dir: Path, package_dirs: Sequence[str | Path] = (),
                      *, where: str = "") -> Path:
    """The file a URDF mesh reference points at.

    ``package://pkg/rel`` is looked up as ``<dir>/pkg/rel`` (or ``<dir>/rel`` when the folder
    itself is named ``pkg``) for every folder in `package_dirs`, then in the URDF folder and
    each of its ancestors - which covers the ROS layout ``pkg/urdf/robot.urdf`` and
    example-robot-data's ``share/example-robot-data/robots/...``. ``file://`` URIs and absolute
    paths are taken as they are; other paths are relative to the URDF folder.
    """
    tried: list[Path] = []
    if filename.startswith("package://"):
        rest = filename[len("package://"):]
        pkg, _, rel = rest.partition("/")
        if not pkg or not rel:
            raise RobotModelError(f"{where}: malformed package URI {filename!r}")
        dirs = [Path(d).expanduser() for d in package_dirs]
        dirs += [base_dir, *base_dir.parents]
        for d in dirs:
            for cand in ((d / rel) if d.name == pkg else None, d / pkg / rel):
                if cand is not None and cand not in tried:
                    tried.append(cand)
                    if cand.is_file():
                        return cand.resolve()
    else:
        if filename.startswith("file://"):
            p = Path(urllib.parse.unquote(urllib.parse.urlparse(filename).path))
        elif "://" in filename:
            raise RobotModelError(f"{where}: unsupported mesh URI {filename!r} "
                                  "(use package://, file:// or a path)")
        else:
            p = Path(filename)
        cand = p if p.is_absolute() else base_dir / p
        tried.append(cand)
        if cand.is_file():
            return cand.resolve()
    shown = ", ".join(str(t) for t in tried[:8]) + (" ..." if len(tried) > 8 else "")
    raise RobotModelError(f"{where}: mesh file not found: {filename!r} (tried: {shown})")


def _joint(el: etree._Element, source: str, links: dict[str, _Link]) -> _Joint:
    name = _required(el, "name", source)
    jtype = _required(el, "type", source)
    if jtype not in _JOINT_TYPES:
        raise RobotModelError(f"{source}:{el.sourceline}: joint {name!r} has unknown type "
                              f"{jtype!r}")
    ends = {}
    for tag in ("parent", "child"):
        e = el.find(tag)
        if e is None:
            raise RobotModelError(f"{source}:{el.sourceline}: joint {name!r} has no <{tag}>")
        link = _required(e, "link", source)
        if link not in links:
            raise RobotModelError(f"{source}:{e.sourceline}: joint {name!r}: <{tag} "
                                  f"link={link!r}> is not a link of this URDF")
        ends[tag] = link
    axis = np.array([1.0, 0.0, 0.0])
    ax = el.find("axis")
    if ax is not None:
        axis = _floats(ax, "xyz", 3, source)
        n = np.linalg.norm(axis)
        if n < 1e-12 and jtype in _ACTUATED:
            raise RobotModelError(f"{source}:{ax.sourceline}: joint {name!r}: the axis is zero")
        axis = axis / n if n > 0 else axis
    lower = upper = 0.0
    velocity = DEFAULT_VELOCITY
    lim = el.find("limit")
    if jtype in ("revolute", "prismatic"):
        if lim is None:
            raise RobotModelError(f"{source}:{el.sourceline}: {jtype} joint {name!r} needs a "
                                  "<limit lower upper velocity effort>")
        lower = float(_floats(lim, "lower", 1, source, "0")[0])
        upper = float(_floats(lim, "upper", 1, source, "0")[0])
        if lower > upper:
            raise RobotModelError(f"{source}:{lim.sourceline}: joint {name!r}: lower limit "
                                  f"{lower} is above the upper limit {upper}")
    elif jtype == "continuous":
        lower, upper = -CONTINUOUS_RANGE, CONTINUOUS_RANGE
    if lim is not None and lim.get("velocity") is not None:
        v = float(_floats(lim, "velocity", 1, source)[0])
        velocity = v if v > 0 else DEFAULT_VELOCITY
    return _Joint(name, jtype, ends["parent"], ends["child"], el.sourceline, axis, lower, upper,
                  velocity)


# ============================================================================ IK settings
@dataclass(frozen=True)
class IKSettings:
    """Damped least squares parameters; the defaults suit arms of 0.3-2 m."""

    #: Iterations per start configuration (most runs converge in 10-60).
    max_iterations: int = 150
    #: Random starts tried after the seed (or the home configuration without a seed).
    restarts: int = 12
    #: More random starts, only when the first ones found nothing (targets that only one
    #: narrow branch reaches inside the limits).
    extra_restarts: int = 36
    #: Stop once this many distinct solutions are found.
    max_solutions: int = 4
    #: lambda of dq = J^T (J J^T + lambda^2 I)^-1 e: bounded steps near singularities. It is
    #: scaled by min(1, |e| / `damping_error`) (Levenberg-Marquardt style), so the last steps
    #: are Gauss-Newton and converge fast even close to a singular configuration.
    damping: float = 1e-2
    damping_error: float = 0.01
    #: Largest joint step per iteration (rad or m): keeps an iteration inside the linear range.
    max_step: float = 0.4
    position_tolerance: float = 1e-6
    orientation_tolerance: float = 1e-5
    #: Solutions closer than this in joint space (rad/m, Euclidean) count as one.
    distinct: float = 1e-3
    #: Seed of the random restarts: the same call always gives the same answer.
    rng_seed: int = 0


# ============================================================================ the robot
class URDFRobot(Robot):
    """A serial chain from `base_link` to `tool_link` of a URDF; other joints are locked.

    Link frames are URDF link frames, i.e. each moving link's frame is its joint frame and
    lies on the joint axis. Bodies that do not move relative to a chain link (fixed joints,
    locked joints such as gripper fingers, anything above the base) are merged into it, their
    shapes re-expressed in its frame. Collision meshes above `COLLISION_FACE_LIMIT` faces are
    replaced by their convex hull.

    Build one with `from_file` / `from_string`; the constructor takes an already parsed
    document and is what `with_tool` / `with_limits` use to share it (meshes load once).
    """

    def __init__(self, doc: _Document, *, base_link: str | None = None,
                 tool_link: str | None = None, tool: Tool | None = None,
                 limits: Array | None = None,
                 locked_positions: Mapping[str, float] | None = None,
                 load_visual: bool = True, ik_settings: IKSettings | None = None):
        self._doc = doc
        self.name = doc.name
        self.base_link = base_link or doc.root
        self._check_link(self.base_link, "base")
        self.tool_link = tool_link or _default_tool_link(doc, self.base_link)
        self._check_link(self.tool_link, "tool")
        self.tool = tool or Tool()
        self.T_flange_tool = np.asarray(self.tool.T_flange_tool, dtype=float)
        if self.T_flange_tool.shape != (4, 4):
            raise RobotModelError(f"tool {self.tool.name!r}: T_flange_tool must be 4x4")
        self.ik_settings = ik_settings or IKSettings()
        self._load_visual = load_visual

        path = self._path()
        chain = [j for j in path if j.type in _ACTUATED]
        if not chain:
            raise RobotModelError(f"{doc.source}: no actuated joint between base link "
                                  f"{self.base_link!r} and tool link {self.tool_link!r}")
        self._chain_joints = chain
        self.joint_names = [j.name for j in chain]
        self.locked_positions = self._locked(locked_positions, {j.name for j in chain})
        self._build_model()
        self._build_chain()
        lower = np.array([j.lower for j in chain])
        upper = np.array([j.upper for j in chain])
        if limits is not None:
            lower, upper = limits[:, 0].copy(), limits[:, 1].copy()
        self.limits = JointLimits(lower, upper, np.array([j.velocity for j in chain]))
        self.links = self._build_links(path)
        self._local = threading.local()

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_file(cls, path: Path | str, *, package_dirs: Sequence[str | Path] = (),
                  base_link: str | None = None, tool_link: str | None = None,
                  tool: Tool | None = None, locked_positions: Mapping[str, float] | None = None,
                  load_visual: bool = True, ik_settings: IKSettings | None = None
                  ) -> URDFRobot:
        """Load a URDF file and its meshes.

        Args:
            path: the .urdf file (xacro must be expanded first).
            package_dirs: folders that contain ROS packages (or are one) for package:// URIs.
            base_link: the robot base frame; default the URDF's root link.
            tool_link: the flange; default the end of the chain with the most actuated joints.
            tool: TCP offset and tool shapes relative to `tool_link`.
            locked_positions: values of joints off the chain (e.g. gripper opening); default
                0 clamped into the joint's range.
            load_visual: False skips visual meshes (batch tools that never draw).
        Returns:
            The robot. Raises `RobotModelError` naming the file and element on bad input.
        """
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            raise RobotModelError(f"{path}: cannot read the URDF: {e}") from None
        doc = _parse(text, str(path), path.resolve().parent, package_dirs)
        return cls(doc, base_link=base_link, tool_link=tool_link, tool=tool,
                   locked_positions=locked_positions, load_visual=load_visual,
                   ik_settings=ik_settings)

    @classmethod
    def from_string(cls, xml: str, *, base_dir: Path | str,
                    package_dirs: Sequence[str | Path] = (), base_link: str | None = None,
                    tool_link: str | None = None, tool: Tool | None = None,
                    locked_positions: Mapping[str, float] | None = None,
                    load_visual: bool = True, ik_settings: IKSettings | None = None,
                    source: str = "<URDF string>") -> URDFRobot:
        """Like `from_file` for URDF text; relative mesh paths are resolved against base_dir."""
        doc = _parse(xml, source, Path(base_dir).resolve(), package_dirs)
        return cls(doc, base_link=base_link, tool_link=tool_link, tool=tool,
                   locked_positions=locked_positions, load_visual=load_visual,
                   ik_settings=ik_settings)

    def _derive(self, **changes) -> URDFRobot:
        kw = dict(base_link=self.base_link, tool_link=self.tool_link, tool=self.tool,
                  limits=np.column_stack([self.limits.lower, self.limits.upper]),
                  locked_positions=self.locked_positions, load_visual=self._load_visual,
                  ik_settings=self.ik_settings)
        kw.update(changes)
        return URDFRobot(self._doc, **kw)

    def with_tool(self, T_flange_tool: Array | Tool) -> URDFRobot:
        tool = T_flange_tool if isinstance(T_flange_tool, Tool) else Tool(
            "custom", np.asarray(T_flange_tool, dtype=float))
        return self._derive(tool=tool)

    def with_limits(self, limits_rad: Array) -> URDFRobot:
        """The same robot with other position limits, shape (dof, 2) = (lower, upper) in rad/m."""
        lim = np.asarray(limits_rad, dtype=float)
        if lim.shape != (self.dof, 2):
            raise RobotModelError(f"{self._doc.source}: limits for {self.dof} joints "
                                  f"({', '.join(self.joint_names)}) need shape ({self.dof}, 2), "
                                  f"got {lim.shape}")
        bad = [n for n, (lo, hi) in zip(self.joint_names, lim, strict=True)
               if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi)]
        if bad:
            raise RobotModelError(f"{self._doc.source}: limits of joint {bad[0]!r} are not a "
                                  "finite range with lower <= upper")
        return self._derive(limits=lim)

    def with_ik_settings(self, settings: IKSettings) -> URDFRobot:
        return self._derive(ik_settings=settings)

    def _check_link(self, name: str, role: str) -> None:
        if name not in self._doc.links:
            known = ", ".join(list(self._doc.links)[:20])
            raise RobotModelError(f"{self._doc.source}: {role} link {name!r} is not in the URDF "
                                  f"(links: {known}{' ...' if len(self._doc.links) > 20 else ''})")

    def _path(self) -> list[_Joint]:
        """Joints from base to tool, in order; refuses a tool that is not below the base."""
        doc, out, link = self._doc, [], self.tool_link
        while link != self.base_link:
            j = doc.parent_joint.get(link)
            if j is None:
                raise RobotModelError(f"{doc.source}: tool link {self.tool_link!r} is not below "
                                      f"base link {self.base_link!r}")
            if j.type in ("floating", "planar"):
                raise RobotModelError(f"{doc.where(j.line)}: joint {j.name!r} of type {j.type} "
                                      "lies between base and tool; only revolute, continuous, "
                                      "prismatic and fixed joints can form the arm")
            out.append(j)
            link = j.parent
        return out[::-1]

    def _locked(self, given: Mapping[str, float] | None, chain: set[str]) -> dict[str, float]:
        doc = self._doc
        out = {}
        for j in doc.joints.values():
            if j.name not in chain and j.type in _ACTUATED:
                out[j.name] = float(np.clip(0.0, j.lower, j.upper))
        for name, v in (given or {}).items():
            if name not in out:
                raise RobotModelError(f"{doc.source}: cannot lock joint {name!r}: it is "
                                      + ("in the arm's chain" if name in chain
                                         else "not a movable joint of the URDF"))
            j = doc.joints[name]
            if not (j.lower - 1e-12 <= float(v) <= j.upper + 1e-12):
                raise RobotModelError(f"{doc.where(j.line)}: locked joint {name!r}: {v} is "
                                      f"outside [{j.lower}, {j.upper}]")
            out[name] = float(v)
        return out

    def _build_model(self) -> None:
        """Reduced pinocchio model: only the chain joints, the rest locked; plus a TCP frame."""
        full = self._doc.model
        q_ref = pin.neutral(full)
        for name, v in self.locked_positions.items():
            _set_pin_q(full, full.getJointId(name), q_ref, v)
        chain_names = set(self.joint_names)
        lock_ids = [i for i in range(1, full.njoints) if full.names[i] not in chain_names]
        model = pin.buildReducedModel(full, lock_ids, q_ref) if lock_ids else pin.Model(full)
        if list(model.names)[1:] != self.joint_names:
            raise RobotModelError(f"{self._doc.source}: pinocchio's joint order "
                                  f"{list(model.names)[1:]} differs from the chain "
                                  f"{self.joint_names}")
        data = model.createData()
        self._q_zero_pin = pin.neutral(model)
        pin.framesForwardKinematics(model, data, self._q_zero_pin)
        base_fid = model.getFrameId(self.base_link, pin.BODY)
        tool_fid = model.getFrameId(self.tool_link, pin.BODY)
        self.T_root_base = data.oMf[base_fid].homogeneous.copy()
        self._T_base_root = inv_T(self.T_root_base)
        self._base_is_root = bool(np.allclose(self.T_root_base, np.eye(4), atol=0, rtol=0))
        dof = len(self.joint_names)
        frame = model.frames[tool_fid]
        if frame.parentJoint != dof:
            raise RobotModelError(f"{self._doc.source}: tool link {self.tool_link!r} does not "
                                  "move with the last joint of the chain")
        self._T_last_flange = frame.placement.homogeneous.copy()
        self._T_last_tcp = self._T_last_flange @ self.T_flange_tool
        self._tcp_fid = model.addFrame(pin.Frame(TCP_FRAME, dof, tool_fid,
                                                 pin.SE3(self._T_last_tcp), pin.FrameType.OP_FRAME))
        self._model = model
        self._idx_q = [model.joints[k].idx_q for k in range(1, dof + 1)]
        self._unbounded = [model.joints[k].nq == 2 for k in range(1, dof + 1)]
        self._simple_q = not any(self._unbounded)
        # World (= URDF root) poses of every body at chain q = 0: placing merged geometry.
        self._T_root_body = {n: data.oMf[model.getFrameId(n, pin.BODY)].homogeneous.copy()
                             for n in self._doc.links}
        self._T_root_joint0 = [np.eye(4)] + [data.oMi[k].homogeneous.copy()
                                             for k in range(1, dof + 1)]

    def _build_chain(self) -> None:
        m = self._model
        joints = []
        for k, j in enumerate(self._chain_joints, start=1):
            T = m.jointPlacements[k].homogeneous.copy()
            if k == 1:
                T = self._T_base_root @ T
            joints.append(ChainJoint(j.name, _ACTUATED[j.type], T, j.axis.copy()))
        self._chain = BatchChain(tuple(joints), self._T_last_tcp.copy())
        # Reach bound: joint 1's origin does not move (revolute) and every later segment
        # has a fixed length, plus prismatic travel. Used to answer REACH honestly.
        self._reach_centre = joints[0].T_prev_joint[:3, 3].copy()
        self._reach = float(sum(np.linalg.norm(j.T_prev_joint[:3, 3]) for j in joints[1:])
                            + np.linalg.norm(self._T_last_tcp[:3, 3])
                            + sum(max(abs(c.lower), abs(c.upper)) for c in self._chain_joints
                                  if c.type == "prismatic"))

    def _build_links(self, path: list[_Joint]) -> list[LinkGeometry]:
        """dof + 1 bodies: every URDF link merged into the chain link it is rigidly fixed to."""
        doc = self._doc
        owner_of_path = {self.base_link: 0}
        k = 0
        for j in path:
            k += j.type in _ACTUATED
            owner_of_path[j.child] = k
        chain_link_names = [self.base_link] + [j.child for j in self._chain_joints]
        members: list[list[str]] = [[] for _ in chain_link_names]
        for name in doc.links:
            link = name
            while link not in owner_of_path and link in doc.parent_joint:
                link = doc.parent_joint[link].parent
            members[owner_of_path.get(link, 0)].append(name)
        T_root_owner = [self.T_root_base] + self._T_root_joint0[1:]
        out = []
        for idx, names in enumerate(members):
            T_owner_root = inv_T(T_root_owner[idx])
            shapes: list[CollisionShape] = []
            visuals: list[trimesh.Trimesh] = []
            color = None
            for name in names:
                T_owner_link = T_owner_root @ self._T_root_body[name]
                link = doc.links[name]
                for g in link.collisions:
                    shapes.append(self._shape(g, link, T_owner_link))
                if self._load_visual:
                    for g in link.visuals:
                        visuals.append(self._visual_mesh(g, link, T_owner_link))
                        if color is None and g.rgba is not None:
                            color = tuple(int(round(255 * float(np.clip(c, 0, 1))))
                                          for c in g.rgba[:3])
            if idx == len(members) - 1:
                shapes += [s.transformed(self._T_last_flange) for s in self.tool.collision]
                visuals += [s.to_trimesh() for s in (s.transformed(self._T_last_flange)
                                                     for s in self.tool.collision)]
            if self._load_visual and not visuals:
                visuals = [s.to_trimesh() for s in shapes]
            visual = trimesh.util.concatenate(visuals) if visuals else None
            out.append(LinkGeometry(chain_link_names[idx], tuple(shapes), visual,
                                    color or (220, 220, 220)))
        return out

    def _mesh(self, g: _Geometry, link: _Link, collision: bool) -> trimesh.Trimesh:
        doc = self._doc
        key = (g.path, collision)
        with doc.lock:
            cached = doc.meshes.get(key)
        if cached is not None:
            return cached
        where = f"{doc.where(g.line)}: link {link.name!r}"
        try:
            mesh = trimesh.load(str(g.path), force="mesh")
        except Exception as e:  # trimesh raises many types for broken files
            raise RobotModelError(f"{where}: cannot load mesh {str(g.path)!r}: {e}") from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise RobotModelError(f"{where}: mesh {str(g.path)!r} has no triangles")
        if not np.all(np.isfinite(mesh.vertices)):
            raise RobotModelError(f"{where}: mesh {str(g.path)!r} has NaN/inf vertices")
        if collision and len(mesh.faces) > COLLISION_FACE_LIMIT:
            mesh = mesh.convex_hull
        with doc.lock:
            doc.meshes[key] = mesh
        return mesh

    def _shape(self, g: _Geometry, link: _Link, T_owner_link: Array) -> CollisionShape:
        T = T_owner_link @ g.T_link_geom
        if g.kind != ShapeKind.MESH:
            return CollisionShape(g.kind, g.size, T)
        mesh = self._mesh(g, link, collision=True)
        if g.scale != (1.0, 1.0, 1.0):
            mesh = mesh.copy()
            mesh.apply_transform(np.diag([*g.scale, 1.0]))
        return CollisionShape(ShapeKind.MESH, (), T, mesh)

    def _visual_mesh(self, g: _Geometry, link: _Link, T_owner_link: Array) -> trimesh.Trimesh:
        if g.kind == ShapeKind.MESH:
            m = self._mesh(g, link, collision=False).copy()
            m.apply_transform(np.diag([*g.scale, 1.0]))
            m.apply_transform(T_owner_link @ g.T_link_geom)
            return m
        return CollisionShape(g.kind, g.size, T_owner_link @ g.T_link_geom).to_trimesh()

    # ------------------------------------------------------------------ kinematics
    @property
    def pinocchio_model(self) -> pin.Model:
        """A copy of the reduced model (chain joints only) with the TCP frame `TCP_FRAME`.

        Its world frame is the URDF root; `T_root_base` places the base in it.
        """
        return pin.Model(self._model)

    def to_pinocchio_q(self, q: Array) -> Array:
        """Joint angles -> pinocchio's configuration (continuous joints are (cos, sin))."""
        q = np.asarray(q, dtype=float)
        if self._simple_q:
            return q
        out = np.empty(self._model.nq)
        for k, (iq, unb) in enumerate(zip(self._idx_q, self._unbounded, strict=True)):
            if unb:
                out[iq], out[iq + 1] = np.cos(q[k]), np.sin(q[k])
            else:
                out[iq] = q[k]
        return out

    def _data(self) -> pin.Data:
        """Per-thread scratch (pinocchio's Data is mutable; the robot is shared)."""
        d = getattr(self._local, "data", None)
        if d is None:
            d = self._local.data = self._model.createData()
        return d

    def _check_q(self, q: Array) -> Array:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.dof,):
            raise ValueError(f"{self.name}: expected {self.dof} joint values "
                             f"({', '.join(self.joint_names)}), got shape {q.shape}")
        return q

    def fk(self, q: Array) -> Array:
        q = self._check_q(q)
        data = self._data()
        pin.forwardKinematics(self._model, data, self.to_pinocchio_q(q))
        T = data.oMi[self.dof].homogeneous @ self._T_last_tcp
        return T if self._base_is_root else self._T_base_root @ T

    def fixed_frame(self, name: str) -> Array | None:
        """A URDF link rigidly attached above the chain (fixed joints only), e.g. the UR
        descriptions' ``base``, in the base frame; None for a missing or moving link."""
        if name not in self._T_root_body or not self._model.existBodyName(name):
            return None
        if self._model.frames[self._model.getFrameId(name, pin.BODY)].parentJoint != 0:
            return None
        return self._T_base_root @ self._T_root_body[name]

    def link_poses(self, q: Array) -> Array:
        q = self._check_q(q)
        data = self._data()
        pin.forwardKinematics(self._model, data, self.to_pinocchio_q(q))
        out = np.empty((self.dof + 1, 4, 4))
        out[0] = np.eye(4)
        for k in range(1, self.dof + 1):
            out[k] = self._T_base_root @ data.oMi[k].homogeneous
        return out

    def batch_fk(self, Q: Array, dtype: type = np.float64) -> BatchPoses:
        """TCP poses of Q (N, dof), vectorised in numpy (see `assistant.robots.batch_chain`)."""
        return self._chain.tip_poses(Q, dtype=dtype)

    def batch_link_poses(self, Q: Array, dtype: type = np.float64) -> Array:
        return self._chain.link_poses(Q, dtype=dtype)

    @property
    def batch_chain(self) -> BatchChain:
        """The chain in base coordinates, TCP as tip (for vectorised users)."""
        return self._chain

    # ------------------------------------------------------------------ inverse kinematics
    def ik(
        self,
        T_base_tool: Array,
        seed: Array | None = None,
        *,
        position_only: bool = False,
        max_solutions: int | None = None,
    ) -> IKResult:
        """Damped least squares from the seed, then seeded random restarts; distinct solutions.

        Every iterate is clamped into the joint limits, so each solution is within limits.
        Failure reasons: REACH (farther than the summed link lengths), JOINT_LIMIT (solvable
        only with a joint outside its range), ORIENTATION (fewer than 6 joints: the position
        is reachable but not with this orientation), NO_CONVERGENCE. The best pose reached
        is offered in `nearest_T_base_tool`.
        """
        T = np.asarray(T_base_tool, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"{self.name}: T_base_tool must be a finite 4x4 transform")
        if not position_only:
            try:
                T = orthonormalized(T)
            except ValueError as exc:
                raise ValueError(f"{self.name}: {exc}") from None
        st = self.ik_settings
        want = max_solutions or st.max_solutions
        T_root_target = T if self._base_is_root else self.T_root_base @ T
        lo, hi = self.limits.lower, self.limits.upper
        home = np.clip(np.zeros(self.dof), lo, hi)
        first = np.clip(self._check_q(seed), lo, hi) if seed is not None else home
        rng = np.random.default_rng(st.rng_seed)
        starts = [first] + [rng.uniform(lo, hi) for _ in range(st.restarts)]
        dist = float(np.linalg.norm(T[:3, 3] - self._reach_centre))
        out_of_reach = dist > self._reach + st.position_tolerance
        if out_of_reach:
            starts = starts[:2]

        sols: list[Array] = []
        best_q, best_err = first, np.inf
        k = 0
        while k < len(starts):
            q, ok, err = self._dls(T_root_target, starts[k], position_only, clamp=True)
            k += 1
            if err < best_err:
                best_q, best_err = q, err
            if ok and all(np.linalg.norm(q - s) > st.distinct for s in sols):
                sols.append(q)
                if len(sols) >= want:
                    break
            if k == len(starts) and not sols and not out_of_reach and \
                    len(starts) == 1 + st.restarts:
                starts += [rng.uniform(lo, hi) for _ in range(st.extra_restarts)]
        ref = first if seed is not None else home
        if sols:
            sols.sort(key=lambda s: float(np.linalg.norm(s - ref)))
            return IKResult(sols)
        nearest = self.fk(best_q)
        target = "point" if position_only else "pose"
        if out_of_reach:
            return IKResult([], IKFailure.REACH,
                            f"{target} at {dist * 1000:.0f} mm from the first joint is beyond "
                            f"the arm's reach ({self._reach * 1000:.0f} mm)", nearest)
        inside, free = self._solve_unlimited(T_root_target, starts[:1 + st.restarts],
                                             position_only)
        if inside is not None:
            return IKResult([inside])
        if free is not None:
            return IKResult([], IKFailure.JOINT_LIMIT,
                            f"no solution within the joint limits was found for this {target}; "
                            "without limits it is reachable with "
                            + ", ".join(self.limits.violations(free, self.joint_names)),
                            nearest)
        if not position_only and self.dof < 6:
            for q0 in starts[:4]:
                if self._dls(T_root_target, q0, True, clamp=True)[1]:
                    return IKResult([], IKFailure.ORIENTATION,
                                    f"the {self.dof}-axis arm reaches this point but not with "
                                    "this orientation; the nearest pose found is offered",
                                    nearest)
        return IKResult([], IKFailure.NO_CONVERGENCE,
                        f"no joint configuration found for this {target} after "
                        f"{len(starts)} starts; the nearest pose found is offered", nearest)

    def _solve_unlimited(self, T_root_target: Array, starts: list[Array],
                         position_only: bool) -> tuple[Array | None, Array | None]:
        """Solve ignoring limits: (a solution that is inside after 2 pi shifts, or else the
        first solution found outside them); (None, None) if none converges."""
        outside = None
        for q0 in starts:
            q, ok, _ = self._dls(T_root_target, q0, position_only, clamp=False)
            if ok:
                q = self._wrap_into_limits(q)
                if self.limits.contains(q):
                    return q, None  # reachable after all: the clamped runs were unlucky
                if outside is None:
                    outside = q
        return None, outside

    def _wrap_into_limits(self, q: Array) -> Array:
        q = q.copy()
        for k, j in enumerate(self._chain_joints):
            if j.type == "prismatic":
                continue
            for shift in (0.0, -2 * np.pi, 2 * np.pi, -4 * np.pi, 4 * np.pi):
                v = q[k] + shift
                if self.limits.lower[k] - 1e-9 <= v <= self.limits.upper[k] + 1e-9:
                    q[k] = v
                    break
        return q

    def _dls(self, T_root_target: Array, q0: Array, position_only: bool, *, clamp: bool
             ) -> tuple[Array, bool, float]:
        """One damped-least-squares run: (q, converged, weighted error of the best iterate)."""
        st = self.ik_settings
        model, data, fid = self._model, self._data(), self._tcp_fid
        lam2 = st.damping ** 2
        oMdes = pin.SE3(T_root_target[:3, :3], T_root_target[:3, 3])
        q = q0.copy()
        best_q, best_err = q.copy(), np.inf
        lo, hi = self.limits.lower, self.limits.upper
        eye = np.eye(3 if position_only else 6)
        stall = 0
        for _ in range(st.max_iterations):
            qp = self.to_pinocchio_q(q)
            pin.computeJointJacobians(model, data, qp)
            pin.updateFramePlacement(model, data, fid)
            oMf = data.oMf[fid]
            dp = oMdes.translation - oMf.translation
            pos_err = float(np.linalg.norm(dp))
            if position_only:
                rot_err = 0.0
                J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
                e = dp
            else:
                iMd = oMf.actInv(oMdes)
                rot_err = rotation_angle(iMd.rotation)
                # e = log6(T_tcp^-1 T_target) in the TCP frame; de/dq = -Jlog6(iMd^-1) J_local
                # (pinocchio's own IK example), so dq = +J^T (J J^T + lambda^2)^-1 e below.
                e = pin.log6(iMd).vector
                J = pin.Jlog6(iMd.inverse()) @ pin.getFrameJacobian(model, data, fid, pin.LOCAL)
            err = pos_err + 0.1 * rot_err
            if err < best_err - 1e-12:
                best_q, best_err, stall = q.copy(), err, 0
            else:
                stall += 1
                if stall > 20:
                    break
            if pos_err < st.position_tolerance and rot_err < st.orientation_tolerance:
                return q, True, err
            # Active set: a joint on a limit that the step would push further out is taken
            # out of the solve, so the others make the progress (plain clamping stalls).
            damp = min(1.0, float(np.linalg.norm(e)) / st.damping_error)
            free = np.ones(self.dof, dtype=bool)
            for _ in range(3):
                Jf = J * free
                dq = Jf.T @ np.linalg.solve(Jf @ Jf.T + lam2 * damp * eye, e)
                if not clamp:
                    break
                blocked = ((q <= lo) & (dq < 0)) | ((q >= hi) & (dq > 0))
                if not np.any(blocked & free):
                    break
                free &= ~blocked
            step = float(np.max(np.abs(dq)))
            if step > st.max_step:
                dq *= st.max_step / step
            q = q + dq
            if clamp:
                q = np.clip(q, lo, hi)
        return best_q, False, best_err

    # ------------------------------------------------------------------ description
    def urdf(self) -> str:
        """The URDF with absolute mesh paths, the current limits and a fixed `tool` frame.

        The tool frame is a link named "tool" (or "cellteach_tool" if "tool" is taken) fixed
        to `tool_link` at `T_flange_tool`, so a viewer or pinocchio sees the TCP.
        """
        root = etree.fromstring(etree.tostring(self._doc.tree))
        for mesh in root.iter("mesh"):
            fn = mesh.get("filename")
            if fn:
                mesh.set("filename", str(self._resolved(fn)))
        by_name = {j.get("name"): j for j in root.findall("joint")}
        for k, name in enumerate(self.joint_names):
            el = by_name[name]
            lo, hi = float(self.limits.lower[k]), float(self.limits.upper[k])
            if el.get("type") == "continuous":
                if lo == -CONTINUOUS_RANGE and hi == CONTINUOUS_RANGE:
                    continue
                el.set("type", "revolute")
            lim = el.find("limit")
            if lim is None:
                lim = etree.SubElement(el, "limit", effort="0",
                                       velocity=repr(float(self.limits.velocity[k])))
            lim.set("lower", repr(lo))
            lim.set("upper", repr(hi))
        tool_name = "tool" if "tool" not in self._doc.links else "cellteach_tool"
        joint_name = f"{tool_name}_fixed"
        while joint_name in self._doc.joints:
            joint_name = "_" + joint_name
        etree.SubElement(root, "link", name=tool_name)
        j = etree.SubElement(root, "joint", name=joint_name, type="fixed")
        T = self.T_flange_tool
        rpy = pin.rpy.matrixToRpy(T[:3, :3])
        etree.SubElement(j, "origin", xyz=" ".join(repr(float(v)) for v in T[:3, 3]),
                         rpy=" ".join(repr(float(v)) for v in rpy))
        etree.SubElement(j, "parent", link=self.tool_link)
        etree.SubElement(j, "child", link=tool_name)
        return '<?xml version="1.0"?>\n' + etree.tostring(root, encoding="unicode")

    def _resolved(self, filename: str) -> Path:
        for link in self._doc.links.values():
            for g in link.visuals + link.collisions:
                if g.filename == filename and g.path is not None:
                    return g.path
        raise KeyError(filename)

    def description_hash(self) -> str:
        """sha256 of the URDF text, mesh contents, frames, tool, limits and locked joints."""
        payload = json.dumps({
            "urdf": hashlib.sha256(self._doc.text.encode()).hexdigest(),
            "meshes": self._doc.mesh_digests,
            "base": self.base_link, "tool_link": self.tool_link,
            "T_flange_tool": np.round(self.T_flange_tool, 12).tolist(),
            "tool_shapes": [(s.kind.value, list(s.size), np.round(s.T_link_shape, 12).tolist())
                            for s in self.tool.collision],
            "limits": np.round(np.column_stack([self.limits.lower, self.limits.upper]),
                               12).tolist(),
            "locked": self.locked_positions,
        }, sort_keys=True)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]


def _set_pin_q(model: pin.Model, jid: int, q: Array, value: float) -> None:
    j = model.joints[jid]
    if j.nq == 1:
        q[j.idx_q] = value
    elif j.nq == 2:
        q[j.idx_q], q[j.idx_q + 1] = np.cos(value), np.sin(value)


def _default_tool_link(doc: _Document, base: str) -> str:
    """The end of the longest chain below `base`: most actuated joints, then most joints."""
    best, best_key = base, (-1, -1)
    stack = [(base, 0, 0)]
    order = {n: i for i, n in enumerate(doc.links)}
    leaves = []
    while stack:
        link, act, total = stack.pop()
        kids = doc.children[link]
        if not kids:
            leaves.append((link, act, total))
        for j in kids:
            stack.append((j.child, act + (j.type in _ACTUATED), total + 1))
    for link, act, total in sorted(leaves, key=lambda t: order[t[0]]):
        if (act, total) > best_key:
            best, best_key = link, (act, total)
    return best


__all__ = ["COLLISION_FACE_LIMIT", "IKSettings", "TCP_FRAME", "URDFRobot", "resolve_mesh_path"]
