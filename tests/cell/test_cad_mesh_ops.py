"""The array repair steps (`cad.mesh_ops`) that replaced trimesh's for big parts: the same
answers as trimesh's on meshes where those are known, in a few numpy passes."""

from __future__ import annotations

import numpy as np
import trimesh

from assistant.cell.cad import mesh_ops as ops
from assistant.cell.cad.outside import outside_bound, point_triangle_distance
from assistant.cell.cad.validate import repair


def _soup(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    tri = mesh.triangles
    return tri.reshape(-1, 3).copy(), np.arange(len(tri) * 3).reshape(-1, 3)


def test_merging_a_triangle_soup_gives_trimeshs_vertices_in_first_seen_order():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    v, f = _soup(sphere)
    mv, mf = ops.merge_vertices(v, f)
    ref = trimesh.Trimesh(v, f, process=False)
    ref.merge_vertices()
    assert len(mv) == len(ref.vertices) == len(sphere.vertices)
    assert np.array_equal(mv, ref.vertices) and np.array_equal(mf, ref.faces)


def test_rows_are_grouped_exactly_even_when_their_hashes_collide(monkeypatch):
    q = np.array([[1, 2, 3], [4, 5, 6], [1, 2, 3], [7, 8, 9]], dtype=np.int64)
    monkeypatch.setattr(ops, "_row_hash", lambda rows: np.zeros(len(rows), dtype=np.uint64))
    first, inverse = ops.unique_rows(q)  # every hash equal: the exact fallback must run
    assert first.tolist() == [0, 1, 3] and inverse.tolist() == [0, 1, 0, 2]


def test_faces_turned_at_random_are_wound_consistently_and_outward():
    sphere = trimesh.creation.icosphere(subdivisions=4)
    f = sphere.faces.copy()
    turned = np.random.default_rng(5).random(len(f)) < 0.4
    f[turned] = f[turned][:, ::-1]
    fixed, rep = repair(trimesh.Trimesh(sphere.vertices, f, process=False), "ball.stl")
    assert fixed.is_winding_consistent and fixed.is_watertight
    assert fixed.volume > 0 and np.isclose(fixed.volume, sphere.volume)
    assert any("winding" in r for r in rep.repairs)


def test_three_and_four_edge_holes_are_closed_flat_sheets_left_open():
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0)).subdivide()
    v, f = box.vertices, box.faces
    tri_hole = np.delete(f, [0], axis=0)
    cube = trimesh.creation.box()
    quad_hole = np.delete(cube.faces, [0, 1], axis=0)  # a side's two triangles: a 4-edge hole
    for verts, faces in ((v, tri_hole), (cube.vertices, quad_hole)):
        fixed, rep = repair(trimesh.Trimesh(verts, faces, process=False), "p.stl")
        assert fixed.is_watertight and fixed.volume > 0, rep
        assert any("filled small holes" in r for r in rep.repairs)
    sheet = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
                            [[0, 1, 2], [0, 2, 3]], process=False)
    fixed, rep = repair(sheet, "sheet.obj")
    assert len(fixed.faces) == 2 and not any("holes" in r for r in rep.repairs)


def test_point_triangle_distance_is_trimeshs_closest_point():
    rng = np.random.default_rng(0)
    a, b, c = rng.normal(size=(3, 5000, 3))
    p = 2 * rng.normal(size=(5000, 3))
    ref = np.linalg.norm(trimesh.triangles.closest_point(np.stack([a, b, c], 1), p) - p,
                         axis=1)
    # the same closest point, reached by different arithmetic: agreement to ~1e-15 of the
    # unit scale; 1e-12 leaves room for the worst-conditioned of 5000 random triangles
    assert np.abs(point_triangle_distance(p, a, b, c) - ref).max() < 1e-12


def test_the_outside_bound_holds_between_the_vertices():
    """A coarse proxy (an octahedron) of a fine sphere: the sphere bulges out of each flat
    proxy face most in the middle of the face, far from any vertex of the sphere lying on a
    proxy vertex - the bound must cover it, at every point of the sphere."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    octa = trimesh.Trimesh([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1],
                            [0, 0, -1]],
                           [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5],
                            [3, 1, 5], [0, 3, 5]])
    b = outside_bound(sphere.vertices, sphere.faces, (octa,), convex=False)
    # the worst point: a face's centre direction, at 1 - 1/sqrt(3) from the face
    exact = 1.0 - 1.0 / np.sqrt(3.0)
    on_sphere, _ = trimesh.sample.sample_surface(sphere, 20_000, seed=2)
    d = trimesh.proximity.closest_point(octa, on_sphere)[1]
    assert d.max() <= b.distance_m + 1e-12
    assert b.distance_m <= exact + 0.02  # tessellated sphere: within a triangle's sagitta
    convex = outside_bound(sphere.vertices, sphere.faces, (octa,), convex=True)
    assert convex.distance_m <= b.distance_m + 1e-12 and convex.distance_m >= d.max() - 1e-12
