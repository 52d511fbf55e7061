"""The world model: octree occupancy as ONE scene node coloured by probability (translucent
boxes for a few thousand cells, square sprites beyond; toggleable), the Voronoi roads as a
point cloud, and the recorded collision postures."""

from __future__ import annotations

import numpy as np

from assistant.session.events import CollisionRecorded, Event, PlanReady, SceneChanged
from web.scene.base import Layer

#: Probability colour stops: low (pale yellow) -> 0.5 (orange) -> certain (red).
STOPS = np.array([[0.0, 250, 230, 120], [0.5, 245, 140, 30], [1.0, 200, 25, 25]])
ROAD_COLOR = (40, 170, 90)
COLLISION_COLOR = (230, 0, 0)
#: Up to this many occupied cells are drawn as translucent boxes; more as square sprites.
BOXES_UP_TO = 5000


def probability_colors(p: np.ndarray) -> np.ndarray:
    """RGB uint8 (N, 3) for occupancy probabilities in [0, 1]."""
    p = np.clip(np.asarray(p, float), 0.0, 1.0)
    out = np.stack([np.interp(p, STOPS[:, 0], STOPS[:, k]) for k in (1, 2, 3)], axis=1)
    return out.round().astype(np.uint8)


def unit_box() -> tuple[np.ndarray, np.ndarray]:
    """A cube of edge 1 centred on the origin: (8 vertices, 12 triangles, outward)."""
    v = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)],
                 np.float32)
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], np.uint32)
    return v, f


class WorldLayer(Layer):
    root = "/world"

    def __init__(self, app) -> None:  # noqa: ANN001
        super().__init__(app)
        self.show_occupancy = True
        self.show_roads = True
        self.min_p = 0.05
        #: Occupied cells drawn last time (benchmarks, the explore panel's figures).
        self.cells_drawn = 0
        #: How they were drawn: "boxes", "sprites" (beyond `BOXES_UP_TO`) or None.
        self.occupancy_style: str | None = None
        self.roads_drawn = 0

    def refresh(self) -> None:
        self.clear()
        s = self.session
        occ = s.occupancy_cells(self.min_p)
        if occ is not None:
            self.draw_occupancy(*occ)
        roads = s.road_cells()
        if roads is not None and len(roads[0]):
            centres, leaf = roads
            self.roads_drawn = len(centres)
            self._nodes["roads"] = self.scene.add_point_cloud(
                f"{self.root}/roads", np.asarray(centres, np.float32), ROAD_COLOR,
                point_size=float(leaf) * 0.12, point_shape="circle", precision="float32",
                visible=self.show_roads)
        qs = list(s.recorded_collisions)
        if qs:
            pts = np.array([s.tcp_world(q)[:3, 3] for q in qs], np.float32)
            self._nodes["collisions"] = self.scene.add_point_cloud(
                f"{self.root}/collisions", pts, COLLISION_COLOR, point_size=0.03,
                point_shape="sparkle", precision="float32")

    def draw_occupancy(self, centres: np.ndarray, p: np.ndarray, leaf: float) -> None:
        """One scene node for all cells (50 k cells stay one draw call). Boxes use toon
        shading: the default PBR material costs several times more per pixel without a GPU."""
        old = self._nodes.pop("occupancy", None)
        if old is not None:
            old.remove()
        self.cells_drawn = len(centres)
        self.occupancy_style = None
        if not len(centres):
            return
        if len(centres) > BOXES_UP_TO:
            # Many cells: one square sprite per cell (1 vertex instead of 12 triangles of
            # blended box faces) - what keeps software WebGL (no GPU) interactive.
            self._nodes["occupancy"] = self.scene.add_point_cloud(
                f"{self.root}/occupancy", np.asarray(centres, np.float32),
                probability_colors(p), point_size=float(0.92 * leaf), point_shape="square",
                precision="float32", visible=self.show_occupancy)
            self.occupancy_style = "sprites"
            return
        v, f = unit_box()
        n = len(centres)
        self._nodes["occupancy"] = self.scene.add_batched_meshes_simple(
            f"{self.root}/occupancy", v, f,
            batched_wxyzs=np.tile(np.array([1.0, 0, 0, 0], np.float32), (n, 1)),
            batched_positions=np.asarray(centres, np.float32),
            batched_scales=np.full(n, 0.92 * leaf, np.float32),
            batched_colors=probability_colors(p), opacity=0.2, lod="off",
            cast_shadow=False, receive_shadow=False, material="toon3",
            visible=self.show_occupancy)
        self.occupancy_style = "boxes"

    def set_visibility(self, *, occupancy: bool | None = None, roads: bool | None = None) -> None:
        if occupancy is not None:
            self.show_occupancy = occupancy
            if "occupancy" in self._nodes:
                self._nodes["occupancy"].visible = occupancy
        if roads is not None:
            self.show_roads = roads
            if "roads" in self._nodes:
                self._nodes["roads"].visible = roads

    def on_event(self, ev: Event) -> None:
        if isinstance(ev, (CollisionRecorded, PlanReady)) or \
                isinstance(ev, SceneChanged) and ev.what in ("world", "all", "objects", "robot"):
            self.refresh()
