"""Reading a URDF with lxml into plain records (links, joints, geometry, materials), with
errors that name the file, the line and the element; mesh paths (``package://``, ``file://``,
relative) resolved. `URDFRobot` builds the robot from these records."""

from __future__ import annotations

import hashlib
import threading
import urllib.parse
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
import trimesh
from lxml import etree

from assistant.file_guard import FileRefused, read_file, xml_parser
from assistant.robots.batch_chain import JointKind
from assistant.robots.errors import RobotModelError
from assistant.robots.model import (
    ShapeKind,
)

Array = np.ndarray

#: Collision meshes with more faces than this are replaced by their convex hull. FCL's cost
#: grows with the triangle count and the planner checks millions of poses; a hull is a safe
#: (conservative) proxy for a link. Visual meshes are never simplified.
COLLISION_FACE_LIMIT = 3000
#: A URDF's text and each mesh file it names may be at most this large (`file_guard`).
MAX_URDF_BYTES = 64 * 2**20
MAX_MESH_BYTES = 256 * 2**20
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
class URDFGeometry:
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
class URDFLink:
    name: str
    line: int
    visuals: tuple[URDFGeometry, ...]
    collisions: tuple[URDFGeometry, ...]


@dataclass(frozen=True)
class URDFJoint:
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
class URDFDocument:
    """A parsed URDF with resolved mesh paths; shared by the robots derived from it.

    Immutable after construction except `meshes`, a load cache (so `with_tool`/`with_limits`
    never reload files).
    """

    source: str
    base_dir: Path
    text: str
    tree: etree._Element
    name: str
    links: dict[str, URDFLink]
    joints: dict[str, URDFJoint]
    parent_joint: dict[str, URDFJoint]
    children: dict[str, list[URDFJoint]]
    root: str
    model: pin.Model
    mesh_digests: dict[str, str]
    meshes: dict[tuple[Path, bool], trimesh.Trimesh] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def where(self, line: int) -> str:
        return f"{self.source}:{line}"


def parse_urdf(text: str, source: str, base_dir: Path, package_dirs: Sequence[str | Path]
           ) -> URDFDocument:
    try:  # no entities, DTDs or network; libxml2 refuses nesting deeper than 256
        root_el = etree.fromstring(text.encode() if isinstance(text, str) else text,
                                   xml_parser())
    except etree.XMLSyntaxError as e:
        raise RobotModelError(f"{source}:{e.lineno}: malformed XML: {e.msg}") from None
    if root_el.tag != "robot":
        raise RobotModelError(f"{source}:{root_el.sourceline}: the root element is "
                              f"<{root_el.tag}>, a URDF needs <robot>")
    materials = _materials(root_el, source)
    mesh_digests: dict[str, str] = {}
    links: dict[str, URDFLink] = {}
    for el in root_el.findall("link"):
        name = _required(el, "name", source)
        if name in links:
            raise RobotModelError(f"{source}:{el.sourceline}: link {name!r} is defined twice")
        geoms = {}
        for tag in ("visual", "collision"):
            geoms[tag] = tuple(
                _geometry(g, tag, name, source, base_dir, package_dirs, materials, mesh_digests)
                for g in el.findall(tag))
        links[name] = URDFLink(name, el.sourceline, geoms["visual"], geoms["collision"])
    if not links:
        raise RobotModelError(f"{source}: the URDF has no <link>")
    joints: dict[str, URDFJoint] = {}
    parent_joint: dict[str, URDFJoint] = {}
    children: dict[str, list[URDFJoint]] = {n: [] for n in links}
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
    return URDFDocument(source, base_dir, text, root_el, root_el.get("name", "robot"), links,
                     joints, parent_joint, children, roots[0], model, mesh_digests)


def _check_reachable(root: str, links: dict[str, URDFLink], children: dict[str, list[URDFJoint]],
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
              ) -> URDFGeometry:
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
        return URDFGeometry(ShapeKind.BOX, tuple(_floats(shape, "size", 3, source)), T,
                         el.sourceline, rgba=rgba)
    if kind in ("cylinder", "capsule"):
        r = float(_floats(shape, "radius", 1, source)[0])
        length = float(_floats(shape, "length", 1, source)[0])
        sk = ShapeKind.CYLINDER if kind == "cylinder" else ShapeKind.CAPSULE
        return URDFGeometry(sk, (r, length), T, el.sourceline, rgba=rgba)
    if kind == "sphere":
        return URDFGeometry(ShapeKind.SPHERE, (float(_floats(shape, "radius", 1, source)[0]),), T,
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
            digests[filename] = hashlib.sha256(read_mesh_bytes(
                path, f"{source}:{shape.sourceline}: link {link!r} <{tag}>")).hexdigest()
        return URDFGeometry(ShapeKind.MESH, (), T, el.sourceline, filename, path,
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
        if cand.exists():  # a device, a pipe, a folder: say what it is
            try:
                read_file(cand, limit=0, what="mesh file")
            except FileRefused as exc:
                raise RobotModelError(f"{where}: {exc}") from None
    shown = ", ".join(str(t) for t in tried[:8]) + (" ..." if len(tried) > 8 else "")
    raise RobotModelError(f"{where}: mesh file not found: {filename!r} (tried: {shown})")


def _joint(el: etree._Element, source: str, links: dict[str, URDFLink]) -> URDFJoint:
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
    return URDFJoint(name, jtype, ends["parent"], ends["child"], el.sourceline, axis, lower, upper,
                  velocity)




def read_mesh_bytes(path: Path, where: str) -> bytes:
    """A mesh file a URDF names, read through `file_guard` (a regular file of at most
    `MAX_MESH_BYTES`): a device or a pipe is refused by name, never read."""
    try:
        return read_file(path, limit=MAX_MESH_BYTES, what="mesh file")
    except FileRefused as exc:
        raise RobotModelError(f"{where}: {exc}") from None
