"""The world model: octree occupancy as ONE scene node coloured by probability (the outside
faces of the occupied cells as one unlit mesh, or square sprites when the cells are scattered;
toggleable), the Voronoi roads as a point cloud (hidden unless asked for: hundreds of dots
hide the path), the obstacle learnt from collision indications as a translucent red solid of
the cells it made occupied, labelled, and the recorded collision postures."""

from __future__ import annotations

import numpy as np

from assistant.session.events import CollisionRecorded, Event, PlanReady, SceneChanged
from web.scene.base import Layer
from web.scene.voxel_surface import surface_glb, voxel_surface

#: Probability colour stops: low (pale yellow) -> 0.5 (orange) -> certain (red).
STOPS = np.array([[0.0, 250, 230, 120], [0.5, 245, 140, 30], [1.0, 200, 25, 25]])
ROAD_COLOR = (40, 170, 90)
COLLISION_COLOR = (230, 0, 0)
#: The learnt obstacle: one colour (it is certain enough to block the planner), see-through.
LEARNT_COLOR = (215, 30, 60)
LEARNT_OPACITY = 0.45
#: The surface mesh is drawn when it has at most this many triangles per occupied cell (or
#: `SURFACE_TRIANGLES_ANYWAY` in all); scattered cells are sprites. Measured in software WebGL
#: (benchmarks/ui.py): one sprite costs about as much as 5-9 surface triangles, a compact
#: block has far fewer than one triangle per cell while an isolated cell has 12.
SURFACE_TRIANGLES_PER_CELL = 6
SURFACE_TRIANGLES_ANYWAY = 60_000
#: The surface is translucent: the CAD parts the cells come from stay visible inside it.
SURFACE_OPACITY = 0.3
#: Each face of the surface is shrunk to this in its plane: the gaps draw the cell grid.
SURFACE_FACE_SCALE = 0.9


def probability_colors(p: np.ndarray) -> np.ndarray:
    """RGB uint8 (N, 3) for occupancy probabilities in [0, 1]."""
    p = np.clip(np.asarray(p, float), 0.0, 1.0)
    out = np.stack([np.interp(p, STOPS[:, 0], STOPS[:, k]) for k in (1, 2, 3)], axis=1)
    return out.round().astype(np.uint8)


class WorldLayer(Layer):
    root = "/world"

    def __init__(self, app) -> None:  # noqa: ANN001
        super().__init__(app)
        self.show_occupancy = False  # a layer the operator turns on (View panel)
        self.show_roads = False
        self.show_learnt = True
        self.show_labels = True
        #: Cells of the learnt obstacle drawn last time (tests, the panels' figures).
        self.learnt_drawn = 0
        self.min_p = 0.05
        #: Occupied cells drawn last time (benchmarks, the explore panel's figures).
        self.cells_drawn = 0
        #: How they were drawn: "surface", "sprites" (scattered cells) or None.
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
        self.draw_learnt()
        qs = list(s.recorded_collisions)
        if qs:
            pts = np.array([s.tcp_world(q)[:3, 3] for q in qs], np.float32)
            self._nodes["collisions"] = self.scene.add_point_cloud(
                f"{self.root}/collisions", pts, COLLISION_COLOR, point_size=0.03,
                point_shape="sparkle", precision="float32")

    def draw_occupancy(self, centres: np.ndarray, p: np.ndarray, leaf: float,
                       R_world_grid: np.ndarray | None = None) -> None:
        """One scene node for all cells (50 k cells stay one draw call): the outside faces of
        the occupied cells as one mesh, or - when the cells are too scattered for that to pay
        - one square sprite per cell that has a free neighbour (the others cannot be seen).
        `R_world_grid`: the octree's axes in the world (see `Session.occupancy_cells`)."""
        old = self._nodes.pop("occupancy", None)
        if old is not None:
            old.remove()
        self.cells_drawn = len(centres)
        self.occupancy_style = None
        if not len(centres):
            return
        colors = probability_colors(p)
        surface = voxel_surface(centres, leaf, R_world_grid, SURFACE_FACE_SCALE)
        if len(surface.faces) <= max(SURFACE_TRIANGLES_ANYWAY,
                                     SURFACE_TRIANGLES_PER_CELL * len(centres)):
            self._nodes["occupancy"] = self.scene.add_glb(
                f"{self.root}/occupancy", surface_glb(surface, colors, SURFACE_OPACITY),
                cast_shadow=False, receive_shadow=False, visible=self.show_occupancy)
            self.occupancy_style = "surface"
            return
        seen = surface.surface_cells
        self._nodes["occupancy"] = self.scene.add_point_cloud(
            f"{self.root}/occupancy", np.asarray(centres, np.float32)[seen], colors[seen],
            point_size=float(0.92 * leaf), point_shape="square", precision="float32",
            visible=self.show_occupancy)
        self.occupancy_style = "sprites"

    def draw_learnt(self) -> None:
        """The obstacle the collision indications taught: the part of its occupied cells
        (those no CAD part explains) outside the arm where it stands (`Session.learnt_view`),
        as one translucent solid, with a label above it."""
        self.learnt_drawn = 0
        view = self.session.learnt_view()
        if view is None or not len(view.centres):
            return
        centres, leaf, R = view.centres, view.edge, view.R_world_grid
        self.learnt_drawn = len(centres)
        surface = voxel_surface(centres, leaf, R, 1.0)
        colors = np.tile(np.array(LEARNT_COLOR, np.uint8), (len(centres), 1))
        self._nodes["learnt"] = self.scene.add_glb(
            f"{self.root}/learnt", surface_glb(surface, colors, LEARNT_OPACITY),
            cast_shadow=False, receive_shadow=False, visible=self.show_learnt)
        top = np.asarray(centres).mean(axis=0)
        top[2] = float(np.asarray(centres)[:, 2].max()) + leaf
        self._nodes["learnt_label"] = self.scene.add_label(
            f"{self.root}/learnt_label", "learnt obstacle", position=tuple(top),
            font_screen_scale=0.9, anchor="bottom-center",
            visible=self.show_learnt and self.show_labels)

    def set_visibility(self, *, occupancy: bool | None = None, roads: bool | None = None,
                       learnt: bool | None = None, labels: bool | None = None) -> None:
        if learnt is not None:
            self.show_learnt = learnt
        if labels is not None:
            self.show_labels = labels
        if "learnt" in self._nodes:
            self._nodes["learnt"].visible = self.show_learnt
            self._nodes["learnt_label"].visible = self.show_learnt and self.show_labels
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
