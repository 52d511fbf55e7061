"""A URDF's geometry as the `Robot` interface holds it: meshes read through `file_guard`'s
rules and cached on the document, collision shapes and visual meshes in their owner's frame.

Why apart from `urdf_robot`: reading and checking mesh files (COLLADA archives, face limits,
NaN vertices) is its own concern; the robot only asks for a link's shapes.
"""

from __future__ import annotations

import io
import zipfile

import numpy as np
import trimesh
from lxml import etree

from assistant.file_guard import check_archive, xml_parser
from assistant.robots.errors import RobotModelError
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.robots.urdf_parse import (
    COLLISION_FACE_LIMIT,
    MAX_MESH_BYTES,
    URDFDocument,
    URDFGeometry,
    URDFLink,
    read_mesh_bytes,
)

Array = np.ndarray


def load_mesh(doc: URDFDocument, g: URDFGeometry, link: URDFLink,
              collision: bool) -> trimesh.Trimesh:
    """The mesh of `g` (cached on `doc`); a collision mesh above `COLLISION_FACE_LIMIT`
    faces becomes its convex hull. A broken file raises `RobotModelError` naming it."""
    key = (g.path, collision)
    with doc.lock:
        cached = doc.meshes.get(key)
    if cached is not None:
        return cached
    where = f"{doc.where(g.line)}: link {link.name!r}"
    data = read_mesh_bytes(g.path, where)
    suffix = g.path.suffix.lower().lstrip(".")
    try:
        if suffix == "dae":
            check_collada(data)
        mesh = trimesh.load(io.BytesIO(data), file_type=suffix, force="mesh",
                            resolver=trimesh.resolvers.FilePathResolver(g.path))
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


def collision_shape(doc: URDFDocument, g: URDFGeometry, link: URDFLink,
                    T_owner_link: Array) -> CollisionShape:
    """`g` as a collision shape in its owner's frame (a mesh scaled as the URDF says)."""
    T = T_owner_link @ g.T_link_geom
    if g.kind != ShapeKind.MESH:
        return CollisionShape(g.kind, g.size, T)
    mesh = load_mesh(doc, g, link, collision=True)
    if g.scale != (1.0, 1.0, 1.0):
        mesh = mesh.copy()
        mesh.apply_transform(np.diag([*g.scale, 1.0]))
    return CollisionShape(ShapeKind.MESH, (), T, mesh)


def visual_mesh(doc: URDFDocument, g: URDFGeometry, link: URDFLink,
                T_owner_link: Array) -> trimesh.Trimesh:
    """`g` as a triangle mesh in its owner's frame, for drawing."""
    if g.kind == ShapeKind.MESH:
        m = load_mesh(doc, g, link, collision=False).copy()
        m.apply_transform(np.diag([*g.scale, 1.0]))
        m.apply_transform(T_owner_link @ g.T_link_geom)
        return m
    return CollisionShape(g.kind, g.size, T_owner_link @ g.T_link_geom).to_trimesh()


def check_collada(data: bytes) -> None:
    """A COLLADA mesh through `file_guard`'s rules before pycollada reads it (which parses
    in libxml2's huge-tree mode and inflates zipped .dae files whole): a zip's directory
    within limits, the XML nested at most 256 deep, without entities or DTDs."""
    if data[:2] == b"PK":
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            members = check_archive(zf.infolist(), what="zipped COLLADA file",
                                    max_total=MAX_MESH_BYTES)
            dae = [m for m in members if m.filename.lower().endswith(".dae")]
            data = zf.read(dae[0]) if dae else b""
    etree.fromstring(data, xml_parser())
