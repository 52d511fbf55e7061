"""All scene layers together, in the order they are redrawn."""

from __future__ import annotations

from typing import TYPE_CHECKING

import viser

from assistant.session.events import Event
from web.scene.base import Layer
from web.scene.frames import FramesLayer
from web.scene.locations import LocationsLayer
from web.scene.objects import ObjectsLayer
from web.scene.paths import PathsLayer
from web.scene.plan import PlanLayer
from web.scene.pointer import PointerLayer
from web.scene.robot import RobotLayer
from web.scene.world import WorldLayer

if TYPE_CHECKING:
    from web.app import App


#: Scene subtrees the View panel switches as a whole: parts, the planned path, names.
GROUPS = ("objects", "plan", "labels")


class SceneLayers:
    def __init__(self, app: App):
        scene = app.server.scene
        scene.set_up_direction("+z")
        # Nothing in our scene casts a shadow, but viser's default lights still render their
        # cascaded shadow maps every frame: without a GPU that is two thirds of a frame.
        scene.configure_default_lights(enabled=True, cast_shadow=False)
        scene.add_grid("/grid", width=1.6, height=1.6, cell_size=0.1, section_size=0.5,
                       plane="xy", shadow_opacity=0.0)
        # Group nodes the View switches hide and show (their children follow them).
        self.groups: dict[str, viser.FrameHandle] = {
            g: scene.add_frame(f"/{g}", show_axes=False) for g in GROUPS}
        for sub in ("objects", "locations"):
            scene.add_frame(f"/labels/{sub}", show_axes=False)
        app.server.initial_camera.position = (1.1, -0.95, 0.75)
        app.server.initial_camera.look_at = (0.2, 0.0, 0.15)
        self.robot = RobotLayer(app)
        self.objects = ObjectsLayer(app)
        self.locations = LocationsLayer(app)
        self.frames = FramesLayer(app)
        self.paths = PathsLayer(app)
        self.world = WorldLayer(app)
        self.plan = PlanLayer(app)
        self.pointer = PointerLayer(app)
        self.all: tuple[Layer, ...] = (self.robot, self.objects, self.locations, self.frames,
                                       self.paths, self.world, self.plan, self.pointer)

    def set_group_visible(self, group: str, visible: bool) -> None:
        h = self.groups[group]
        if h.visible != visible:
            h.visible = visible

    def refresh(self) -> None:
        for layer in self.all:
            layer.refresh()

    def on_event(self, ev: Event) -> None:
        for layer in self.all:
            layer.on_event(ev)
