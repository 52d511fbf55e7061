"""The octree surface mesh: exactly the faces between occupied and free cells, closed and
facing outwards (its volume is the cells' volume), on turned grids too, and a glTF that a
loader reads back with the cells' colours and an unlit material."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh

from assistant.transforms import rot_z
from web.scene.voxel_surface import SHADE, surface_glb, voxel_surface

LEAF = 0.02


def _closed_mesh(surface) -> trimesh.Trimesh:
    mesh = trimesh.Trimesh(surface.vertices, surface.faces, process=False)
    mesh.merge_vertices()  # quads have their own corners; share them to test closedness
    return mesh


def _gltf_json(glb: bytes) -> dict:
    """The JSON chunk of a binary glTF (header 12 bytes, then length, type, data)."""
    n = struct.unpack("<I", glb[12:16])[0]
    return json.loads(glb[20:20 + n])


def _cells(ijk) -> np.ndarray:
    return (np.asarray(ijk, float) + 0.5) * LEAF + np.array([-1.0, -1.0, 0.3])


@pytest.mark.parametrize(("ijk", "quads", "seen"), [
    ([[0, 0, 0]], 6, 1),
    ([[0, 0, 0], [1, 0, 0]], 10, 2),
    ([[0, 0, 0], [2, 0, 0]], 12, 2),  # not neighbours: two whole cubes
    ([[i, j, k] for i in range(3) for j in range(3) for k in range(3)], 54, 26),
])
def test_only_faces_between_occupied_and_free_cells(ijk, quads, seen):
    s = voxel_surface(_cells(ijk), LEAF)
    assert len(s.faces) == 2 * quads and len(s.vertices) == 4 * quads
    assert len(s.surface_cells) == seen  # the centre of the 3x3x3 block has no free side
    mesh = _closed_mesh(s)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(len(ijk) * LEAF**3, rel=1e-5)  # > 0: outwards


def test_a_random_blob_is_closed_and_every_cell_has_its_volume():
    rng = np.random.default_rng(3)
    ijk = np.unique(rng.integers(0, 6, (120, 3)), axis=0)
    s = voxel_surface(_cells(ijk), LEAF)
    # Each quad lies between a cell of the set and a lattice neighbour outside it.
    occupied = {tuple(c) for c in ijk}
    step = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]])
    for cell, d in zip(s.quad_cell, s.quad_dir, strict=True):
        assert tuple(ijk[cell] + step[d]) not in occupied
    expected = sum(tuple(c + st) not in occupied for c in ijk for st in step)
    assert len(s.quad_cell) == expected
    assert _closed_mesh(s).volume == pytest.approx(len(ijk) * LEAF**3, rel=1e-5)


def test_a_turned_grid_gives_the_same_surface_turned():
    ijk = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1]]
    R = rot_z(np.pi / 4)[:3, :3]
    straight = voxel_surface(_cells(ijk), LEAF)
    turned = voxel_surface(_cells(ijk) @ R.T, LEAF, R)
    assert len(turned.faces) == len(straight.faces) == 2 * 18
    assert np.allclose(turned.vertices, straight.vertices @ R.T, atol=1e-6)
    assert _closed_mesh(turned).volume == pytest.approx(4 * LEAF**3, rel=1e-5)


def test_no_cells_no_faces():
    s = voxel_surface(np.zeros((0, 3)), LEAF)
    assert s.faces.shape == (0, 3) and s.vertices.shape == (0, 3)


def test_the_glb_holds_the_cell_colours_shaded_and_an_unlit_material():
    ijk = [[0, 0, 0], [1, 0, 0]]
    s = voxel_surface(_cells(ijk), LEAF)
    rgb = np.array([[200, 20, 20], [20, 200, 20]], np.uint8)
    glb = surface_glb(s, rgb, opacity=0.45)
    tree = _gltf_json(glb)
    assert tree["extensionsUsed"] == ["KHR_materials_unlit"]
    (mat,) = tree["materials"]
    assert mat["alphaMode"] == "BLEND" and mat["pbrMetallicRoughness"]["baseColorFactor"][3] \
        == pytest.approx(0.45)
    assert all(p["material"] == 0 for m in tree["meshes"] for p in m["primitives"])
    scene = trimesh.load(trimesh.util.wrap_as_stream(glb), file_type="glb")
    (mesh,) = scene.geometry.values()
    assert len(mesh.faces) == len(s.faces)
    colours = np.asarray(mesh.visual.vertex_attributes["color"])[::4, :3].astype(float)
    want = rgb[s.quad_cell].astype(float) * SHADE[s.quad_dir, None]
    assert np.abs(colours - want).max() <= 1.0
    assert _gltf_json(surface_glb(s, rgb))["materials"][0]["alphaMode"] == "OPAQUE"


def test_shrunk_faces_stay_in_their_cell_planes_about_their_centres():
    full = voxel_surface(_cells([[0, 0, 0]]), LEAF)
    shrunk = voxel_surface(_cells([[0, 0, 0]]), LEAF, face_scale=0.9)
    q_full = full.vertices.reshape(-1, 4, 3).astype(float)
    q_shrunk = shrunk.vertices.reshape(-1, 4, 3).astype(float)
    assert np.allclose(q_full.mean(axis=1), q_shrunk.mean(axis=1), atol=1e-7)
    assert np.allclose(q_shrunk - q_shrunk.mean(axis=1, keepdims=True),
                       0.9 * (q_full - q_full.mean(axis=1, keepdims=True)), atol=1e-7)
    assert _closed_mesh(full).area == pytest.approx(6 * LEAF**2, rel=1e-5)
