"""The octree layer on a real viser server (no browser needed): a few cells as translucent
boxes, many as square sprites in one scene node, hidden and shown by the panel's toggle."""

from __future__ import annotations

import socket

import numpy as np
import pytest
import viser

from assistant.session import Session
from web.app import build_app
from web.scene.world import BOXES_UP_TO


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
        yield app.scene_layers.world
    finally:
        session.close()
        server.stop()


def test_few_cells_are_boxes_many_are_sprites_in_one_node(world_layer):
    rng = np.random.default_rng(0)
    few = rng.uniform(-0.5, 0.5, (100, 3))
    world_layer.draw_occupancy(few, rng.uniform(0, 1, 100), 0.02)
    assert (world_layer.occupancy_style, world_layer.cells_drawn) == ("boxes", 100)
    many = rng.uniform(-0.5, 0.5, (BOXES_UP_TO + 1, 3))
    world_layer.draw_occupancy(many, rng.uniform(0, 1, len(many)), 0.02)
    assert (world_layer.occupancy_style, world_layer.cells_drawn) == ("sprites", len(many))
    world_layer.set_visibility(occupancy=False)
    world_layer.draw_occupancy(few, rng.uniform(0, 1, 100), 0.02)  # redrawn hidden
    assert world_layer.occupancy_style == "boxes" and not world_layer.show_occupancy
    world_layer.draw_occupancy(few[:0], np.zeros(0), 0.02)
    assert (world_layer.occupancy_style, world_layer.cells_drawn) == (None, 0)
