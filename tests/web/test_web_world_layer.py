"""The octree layer on a real viser server (no browser needed): compact cells as one surface
mesh, scattered ones as square sprites (only those with a free side), always one scene node,
hidden and shown by the panel's toggle."""

from __future__ import annotations

import socket

import numpy as np
import pytest
import viser

from assistant.session import Session
from web.app import build_app
from web.scene.world import SURFACE_TRIANGLES_ANYWAY


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture()
def world_layer(tmp_path):
    session = Session.from_sample("thesis_rv2aj", tmp_path / "s")
    server = viser.ViserServer(host="127.0.0.1", port=_free_port(), verbose=False)
    try:
        app = build_app(session, server)
    except BaseException:
        session.close()
        server.stop()
        raise
    try:
        yield app.scene_layers.world
    finally:
        app.stop()  # the UI thread first: left running, it drew on the stopped server


def _block(n: int) -> np.ndarray:
    """n*n*n cells of 2 cm in a solid cube (CAD-like occupancy)."""
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    return (g + 0.5) * 0.02


def test_blocks_are_one_surface_scattered_cells_are_sprites_in_one_node(world_layer):
    rng = np.random.default_rng(0)
    block = _block(30)  # 27 000 cells, 5 400 outside faces
    world_layer.draw_occupancy(block, rng.uniform(0, 1, len(block)), 0.02)
    assert (world_layer.occupancy_style, world_layer.cells_drawn) == ("surface", len(block))
    node = world_layer._nodes["occupancy"]  # noqa: SLF001
    assert isinstance(node, viser.GlbHandle)
    # Isolated cells have 12 triangles each: more than the surface budget -> sprites, and
    # only the cells with a free side (all of them here).
    n = SURFACE_TRIANGLES_ANYWAY // 12 + 100
    scattered = rng.choice(200**3, n, replace=False)
    many = (np.stack(np.unravel_index(scattered, (200,) * 3), axis=1) * 2 + 0.5) * 0.02
    world_layer.draw_occupancy(many, rng.uniform(0, 1, n), 0.02)
    assert (world_layer.occupancy_style, world_layer.cells_drawn) == ("sprites", n)
    node = world_layer._nodes["occupancy"]  # noqa: SLF001
    assert isinstance(node, viser.PointCloudHandle) and len(node.points) == n
    world_layer.set_visibility(occupancy=False)
    world_layer.draw_occupancy(block, rng.uniform(0, 1, len(block)), 0.02)  # redrawn hidden
    assert world_layer.occupancy_style == "surface" and not world_layer.show_occupancy
    assert world_layer._nodes["occupancy"].visible is False  # noqa: SLF001
    world_layer.draw_occupancy(block[:0], np.zeros(0), 0.02)
    assert (world_layer.occupancy_style, world_layer.cells_drawn) == (None, 0)
    assert "occupancy" not in world_layer._nodes  # noqa: SLF001


def test_sprites_skip_the_cells_without_a_free_side(world_layer, monkeypatch):
    import web.scene.world as world

    monkeypatch.setattr(world, "SURFACE_TRIANGLES_ANYWAY", 0)
    monkeypatch.setattr(world, "SURFACE_TRIANGLES_PER_CELL", 0)
    block = _block(5)
    world_layer.draw_occupancy(block, np.full(len(block), 0.9), 0.02)
    node = world_layer._nodes["occupancy"]  # noqa: SLF001
    assert world_layer.occupancy_style == "sprites" and world_layer.cells_drawn == 125
    assert len(node.points) == 125 - 27  # the inner 3x3x3 cannot be seen
