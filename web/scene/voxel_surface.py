"""Occupied octree leaves as ONE surface mesh: only the faces between an occupied and a free
cell, each coloured like its cell and shaded by its direction, packed as an unlit glTF.

Why: without a GPU (software WebGL) a frame costs what its triangles and covered pixels cost.
Obstacles fill the octree as solid blocks, so their outside faces are a small fraction of the
12 triangles per box that per-cell boxes draw - 50 000 cells of CAD-like blocks are 35 000
triangles and draw at about the speed of the empty page (benchmarks/ui.py). The shading is
baked into the vertex colours (top brightest, bottom darkest) and the material is unlit, the
cheapest fragment shader there is, with no lights or environment map to evaluate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from trimesh.exchange.gltf import export_glb

#: Brightness of a face by the direction it faces: -x, +x, -y, +y, -z, +z.
SHADE = np.array([0.80, 0.80, 0.68, 0.68, 0.55, 1.0])


@dataclass(frozen=True)
class VoxelSurface:
    """Quads of the exposed cell faces: 4 vertices per quad, 2 triangles per quad."""

    vertices: np.ndarray  # (4Q, 3) float32
    faces: np.ndarray  # (2Q, 3) uint32, counter-clockwise seen from outside
    quad_cell: np.ndarray  # (Q,) index of the cell each quad belongs to
    quad_dir: np.ndarray  # (Q,) 0..5 = -x, +x, -y, +y, -z, +z

    @property
    def surface_cells(self) -> np.ndarray:
        """Indices of the cells with at least one exposed face (the others are hidden)."""
        return np.unique(self.quad_cell)


def voxel_surface(centres: np.ndarray, leaf: float, R_world_grid: np.ndarray | None = None,
                  face_scale: float = 1.0) -> VoxelSurface:
    """Exposed faces of cubes of edge `leaf` at `centres` (world frame, on one lattice whose
    axes are the columns of `R_world_grid`; identity when None). `face_scale` < 1 shrinks each
    face about its centre, in its plane: thin gaps then show where the cells are."""
    centres = np.asarray(centres, float).reshape(-1, 3)
    R = np.eye(3) if R_world_grid is None else np.asarray(R_world_grid, float)
    if not len(centres):
        return VoxelSurface(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32),
                            np.zeros(0, np.int64), np.zeros(0, np.int64))
    local = centres @ R  # grid axes
    ijk = np.rint((local - local.min(axis=0)) / leaf).astype(np.int64) + 1
    dims = ijk.max(axis=0) + 2
    keys = np.ravel_multi_index(ijk.T, dims)
    occupied = np.sort(keys)
    strides = np.array([dims[1] * dims[2], dims[2], 1])
    h = 0.5 * leaf
    quads, cells, dirs = [], [], []
    for axis in range(3):
        u, w = [(1, 2), (2, 0), (0, 1)][axis]  # e_u x e_w = +e_axis
        for sign in (-1, 1):
            nb = keys + sign * strides[axis]
            pos = np.minimum(np.searchsorted(occupied, nb), len(occupied) - 1)
            exposed = np.flatnonzero(occupied[pos] != nb)
            if not len(exposed):
                continue
            c = local[exposed]
            corners = []
            for du, dw in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                off = np.zeros(3)
                off[axis] = sign * h
                off[u] = du * h * face_scale
                off[w] = dw * sign * h * face_scale  # mirrored on the - side: still outward
                corners.append(c + off)
            quads.append(np.stack(corners, axis=1))
            cells.append(exposed)
            dirs.append(np.full(len(exposed), 2 * axis + (sign > 0)))
    q = np.concatenate(quads)  # (Q, 4, 3), grid axes
    vertices = (q.reshape(-1, 3) @ R.T).astype(np.float32)
    base = 4 * np.arange(len(q), dtype=np.uint32)[:, None]
    faces = (base + np.array([0, 1, 2, 0, 2, 3], np.uint32)).reshape(-1, 3)
    return VoxelSurface(vertices, faces, np.concatenate(cells), np.concatenate(dirs))


def surface_glb(surface: VoxelSurface, cell_rgb: np.ndarray, opacity: float = 1.0) -> bytes:
    """The surface as a binary glTF: vertex colours (cell colour x direction shade) and one
    unlit material (KHR_materials_unlit), blended when `opacity` < 1."""
    rgb = np.asarray(cell_rgb, float)[surface.quad_cell] * SHADE[surface.quad_dir, None]
    rgba = np.concatenate([rgb.round(), np.full((len(rgb), 1), 255.0)], axis=1)
    mesh = trimesh.Trimesh(surface.vertices, surface.faces, process=False,
                           vertex_colors=np.repeat(rgba.astype(np.uint8), 4, axis=0))

    def unlit(tree: dict) -> None:
        tree["materials"] = [{
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, float(opacity)],
                                     "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "alphaMode": "BLEND" if opacity < 1.0 else "OPAQUE",
            "extensions": {"KHR_materials_unlit": {}}}]
        tree["extensionsUsed"] = sorted(set(tree.get("extensionsUsed", []))
                                        | {"KHR_materials_unlit"})
        for m in tree["meshes"]:
            for prim in m["primitives"]:
                prim["material"] = 0

    return export_glb(trimesh.Scene(mesh), include_normals=False, tree_postprocessor=unlit)
